"""Windows of horizon H cut from episodes (training) and the editor's one-step-overlap tiling."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

from xted.data.windows import WindowSampler, tile_episodes, window_index
from xted.errors import InputError


def _episode_of(dataset):
    bounds = dataset.episode_bounds()
    return np.repeat(np.arange(len(bounds)), bounds[:, 1] - bounds[:, 0])


def test_full_windows_stride_one(tiny_dataset):
    index, skipped = window_index(tiny_dataset, horizon=3)
    assert index.shape == ((4 - 2) + (6 - 2) + (3 - 2), 3) and skipped == 0
    np.testing.assert_array_equal(index[:, 0], [0, 1, 4, 5, 6, 7, 10])
    np.testing.assert_array_equal(np.diff(index, axis=1), 1)


def test_windows_never_cross_episodes(make_dataset):
    ends = ["terminal", "timeout", "timeout", "terminal", "terminal"]
    dataset = make_dataset(lengths=(5, 2, 7, 1, 9), ends=ends)
    episode = _episode_of(dataset)
    for stride in (1, 2, 3):
        index, _ = window_index(dataset, 4, stride=stride)
        assert all(len(set(row)) == 1 for row in episode[index])
        ends_inside = (dataset.terminals | dataset.timeouts)[index[:, :-1]]
        assert not ends_inside.any()  # an episode end only at a window's last step


def test_stride(make_dataset):
    dataset = make_dataset(lengths=(10,))
    np.testing.assert_array_equal(window_index(dataset, 4, stride=3)[0][:, 0], [0, 3, 6])
    np.testing.assert_array_equal(window_index(dataset, 4, stride=4)[0][:, 0], [0, 4])


def test_short_episodes_skipped_and_counted(make_dataset):
    dataset = make_dataset(lengths=(2, 5, 1, 3))
    index, skipped = window_index(dataset, 3)
    assert skipped == 2
    np.testing.assert_array_equal(index[:, 0], [2, 3, 4, 8])
    with pytest.raises(InputError, match="all 4 episodes are shorter"):
        window_index(dataset, 6)


@pytest.mark.parametrize("kwargs, message", [({"horizon": 0}, "horizon"), ({"horizon": 2, "stride": 0}, "stride"),
                                             ({"horizon": 2.5}, "horizon")])
def test_bad_arguments(tiny_dataset, kwargs, message):
    with pytest.raises(InputError, match=message):
        window_index(tiny_dataset, **kwargs)


def test_sampler_gathers_windows_with_their_returns(tiny_dataset):
    index, _ = window_index(tiny_dataset, 3)
    flat = {"state": tiny_dataset.observations}
    returns = tiny_dataset.rewards[index].sum(axis=1)
    sampler = WindowSampler(flat=flat, index=index, returns=returns, loss_mask=np.array([False, True, True]))
    batch = sampler.batch(np.random.default_rng(0), 16)
    assert batch["state"].shape == (16, 3, tiny_dataset.observation_dim) and batch["loss_mask"].shape == (16, 3)
    for states, ret in zip(batch["state"], batch["returns"]):
        row = next(i for i in range(len(index)) if np.array_equal(tiny_dataset.observations[index[i]], states))
        assert ret == pytest.approx(returns[row])


@pytest.mark.parametrize("horizon", [2, 3, 5])
def test_tiling_puts_every_transition_inside_one_window(make_dataset, horizon):
    dataset = make_dataset(lengths=(1, 4, 7, 9))
    tiling = tile_episodes(dataset.episode_bounds(), horizon)
    lengths = dataset.episode_lengths()
    np.testing.assert_array_equal(tiling.passed_through, lengths + 1 < horizon)
    np.testing.assert_array_equal(np.sort(tiling.transition_steps),
                                  np.concatenate([np.arange(s, e) for (s, e), p in
                                                  zip(dataset.episode_bounds(), tiling.passed_through) if not p]))
    assert (tiling.transition_position <= horizon - 2).all()  # s_t+1 is in the same window
    # Sequence rows: s_t at the window position, s_t+1 just after it, never across episodes.
    rows = tiling.window_rows[tiling.transition_window, tiling.transition_position]
    np.testing.assert_array_equal(tiling.sequence_steps[rows], tiling.transition_steps)
    assert not tiling.sequence_is_next[rows].any()
    next_rows = rows + 1
    following = np.where(tiling.sequence_is_next[next_rows], tiling.sequence_steps[next_rows],
                         tiling.sequence_steps[next_rows] - 1)
    np.testing.assert_array_equal(following, tiling.transition_steps)


@pytest.mark.parametrize("slots", [1, 2, 5])
def test_stitching_schedule_edits_each_window_after_the_one_it_starts_from(make_dataset, slots):
    dataset = make_dataset(lengths=(1, 4, 7, 9, 30))
    tiling = tile_episodes(dataset.episode_bounds(), 4)
    table = tiling.schedule(slots)
    ids = table[table >= 0]
    np.testing.assert_array_equal(np.sort(ids), np.arange(len(tiling.window_rows)))  # each window once
    step_of = np.empty(len(tiling.window_rows), np.int64)
    step_of[table[table >= 0]] = np.nonzero(table >= 0)[0]
    previous = tiling.window_previous
    assert (step_of[previous >= 0] > step_of[previous[previous >= 0]]).all()
    assert len(table) <= -(-len(ids) // slots) + 10  # the longest episode (10 windows) bounds the imbalance
    # A window's first state is the previous window's carried position, and transitions between them.
    rows = tiling.window_rows
    np.testing.assert_array_equal(rows[previous >= 0, 0],
                                  rows[previous[previous >= 0], tiling.window_carry_position[previous >= 0]])
    w, p = tiling.transition_window, tiling.transition_position
    nxt = previous >= 0
    last = {int(previous[i]): tiling.window_carry_position[i] for i in np.flatnonzero(nxt)}
    for window, position in zip(w, p):
        assert position < last.get(int(window), tiling.window_rows.shape[1] - 1)


def test_training_says_which_episodes_it_leaves_out(make_dataset):
    from xted.data import Normalizer
    from xted.diffusion.config import preset
    from xted.diffusion.training import training_windows
    from xted.errors import DataWarning

    dataset = make_dataset(lengths=(2, 7, 1, 8))
    config = dataclasses.replace(preset("tiny", 3, 2), horizon=5)
    with pytest.warns(DataWarning, match=r"2 of 4 target episodes are shorter than the prior's horizon \(5 steps\)"):
        _, info = training_windows(dataset, Normalizer.fit(dataset), config)
    assert info["skipped_episodes"] == 2


def test_one_long_episode_is_warned_of(make_dataset):
    from xted.data.windows import warn_if_one_long_episode
    from xted.errors import DataWarning

    with pytest.warns(DataWarning, match="one episode of 1500 steps"):
        warn_if_one_long_episode(make_dataset(lengths=(1500,)), "the target data")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warn_if_one_long_episode(make_dataset(lengths=(1000,)), "the target data")
        warn_if_one_long_episode(make_dataset(lengths=(900, 900)), "the target data")


def test_the_cli_prints_a_data_warning_as_one_line():
    import xted.cli.main  # noqa: F401  (installs the format)
    from xted.errors import DataWarning

    assert warnings.formatwarning("3 episodes left out", DataWarning, "x.py", 1) == "xted: warning: 3 episodes left out\n"
    assert "x.py:1" in warnings.formatwarning("other", UserWarning, "x.py", 1)
