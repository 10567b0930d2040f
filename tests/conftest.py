"""Shared fixtures: small synthetic datasets."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import pytest

from xted.data import Dataset, load


def build_dataset(
    lengths: Sequence[int] = (4, 6, 3),
    ends: Sequence[str] | None = None,
    obs_dim: int = 3,
    act_dim: int = 2,
    next_observations: str | None = "consistent",
    seed: int = 0,
) -> Dataset:
    """Episodes of the given lengths ending in ``"terminal"`` or ``"timeout"`` (default alternate).

    ``next_observations``: ``"consistent"`` (next row within an episode, fresh at episode ends),
    ``"random"`` (independent of the observations) or None.
    """
    rng = np.random.default_rng(seed)
    n = sum(lengths)
    ends = ends or ["timeout" if i % 2 == 0 else "terminal" for i in range(len(lengths))]
    last = np.cumsum(lengths) - 1
    terminals, timeouts = np.zeros(n, bool), np.zeros(n, bool)
    for index, kind in zip(last, ends):
        (terminals if kind == "terminal" else timeouts)[index] = True
    observations = rng.normal(size=(n, obs_dim)).astype(np.float32)
    nexts = None
    if next_observations == "consistent":
        nexts = np.roll(observations, -1, axis=0)
        nexts[last] = rng.normal(size=(len(lengths), obs_dim))
    elif next_observations == "random":
        nexts = rng.normal(size=(n, obs_dim)).astype(np.float32)
    return Dataset(
        observations=observations,
        actions=rng.uniform(-1, 1, size=(n, act_dim)).astype(np.float32),
        rewards=rng.normal(size=n).astype(np.float32),
        terminals=terminals,
        timeouts=timeouts,
        next_observations=nexts,
        extras={
            "qpos": rng.normal(size=(n, obs_dim + 1)),
            "sim/contact": rng.random(n) < 0.5,
            "step": np.arange(n, dtype=np.int32),
        },
        metadata={"env": "Toy-v0", "seed": seed, "policy": "random", "normalized_score": 12.5},
    )


def first_steps(name: str, steps: int, episodes: int = 2, next_observations: bool = False) -> Dataset:
    """The first ``steps`` steps of the first ``episodes`` episodes of a shipped dataset (with its
    next observations if asked)."""
    data = load(name)
    rows = np.concatenate([np.arange(start, start + steps) for start, _ in data.episode_bounds()[:episodes]])
    timeouts = np.zeros(len(rows), bool)
    timeouts[steps - 1 :: steps] = True
    return Dataset(observations=data.observations[rows], actions=data.actions[rows], rewards=data.rewards[rows],
                   terminals=np.zeros(len(rows), bool), timeouts=timeouts, metadata={"env": data.metadata["env"]},
                   next_observations=data.next_observations[rows] if next_observations else None)


@pytest.fixture
def make_dataset() -> Callable[..., Dataset]:
    return build_dataset


@pytest.fixture
def tiny_dataset() -> Dataset:
    """13 steps in 3 episodes (lengths 4, 6, 3; timeout, terminal, timeout) with extras."""
    return build_dataset()


def assert_same_dataset(actual: Dataset, expected: Dataset) -> None:
    """Arrays (values and dtypes), extras and metadata all equal."""
    for name in ("observations", "actions", "rewards", "terminals", "timeouts", "next_observations"):
        a, e = getattr(actual, name), getattr(expected, name)
        if e is None:
            assert a is None, name
            continue
        assert a.dtype == e.dtype, name
        np.testing.assert_array_equal(a, e, err_msg=name)
    assert sorted(actual.extras) == sorted(expected.extras)
    for name, value in expected.extras.items():
        assert actual.extras[name].dtype == value.dtype, name
        np.testing.assert_array_equal(actual.extras[name], value, err_msg=name)
    assert actual.metadata == expected.metadata


@pytest.fixture
def assert_same() -> Callable[[Dataset, Dataset], None]:
    return assert_same_dataset
