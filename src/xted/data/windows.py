"""Fixed-horizon windows cut from episodes, never crossing an episode boundary: xted's one
windowing module.

- Training draws stride-1 windows of ``H`` transitions (:func:`window_index`, sampled per batch by
  :class:`WindowSampler`); episodes shorter than ``H`` are skipped and counted, never padded.
- Editing tiles each episode's state sequence ``s_0 .. s_T`` (its ``T`` observations and the final
  next observation) with windows that overlap by one step (:func:`tile_episodes`), so every
  transition ``(s_t, a_t, s_t+1)`` lies inside one window, and each window after an episode's
  first starts where the window before it reads its last next state: edited in episode order
  (:meth:`EpisodeTiling.schedule`), each window can start from what the one before it edited.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from xted.data.dataset import Dataset
from xted.errors import InputError, warn_data

LONGEST_PLAIN_EPISODE = 1000  # Gymnasium's locomotion envs end every episode by then


def warn_if_one_long_episode(dataset: Dataset, what: str) -> None:
    """Warn where ``dataset`` is one episode longer than any locomotion episode: most often a file that
    records no episode ends, whose windows would then span the resets between its episodes."""
    if dataset.num_episodes == 1 and len(dataset) > LONGEST_PLAIN_EPISODE:
        warn_data(f"{what} is one episode of {len(dataset)} steps (no terminal or timeout before its last step): "
                  "if it holds several episodes, windows span the resets between them; record terminals or "
                  "timeouts (xted data info shows the episodes)")


def window_index(dataset: Dataset, horizon: int, stride: int = 1) -> tuple[np.ndarray, int]:
    """``([W, H] flat step indices, number of skipped episodes)``: windows start every ``stride``
    steps of an episode while a full window fits; shorter episodes are skipped."""
    for name, value in (("horizon", horizon), ("stride", stride)):
        if int(value) != value or value < 1:
            raise InputError(f"{name} must be a positive integer, got {value}")
    rows, skipped = [], 0
    offsets = np.arange(horizon)
    for start, end in dataset.episode_bounds():
        if end - start >= horizon:
            rows.append(np.arange(start, end - horizon + 1, stride)[:, None] + offsets)
        else:
            skipped += 1
    if not rows:
        raise InputError(f"no windows of horizon {horizon}: all {skipped} episodes are shorter")
    return np.concatenate(rows).astype(np.int64), skipped


@dataclass(frozen=True, eq=False)
class WindowSampler:
    """Windows gathered per batch from flat per-step arrays (never materialised as ``[W, H, ...]``)."""

    flat: dict[str, np.ndarray]  # name -> [N, d] per-step values
    index: np.ndarray  # [W, H] from window_index
    returns: np.ndarray  # [W] one value per window
    loss_mask: np.ndarray  # [H] positions that count in the loss

    def batch(self, rng: np.random.Generator, size: int) -> dict[str, np.ndarray]:
        pick = rng.integers(0, len(self.index), size=size)
        rows = self.index[pick]
        out = {name: values[rows] for name, values in self.flat.items()}
        out["loss_mask"] = np.broadcast_to(self.loss_mask, rows.shape)
        out["returns"] = self.returns[pick]
        return out


@dataclass(frozen=True, eq=False)
class EpisodeTiling:
    """Windows over the per-episode state sequences and where each transition is read from.

    Window ``w`` reads the transitions ``t`` with ``start_w <= t < start_{w+1}`` (the episode's last
    window: to its end), so its position ``carry_position[w + 1]`` is both its last transition's
    next state and the next window's first state."""

    window_rows: np.ndarray  # [W, H] rows of the sequence arrays
    window_previous: np.ndarray  # [W] the episode's window before this one, -1 for its first
    window_carry_position: np.ndarray  # [W] position in window_previous equal to this window's position 0
    window_episode: np.ndarray  # [W] tiled episode the window belongs to
    transition_steps: np.ndarray  # [T] dataset rows of the tiled transitions
    transition_window: np.ndarray  # [T] window of each transition
    transition_position: np.ndarray  # [T] position of s_t in that window
    sequence_steps: np.ndarray  # [S] dataset row each sequence position is taken from
    sequence_is_next: np.ndarray  # [S] True where the position is the episode's final next observation
    passed_through: np.ndarray  # [E] True for episodes too short to tile (fewer than H - 1 steps)

    def schedule(self, slots: int) -> np.ndarray:
        """``[steps, slots]`` window ids (-1: idle) such that every window comes a step after its
        ``window_previous``: each slot edits whole episodes in order, longest episodes first, each
        to the slot with the least work so far (so the steps stay near ``W / slots``)."""
        if slots < 1:
            raise InputError(f"schedule: slots must be >= 1, got {slots}")
        episodes = [np.flatnonzero(self.window_episode == e) for e in range(int(self.window_episode.max(initial=-1)) + 1)]
        queues: list[list[int]] = [[] for _ in range(slots)]
        for windows in sorted(episodes, key=len, reverse=True):
            min(queues, key=len).extend(windows.tolist())
        table = np.full((max(map(len, queues)), slots), -1, np.int64)
        for slot, queue in enumerate(queues):
            table[:len(queue), slot] = queue
        return table


def tile_episodes(bounds: np.ndarray, horizon: int) -> EpisodeTiling:
    """Tile each episode's ``T + 1`` states with ``H``-step windows at stride ``H - 1`` (the last
    one shifted back to end at the final state); window ``w`` reads the transitions from its start
    to the next window's start."""
    stride = horizon - 1
    rows, previous, carry, episode_of = [], [], [], []
    t_steps, t_window, t_position, seq_steps, seq_next, passed = [], [], [], [], [], []
    offset = n_windows = n_tiled = 0
    for start, end in bounds:
        length = int(end - start)
        if length + 1 < horizon:
            passed.append(True)
            continue
        passed.append(False)
        starts = list(range(0, length + 2 - horizon, stride))
        if starts[-1] + horizon < length + 1:
            starts.append(length + 1 - horizon)
        starts = np.asarray(starts)
        rows.append(offset + starts[:, None] + np.arange(horizon))
        previous.append(np.where(np.arange(len(starts)) > 0, n_windows + np.arange(len(starts)) - 1, -1))
        carry.append(np.diff(starts, prepend=0))
        episode_of.append(np.full(len(starts), n_tiled))
        t = np.arange(length)
        window = np.searchsorted(starts, t, side="right") - 1
        t_steps.append(start + t)
        t_window.append(n_windows + window)
        t_position.append(t - starts[window])
        seq_steps.append(np.append(np.arange(start, end), end - 1))
        seq_next.append(np.arange(length + 1) == length)
        offset += length + 1
        n_windows += len(starts)
        n_tiled += 1

    def cat(parts: list, dtype) -> np.ndarray:
        return np.concatenate(parts).astype(dtype) if parts else np.zeros(0, dtype)

    return EpisodeTiling(
        window_rows=np.concatenate(rows) if rows else np.zeros((0, horizon), np.int64),
        window_previous=cat(previous, np.int64),
        window_carry_position=cat(carry, np.int64),
        window_episode=cat(episode_of, np.int64),
        transition_steps=cat(t_steps, np.int64),
        transition_window=cat(t_window, np.int64),
        transition_position=cat(t_position, np.int64),
        sequence_steps=cat(seq_steps, np.int64),
        sequence_is_next=cat(seq_next, bool),
        passed_through=np.asarray(passed, bool),
    )
