"""Settings of pictures and videos. Plain Python: the CLI takes its defaults from here without
loading MuJoCo, JAX or matplotlib."""

from __future__ import annotations

from dataclasses import dataclass

from xted.errors import InputError

VIDEO_SUFFIXES = (".mp4", ".gif")


@dataclass(frozen=True)
class VideoConfig:
    """One panel's size in pixels (a side-by-side video is two panels wide) and the frame rate
    (None: real time, one frame per env step)."""

    width: int = 384
    height: int = 256
    fps: float | None = None
    camera_distance: float = 3.0

    def __post_init__(self) -> None:
        for name in ("width", "height"):
            value = getattr(self, name)
            if not 16 <= value <= 2048 or value % 16:
                raise InputError(f"{name} must be a multiple of 16 between 16 and 2048 (the video codec's blocks), "
                                 f"got {value}")
        if self.fps is not None and not self.fps > 0:
            raise InputError(f"fps must be positive, got {self.fps}")
        if not self.camera_distance > 0:
            raise InputError(f"camera_distance must be positive, got {self.camera_distance}")


@dataclass(frozen=True)
class PlotDefaults:
    """Defaults of ``xted plot``: the spectrum's segment length (the paper's frequency analysis
    takes 100 transitions), its low-frequency band (``xted analyze content``'s cutoff) and how
    many steps of an episode a trajectory plot shows."""

    segment: int = 100
    cutoff: float = 0.2
    trajectory_steps: int = 200
