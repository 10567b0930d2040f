"""Text on video frames, and frames side by side."""

from __future__ import annotations

import functools

import numpy as np
from PIL import Image, ImageDraw, ImageFont

SEPARATOR = np.array([40, 40, 40], dtype=np.uint8)


@functools.cache
def _font(size: int) -> ImageFont.ImageFont:
    return ImageFont.load_default(size=size)


def draw_label(frame: np.ndarray, text: str) -> np.ndarray:
    """``frame`` with ``text`` in its top-left corner, white on a dark box."""
    image = Image.fromarray(frame)
    draw = ImageDraw.Draw(image)
    font = _font(max(10, frame.shape[0] // 18))
    margin = max(3, frame.shape[0] // 80)
    left, top, right, bottom = draw.textbbox((2 * margin, 2 * margin), text, font=font)
    draw.rectangle((left - margin, top - margin, right + margin, bottom + margin), fill=(0, 0, 0))
    draw.text((2 * margin, 2 * margin), text, fill=(255, 255, 255), font=font)
    return np.asarray(image)


def side_by_side(frames: list[np.ndarray]) -> np.ndarray:
    """Frames of one height next to each other, a dark line between them."""
    joined = np.concatenate(frames, axis=1)
    for boundary in np.cumsum([frame.shape[1] for frame in frames[:-1]]):
        joined[:, boundary - 1 : boundary + 1] = SEPARATOR
    return joined
