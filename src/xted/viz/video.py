"""Frames to a video file: ``.mp4`` (H.264, through imageio's ffmpeg plugin) or ``.gif`` (Pillow)."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import numpy as np

from xted.atomic import atomic_path
from xted.errors import InputError
from xted.viz.config import VIDEO_SUFFIXES


def check_video_path(path: str | Path) -> Path:
    """``path`` if a video may be written there (replacing a file), else InputError."""
    path = Path(path)
    if path.suffix.lower() not in VIDEO_SUFFIXES:
        raise InputError(f"{path}: unknown video extension {path.suffix!r}; use {' or '.join(VIDEO_SUFFIXES)}")
    if path.is_dir():
        raise InputError(f"{path}: is a folder, expected a file path")
    return path


def write_video(frames: Iterable[np.ndarray], path: str | Path, fps: float) -> int:
    """Write ``frames`` (uint8 ``[H, W, 3]``, one size) atomically to ``path``; return how many."""
    path = check_video_path(path)
    suffix = path.suffix.lower()
    count = 0
    with atomic_path(path, suffix=suffix) as tmp:
        write = _write_mp4 if suffix == ".mp4" else _write_gif
        count = write(frames, tmp, fps)
        if count == 0:
            raise InputError(f"{path}: no frames to write")
    return count


def _write_mp4(frames: Iterable[np.ndarray], path: Path, fps: float) -> int:
    import imageio.v2 as imageio

    try:
        import imageio_ffmpeg  # noqa: F401  (imageio's FFMPEG plugin needs it)
    except ImportError:
        raise InputError("writing .mp4 needs imageio-ffmpeg (pip install imageio-ffmpeg), or write a .gif") from None
    count = 0
    # x264's "veryfast" preset encodes about three times faster than its default at these sizes,
    # for files about half again as large.
    writer = imageio.get_writer(path, format="FFMPEG", mode="I", fps=fps, codec="libx264", quality=7,
                                macro_block_size=16, ffmpeg_log_level="error", output_params=["-preset", "veryfast"])
    try:
        for frame in frames:
            writer.append_data(frame)
            count += 1
    finally:
        writer.close()
    return count


def _write_gif(frames: Iterable[np.ndarray], path: Path, fps: float) -> int:
    import imageio.v3 as iio

    count = 0
    # Pillow writes a GIF when it is closed, from every frame kept until then: a frame reduced to
    # a 256-colour palette takes a third of its RGB size.
    with iio.imopen(path, "w", plugin="pillow", extension=".gif") as file:
        for frame in frames:
            file.write(frame, duration=1000.0 / fps, loop=0, bits=8)
            count += 1
    return count
