"""The in-memory dataset: episodes stored as flat per-step arrays.

An episode ends at a step whose ``terminals`` (the environment terminated) or ``timeouts``
(the episode was cut short: time limit, end of collection) flag is set; never both.

Reward-free data (demonstrations, a real robot's logs) is built with ``rewards=None``: it holds
zero rewards and says so in ``metadata["reward_free"]``, which every reader of rewards checks
(:attr:`Dataset.has_rewards`); files written from it omit the rewards.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from xted.errors import InputError

REWARD_FREE = "reward_free"  # metadata key: the data records no rewards (its rewards are zeros)


@dataclass(frozen=True, eq=False)
class Dataset:
    """Transitions ``(s_t, a_t, r_t, s_{t+1})`` of consecutive episodes, validated on construction."""

    observations: np.ndarray
    actions: np.ndarray
    rewards: np.ndarray | None = None  # None: reward-free data
    terminals: np.ndarray | None = None  # None: no step is terminal
    timeouts: np.ndarray | None = None  # None: only the last step ends an episode (where it is not terminal)
    next_observations: np.ndarray | None = None
    extras: dict[str, np.ndarray] = field(default_factory=dict)
    metadata: dict[str, Any] = field(default_factory=dict)
    origin: str | None = None  # the file it was read from, for errors; never written

    def __post_init__(self) -> None:
        observations = _float_array("observations", self.observations, ndim=2)
        metadata = _json_roundtrip(self.metadata)
        if self.rewards is None:
            rewards = np.zeros(len(observations), np.float32)
            metadata[REWARD_FREE] = True
        else:
            rewards = _float_array("rewards", self.rewards, ndim=1)
        terminals = np.zeros(len(observations), bool) if self.terminals is None else as_flags("terminals", self.terminals)
        if self.timeouts is None:
            timeouts = np.zeros(len(terminals), bool)
            timeouts[-1:] = ~terminals[-1:]
        else:
            timeouts = as_flags("timeouts", self.timeouts)
        converted = {
            "observations": observations,
            "actions": _float_array("actions", self.actions, ndim=2),
            "rewards": rewards,
            "terminals": terminals,
            "timeouts": timeouts,
            "extras": {str(k): np.asarray(v) for k, v in self.extras.items()},
            "metadata": metadata,
        }
        if self.next_observations is not None:
            converted["next_observations"] = _float_array("next_observations", self.next_observations, ndim=2)
        for name, value in converted.items():
            object.__setattr__(self, name, value)
        self._validate()

    def _validate(self) -> None:
        n = len(self.observations)
        if n == 0:
            raise InputError("empty dataset: observations has no rows")
        for name in ("actions", "rewards", "terminals", "timeouts"):
            if len(getattr(self, name)) != n:
                raise InputError(f"{name} has {len(getattr(self, name))} rows, observations has {n}")
        if self.next_observations is not None and self.next_observations.shape != self.observations.shape:
            raise InputError(
                f"next_observations has shape {self.next_observations.shape}, "
                f"observations has shape {self.observations.shape}"
            )
        if self.next_observations is not None and np.array_equal(self.next_observations, self.observations):
            raise InputError("next_observations equals observations in every row (a logging off-by-one?): each "
                             "transition's next observation must be the state it stepped into")
        for name, value in self.extras.items():
            if value.ndim == 0 or len(value) != n:
                raise InputError(f"extras[{name!r}] has shape {value.shape}; its first dimension must be {n}")
        both = np.flatnonzero(self.terminals & self.timeouts)
        if both.size:
            raise InputError(f"terminals[{both[0]}] and timeouts[{both[0]}] are both true")
        if not (self.terminals[-1] or self.timeouts[-1]):
            raise InputError(f"the final step (index {n - 1}) ends no episode: terminals and timeouts false")
        if not self.has_rewards and np.any(self.rewards != 0):
            raise InputError(f"metadata[{REWARD_FREE!r}] says the data has no rewards, but rewards has nonzero "
                             f"entries (index {int(np.flatnonzero(self.rewards)[0])})")

    def __repr__(self) -> str:
        parts = [f"{len(self)} transitions", f"{self.num_episodes} episodes", f"observations {self.observation_dim}-d",
                 f"actions {self.action_dim}-d", "rewards" if self.has_rewards else "reward-free"]
        if self.next_observations is not None:
            parts.append("next_observations")
        if self.extras:
            parts.append(f"extras {sorted(self.extras)}")
        if "env" in self.metadata:
            parts.append(f"env {self.metadata['env']!r}")
        return f"Dataset({', '.join(parts)})"

    # ----------------------------------------------------------------- shape
    def __len__(self) -> int:
        return len(self.observations)

    @property
    def observation_dim(self) -> int:
        return self.observations.shape[1]

    @property
    def action_dim(self) -> int:
        return self.actions.shape[1]

    @property
    def has_rewards(self) -> bool:
        """False for reward-free data (built with ``rewards=None``, or read from a file without them)."""
        return not self.metadata.get(REWARD_FREE, False)

    def require_rewards(self, what: str, remedy: str) -> None:
        """InputError naming ``what`` needs rewards when this data has none, and the ``remedy``."""
        if not self.has_rewards:
            raise InputError(f"{what} needs rewards, and this data has none (reward-free); {remedy}")

    # -------------------------------------------------------------- episodes
    def episode_bounds(self) -> np.ndarray:
        """``[E, 2]`` int array of ``(start, end)`` per episode, ``end`` exclusive."""
        ends = np.flatnonzero(self.terminals | self.timeouts) + 1
        starts = np.concatenate([[0], ends[:-1]])
        return np.stack([starts, ends], axis=1)

    @property
    def num_episodes(self) -> int:
        return int(np.count_nonzero(self.terminals | self.timeouts))

    def episode_lengths(self) -> np.ndarray:
        bounds = self.episode_bounds()
        return bounds[:, 1] - bounds[:, 0]

    def episode_returns(self) -> np.ndarray:
        """Undiscounted return of each episode (float64)."""
        starts = self.episode_bounds()[:, 0]
        return np.add.reduceat(self.rewards.astype(np.float64), starts)

    def select_episodes(self, indices: Sequence[int] | np.ndarray) -> Dataset:
        """A dataset of the given episodes, in the given order (repeats allowed)."""
        bounds = self.episode_bounds()
        indices = np.asarray(indices, dtype=np.int64).reshape(-1)
        if indices.size == 0:
            raise InputError("select_episodes: no episodes selected (empty dataset)")
        bad = indices[(indices < 0) | (indices >= len(bounds))]
        if bad.size:
            raise InputError(f"select_episodes: episode {bad[0]} out of range 0..{len(bounds) - 1}")
        steps = np.concatenate([np.arange(*bounds[i]) for i in indices])
        return Dataset(
            observations=self.observations[steps],
            actions=self.actions[steps],
            rewards=self.rewards[steps],
            terminals=self.terminals[steps],
            timeouts=self.timeouts[steps],
            next_observations=None if self.next_observations is None else self.next_observations[steps],
            extras={k: v[steps] for k, v in self.extras.items()},
            metadata=self.metadata,
            origin=self.origin,
        )

    @staticmethod
    def concatenate(datasets: Sequence[Dataset], metadata: Mapping[str, Any] | None = None) -> Dataset:
        """Episodes of all datasets in order.

        ``next_observations`` is kept if every dataset has it; extras are kept where every
        dataset has the name. ``metadata`` defaults to ``{"sources": [each metadata]}``.
        """
        if not datasets:
            raise InputError("concatenate: no datasets given (empty dataset)")
        dims = {(d.observation_dim, d.action_dim) for d in datasets}
        if len(dims) > 1:
            raise InputError(f"concatenate: datasets differ in (observation_dim, action_dim): {sorted(dims)}")
        def cat(name: str) -> np.ndarray:
            return np.concatenate([getattr(d, name) for d in datasets])

        has_next = all(d.next_observations is not None for d in datasets)
        common = set.intersection(*(set(d.extras) for d in datasets))
        return Dataset(
            observations=cat("observations"),
            actions=cat("actions"),
            rewards=cat("rewards") if all(d.has_rewards for d in datasets) else None,
            terminals=cat("terminals"),
            timeouts=cat("timeouts"),
            next_observations=cat("next_observations") if has_next else None,
            extras={k: np.concatenate([d.extras[k] for d in datasets]) for k in sorted(common)},
            metadata=dict(metadata) if metadata is not None else {"sources": [d.metadata for d in datasets]},
        )

    def with_metadata(self, **updates: Any) -> Dataset:
        """A copy with ``metadata`` updated by ``updates``."""
        return dataclasses.replace(self, metadata={**self.metadata, **updates})

    def fingerprint(self) -> str:
        """SHA-256 of the transition arrays (not the metadata): equal exactly when the data is."""
        digest = hashlib.sha256()
        names = ("observations", "actions", "rewards", "terminals", "timeouts", "next_observations")
        for name in names:
            value = getattr(self, name)
            if value is not None:
                digest.update(name.encode())
                digest.update(np.ascontiguousarray(value).tobytes())
        return digest.hexdigest()

    def require_next_observations(self) -> np.ndarray:
        """``next_observations``, or an InputError saying the dataset stores none (the last step of
        an episode has no successor to take it from)."""
        if self.next_observations is not None:
            return self.next_observations
        end = int(np.flatnonzero(self.terminals | self.timeouts)[0])
        where = f"{self.origin}: " if self.origin else ""
        raise InputError(
            f"{where}next_observations is missing and cannot be derived for the last step of an episode "
            f"(index {end}); use a dataset that stores next_observations"
        )

    def summary(self) -> dict[str, Any]:
        """Counts, dimensions, return (None for reward-free data) and length statistics, extras and
        metadata."""
        returns = self.episode_returns() if self.has_rewards else None
        lengths = self.episode_lengths()

        def stat(reduce) -> float | None:
            return None if returns is None else float(reduce(returns))

        return {
            "episodes": self.num_episodes,
            "transitions": len(self),
            "observation_dim": self.observation_dim,
            "action_dim": self.action_dim,
            "rewards": self.has_rewards,
            "return_mean": stat(np.mean),
            "return_std": stat(np.std),
            "return_min": stat(np.min),
            "return_max": stat(np.max),
            "episode_length_mean": float(lengths.mean()),
            "episode_length_min": int(lengths.min()),
            "episode_length_max": int(lengths.max()),
            "terminals": int(self.terminals.sum()),
            "timeouts": int(self.timeouts.sum()),
            "next_observations": self.next_observations is not None,
            "extras": sorted(self.extras),
            "metadata": self.metadata,
        }


def _float_array(name: str, value: Any, ndim: int) -> np.ndarray:
    array = np.asarray(value)
    if array.ndim != ndim:
        raise InputError(f"{name} must be {ndim}-D, got shape {array.shape}")
    if not (np.issubdtype(array.dtype, np.number) or array.dtype == np.bool_):
        raise InputError(f"{name} must be numeric, got dtype {array.dtype}")
    array = array.astype(np.float32, copy=False)
    bad = np.argwhere(~np.isfinite(array))
    if bad.size:
        where = tuple(int(i) for i in bad[0])
        label = ", ".join(map(str, where))
        raise InputError(f"{name}[{label}] is {array[where]}")
    return array


def as_flags(name: str, value: Any) -> np.ndarray:
    """``value`` as a 1-D bool array; numbers must be 0 or 1."""
    array = np.asarray(value)
    if array.ndim != 1:
        raise InputError(f"{name} must be 1-D, got shape {array.shape}")
    if array.dtype != np.bool_:
        if not np.issubdtype(array.dtype, np.number):
            raise InputError(f"{name} must be boolean, got dtype {array.dtype}")
        bad = np.flatnonzero((array != 0) & (array != 1))
        if bad.size:
            raise InputError(f"{name}[{bad[0]}] is {array[bad[0]]}, expected 0 or 1")
        array = array.astype(bool)
    return array


def _json_roundtrip(metadata: Mapping[str, Any]) -> dict[str, Any]:
    try:
        return json.loads(json.dumps(dict(metadata)))
    except (TypeError, ValueError) as err:
        raise InputError(f"metadata is not JSON-serialisable: {err}") from None


def check_dimensions(data: Dataset, dims: tuple[int, int], name: str, expected_by: str) -> None:
    """An InputError unless ``data`` has ``dims = (observation_dim, action_dim)``; the message names
    the data (``name``) and what expects those dimensions (``expected_by``)."""
    if (data.observation_dim, data.action_dim) != tuple(dims):
        raise InputError(f"{name} has {data.observation_dim}-d observations and {data.action_dim}-d actions; "
                         f"{expected_by} has {dims[0]} and {dims[1]}")


def split_heldout(dataset: Dataset, episodes: int, seed: int = 0) -> tuple[Dataset, Dataset | None]:
    """(training part, ``episodes`` held-out episodes chosen at random, or None for 0): the held-out
    episodes measure a prior's floor, the same edit applied to target data it never saw."""
    if not 0 <= episodes < dataset.num_episodes:
        raise InputError(f"cannot hold out {episodes} of {dataset.num_episodes} episodes")
    if episodes == 0:
        return dataset, None
    order = np.random.default_rng(seed).permutation(dataset.num_episodes)
    return dataset.select_episodes(np.sort(order[episodes:])), dataset.select_episodes(np.sort(order[:episodes]))
