"""Fixed-horizon windows cut from episodes, never crossing an episode boundary.

Episodes shorter than the horizon are skipped (and counted) or padded. Padded steps repeat the
last valid step's values and are marked invalid (``valid`` and ``loss_mask`` false), so a model
never learns them as data. The first step of every window is the held (inpainted) transition:
``first_mask`` is true there and ``loss_mask`` false.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from xted.data.dataset import Dataset
from xted.errors import InputError

ShortEpisodes = Literal["skip", "pad"]


@dataclass(frozen=True, eq=False)
class Windows:
    """``W`` windows of ``H`` steps; per-step arrays are ``[W, H, ...]``."""

    observations: np.ndarray
    actions: np.ndarray
    rewards: np.ndarray
    next_observations: np.ndarray | None
    loss_mask: np.ndarray
    first_mask: np.ndarray
    valid: np.ndarray
    index: np.ndarray
    returns: np.ndarray
    skipped_episodes: int

    def __len__(self) -> int:
        return len(self.index)

    @property
    def horizon(self) -> int:
        return self.index.shape[1]


def window_index(
    dataset: Dataset, horizon: int, stride: int = 1, short_episodes: ShortEpisodes = "skip"
) -> tuple[np.ndarray, int]:
    """``([W, H] flat step indices, -1 on padding; number of skipped episodes)``.

    Windows start every ``stride`` steps of an episode while a full window fits.
    """
    _check_args(horizon, stride, short_episodes)
    rows, skipped = [], 0
    offsets = np.arange(horizon)
    for start, end in dataset.episode_bounds():
        if end - start >= horizon:
            rows.append(np.arange(start, end - horizon + 1, stride)[:, None] + offsets)
        elif short_episodes == "pad":
            rows.append(np.where(offsets < end - start, start + offsets, -1)[None])
        else:
            skipped += 1
    if not rows:
        raise InputError(
            f"no windows of horizon {horizon}: all {skipped} episodes are shorter "
            f"(use short_episodes='pad' or a smaller horizon)"
        )
    return np.concatenate(rows).astype(np.int64), skipped


def make_windows(
    dataset: Dataset, horizon: int, stride: int = 1, short_episodes: ShortEpisodes = "skip"
) -> Windows:
    """Cut ``dataset`` into windows (see :func:`window_index`) and gather their arrays."""
    index, skipped = window_index(dataset, horizon, stride, short_episodes)
    valid = index >= 0
    last = index[np.arange(len(index)), valid.sum(axis=1) - 1]
    gather = np.where(valid, index, last[:, None])
    first_mask = np.zeros_like(valid)
    first_mask[:, 0] = True
    rewards = dataset.rewards[gather]
    next_observations = dataset.next_observations
    return Windows(
        observations=dataset.observations[gather],
        actions=dataset.actions[gather],
        rewards=rewards,
        next_observations=None if next_observations is None else next_observations[gather],
        loss_mask=valid & ~first_mask,
        first_mask=first_mask,
        valid=valid,
        index=index,
        returns=np.where(valid, rewards, 0.0).sum(axis=1, dtype=np.float32),
        skipped_episodes=skipped,
    )


def _check_args(horizon: int, stride: int, short_episodes: str) -> None:
    if int(horizon) != horizon or horizon < 1:
        raise InputError(f"horizon must be a positive integer, got {horizon}")
    if int(stride) != stride or stride < 1:
        raise InputError(f"stride must be a positive integer, got {stride}")
    if short_episodes not in ("skip", "pad"):
        raise InputError(f"short_episodes must be 'skip' or 'pad', got {short_episodes!r}")
