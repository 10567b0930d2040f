"""Windows of horizon H cut from episodes."""

from __future__ import annotations

import numpy as np
import pytest

from xted.data import make_windows
from xted.data.windows import window_index
from xted.errors import InputError


def _episode_of(dataset):
    bounds = dataset.episode_bounds()
    return np.repeat(np.arange(len(bounds)), bounds[:, 1] - bounds[:, 0])


def test_full_windows_stride_one(tiny_dataset):
    w = make_windows(tiny_dataset, horizon=3)
    assert len(w) == (4 - 2) + (6 - 2) + (3 - 2) and w.horizon == 3 and w.skipped_episodes == 0
    assert w.observations.shape == (7, 3, 3) and w.actions.shape == (7, 3, 2) and w.rewards.shape == (7, 3)
    np.testing.assert_array_equal(w.index[:, 0], [0, 1, 4, 5, 6, 7, 10])
    np.testing.assert_array_equal(w.observations, tiny_dataset.observations[w.index])
    np.testing.assert_array_equal(w.next_observations, tiny_dataset.next_observations[w.index])
    assert w.valid.all() and w.first_mask[:, 0].all() and not w.first_mask[:, 1:].any()
    np.testing.assert_array_equal(w.loss_mask, ~w.first_mask)
    np.testing.assert_allclose(w.returns, tiny_dataset.rewards[w.index].sum(axis=1), rtol=1e-6)


def test_windows_never_cross_episodes(make_dataset):
    ends = ["terminal", "timeout", "timeout", "terminal", "terminal"]
    dataset = make_dataset(lengths=(5, 2, 7, 1, 9), ends=ends)
    episode = _episode_of(dataset)
    for stride in (1, 2, 3):
        for short in ("skip", "pad"):
            w = make_windows(dataset, 4, stride=stride, short_episodes=short)
            ids = np.where(w.valid, episode[np.maximum(w.index, 0)], -1)
            assert all(len(set(row[row >= 0])) == 1 for row in ids)
            ends = (dataset.terminals | dataset.timeouts)[np.maximum(w.index, 0)] & w.valid
            last_valid = w.valid.sum(axis=1) - 1
            rows, cols = np.nonzero(ends)
            np.testing.assert_array_equal(cols, last_valid[rows])  # an end only at a window's last step


def test_terminal_and_timeout_ends_are_carried(make_dataset):
    dataset = make_dataset(lengths=(4, 4), ends=["terminal", "timeout"])
    w = make_windows(dataset, 4)
    np.testing.assert_array_equal(dataset.terminals[w.index[:, -1]], [True, False])
    np.testing.assert_array_equal(dataset.timeouts[w.index[:, -1]], [False, True])


def test_stride(make_dataset):
    dataset = make_dataset(lengths=(10,))
    np.testing.assert_array_equal(window_index(dataset, 4, stride=3)[0][:, 0], [0, 3, 6])
    np.testing.assert_array_equal(window_index(dataset, 4, stride=4)[0][:, 0], [0, 4])


def test_short_episodes_skipped_and_counted(make_dataset):
    dataset = make_dataset(lengths=(2, 5, 1, 3))
    w = make_windows(dataset, 3, short_episodes="skip")
    assert w.skipped_episodes == 2
    np.testing.assert_array_equal(w.index[:, 0], [2, 3, 4, 8])
    with pytest.raises(InputError, match="all 4 episodes are shorter"):
        make_windows(dataset, 6)


def test_short_episodes_padded_and_masked(make_dataset):
    dataset = make_dataset(lengths=(2, 5))
    w = make_windows(dataset, 4, short_episodes="pad")
    assert w.skipped_episodes == 0 and len(w) == 1 + 2
    np.testing.assert_array_equal(w.index[0], [0, 1, -1, -1])
    np.testing.assert_array_equal(w.valid[0], [True, True, False, False])
    np.testing.assert_array_equal(w.loss_mask[0], [False, True, False, False])
    np.testing.assert_array_equal(w.observations[0, 2:], dataset.observations[[1, 1]])  # repeats, not zeros
    np.testing.assert_array_equal(w.actions[0, 3], dataset.actions[1])
    assert w.returns[0] == pytest.approx(float(dataset.rewards[:2].sum()), rel=1e-6)
    assert w.valid[1:].all()


def test_windows_without_next_observations(make_dataset):
    assert make_windows(make_dataset(next_observations=None), 2).next_observations is None


@pytest.mark.parametrize(
    "kwargs, message",
    [({"horizon": 0}, "horizon"), ({"horizon": 2, "stride": 0}, "stride"),
     ({"horizon": 2, "short_episodes": "zero"}, "short_episodes")],
)
def test_bad_arguments(tiny_dataset, kwargs, message):
    with pytest.raises(InputError, match=message):
        make_windows(tiny_dataset, **kwargs)
