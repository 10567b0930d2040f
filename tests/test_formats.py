"""Reading and writing .npz, D4RL-style HDF5 and Minari datasets."""

from __future__ import annotations

import warnings

import gymnasium as gym
import h5py
import minari
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from xted.data import formats, load, save, shipped
from xted.errors import InputError


@pytest.fixture(autouse=True)
def minari_root(tmp_path, monkeypatch):
    root = tmp_path / "minari-root"
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(root))
    return root


DESTINATIONS = ["out.npz", "out.hdf5", "out.h5", "minari-out-v0", "minari:xted/roundtrip-v1"]


def _dest(tmp_path, name):
    return name if name.startswith("minari:") else str(tmp_path / name)


@pytest.mark.parametrize("dest", DESTINATIONS)
@pytest.mark.parametrize("next_observations", ["consistent", "random", None])
def test_round_trip_loses_nothing(tmp_path, make_dataset, assert_same, dest, next_observations):
    dataset = make_dataset(next_observations=next_observations)
    location = save(dataset, _dest(tmp_path, dest))
    assert_same(load(_dest(tmp_path, dest)), dataset)
    assert location.format == formats.locate(_dest(tmp_path, dest)).format
    assert not [p for p in location.path.parent.iterdir() if p.name.startswith(".")]


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    lengths=st.lists(st.integers(1, 5), min_size=1, max_size=4),
    dest=st.sampled_from(["p.npz", "p.hdf5", "p-v0"]),
    next_observations=st.sampled_from(["consistent", "random", None]),
)
def test_round_trip_property(tmp_path, make_dataset, assert_same, lengths, dest, next_observations):
    dataset = make_dataset(lengths, next_observations=next_observations, obs_dim=len(lengths))
    save(dataset, tmp_path / dest)
    assert_same(load(tmp_path / dest), dataset)


def test_minari_id_lands_in_minari_root(minari_root, tiny_dataset):
    location = save(tiny_dataset, "minari:xted/tiny-v0")
    assert location.path == minari_root / "xted" / "tiny-v0"
    native = minari.load_dataset("xted/tiny-v0")
    assert native.total_steps == len(tiny_dataset) and native.total_episodes == 3
    episode = next(native.iterate_episodes())
    np.testing.assert_array_equal(episode.observations[:-1], tiny_dataset.observations[:4])
    np.testing.assert_array_equal(episode.observations[-1], tiny_dataset.next_observations[3])
    from_data_folder = load(minari_root / "xted" / "tiny-v0" / "data")
    np.testing.assert_array_equal(from_data_folder.rewards, tiny_dataset.rewards)


class _StateInInfo(gym.Wrapper):
    """Adds Pendulum's internal state (theta, theta_dot) to every info."""

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        return obs, {**info, "state": np.array(self.env.unwrapped.state)}

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        return obs, reward, terminated, truncated, {**info, "state": np.array(self.env.unwrapped.state)}


def test_reads_dataset_made_by_minari_data_collector():
    env = minari.DataCollector(_StateInInfo(gym.make("Pendulum-v1", max_episode_steps=6)), record_infos=True)
    actions = []
    for seed in range(3):
        env.reset(seed=seed)
        for _ in range(6 if seed < 2 else 4):
            actions.append(env.action_space.sample())
            env.step(actions[-1])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        native = env.create_dataset("test/pendulum-v0", algorithm_name="random")
    env.close()

    dataset = load("minari:test/pendulum-v0")
    episodes = list(native.iterate_episodes())
    assert len(dataset) == 16 and dataset.num_episodes == 3
    np.testing.assert_array_equal(dataset.episode_lengths(), [6, 6, 4])
    np.testing.assert_array_equal(dataset.actions, np.stack(actions))
    np.testing.assert_array_equal(dataset.timeouts[[5, 11, 15]], True)  # the last one cut by reset
    assert not dataset.terminals.any() and dataset.timeouts.sum() == 3
    np.testing.assert_array_equal(dataset.observations[:6], episodes[0].observations[:-1])
    np.testing.assert_array_equal(dataset.next_observations[:6], episodes[0].observations[1:])
    np.testing.assert_array_equal(dataset.rewards[12:], episodes[2].rewards.astype(np.float32))
    theta = dataset.extras["state"][:, 0]  # info[t] belongs to observation t
    np.testing.assert_allclose(dataset.observations[:, 0], np.cos(theta), atol=1e-6)
    assert dataset.metadata["env"] == "Pendulum-v1"
    assert dataset.metadata["minari_dataset_id"] == "test/pendulum-v0"


def _write_d4rl(path, n=12, timeouts=True, next_observations=True, reward_column=False):
    rng = np.random.default_rng(1)
    obs = rng.normal(size=(n, 3))
    terminals = np.zeros(n, dtype=np.float32)
    terminals[4] = 1.0
    with h5py.File(path, "w") as f:
        f["observations"] = obs
        f["actions"] = rng.normal(size=(n, 2))
        f["rewards"] = rng.normal(size=(n, 1) if reward_column else n)
        f["terminals"] = terminals
        if timeouts:
            t = np.zeros(n, dtype=bool)
            t[[8, n - 1]] = True
            f["timeouts"] = t
        if next_observations:
            f["next_observations"] = obs + 1
        f["infos/qpos"] = rng.normal(size=(n, 4))
        f["infos/goal/xy"] = rng.normal(size=(n, 2))
        f["metadata/algorithm"] = b"SAC"
        f["metadata/iteration"] = 7
        f["metadata/policy/fc0/weight"] = rng.normal(size=(4, 3))
    return obs


def test_reads_d4rl_layout(tmp_path):
    obs = _write_d4rl(tmp_path / "d4rl.hdf5")
    dataset = load(tmp_path / "d4rl.hdf5")
    np.testing.assert_array_equal(dataset.episode_bounds(), [[0, 5], [5, 9], [9, 12]])
    np.testing.assert_array_equal(dataset.observations, obs.astype(np.float32))
    np.testing.assert_array_equal(dataset.next_observations, (obs + 1).astype(np.float32))
    assert dataset.terminals.dtype == np.bool_ and dataset.terminals.sum() == 1
    assert sorted(dataset.extras) == ["goal/xy", "qpos"]
    assert dataset.metadata == {"algorithm": "SAC", "iteration": 7}


def test_reads_d4rl_file_attributes_as_metadata(tmp_path):
    _write_d4rl(tmp_path / "d4rl.hdf5")
    with h5py.File(tmp_path / "d4rl.hdf5", "a") as f:
        f.attrs["env_name"] = "Walker2d-v5"
        f.attrs["deprecated"] = True
    dataset = load(tmp_path / "d4rl.hdf5")
    assert dataset.metadata == {"algorithm": "SAC", "iteration": 7, "env_name": "Walker2d-v5", "deprecated": True}


def test_reads_d4rl_without_optional_keys(tmp_path):
    _write_d4rl(tmp_path / "bare.h5", timeouts=False, next_observations=False, reward_column=True)
    dataset = load(tmp_path / "bare.h5")
    assert dataset.next_observations is None and dataset.rewards.shape == (12,)
    np.testing.assert_array_equal(dataset.episode_bounds(), [[0, 5], [5, 12]])
    assert dataset.timeouts[-1] and dataset.timeouts.sum() == 1
    assert any("no timeouts" in note for note in dataset.metadata["notes"])
    assert any("unfinished" in note for note in dataset.metadata["notes"])


def test_overlapping_flags_keep_terminal(tmp_path, tiny_dataset):
    path = tmp_path / "both.hdf5"
    save(tiny_dataset, path)
    with h5py.File(path, "a") as f:
        f["timeouts"][9] = True
    dataset = load(path)
    assert dataset.terminals[9] and not dataset.timeouts[9]
    assert "kept as terminal" in dataset.metadata["notes"][0]


@pytest.mark.parametrize("name", ["x.npz", "x.hdf5"])
def test_missing_required_key_is_named(tmp_path, tiny_dataset, name):
    path = tmp_path / name
    if name.endswith(".npz"):
        np.savez(path, observations=tiny_dataset.observations, rewards=tiny_dataset.rewards)
    else:
        with h5py.File(path, "w") as f:
            f["observations"] = tiny_dataset.observations
            f["rewards"] = tiny_dataset.rewards
    with pytest.raises(InputError, match=f"{name}: missing required key 'actions'"):
        load(path)


def test_field_errors_name_the_file(tmp_path, tiny_dataset):
    path = tmp_path / "nan.npz"
    observations = tiny_dataset.observations.copy()
    observations[2, 1] = np.nan
    arrays = {k: getattr(tiny_dataset, k) for k in ("actions", "rewards", "terminals", "timeouts")}
    np.savez(path, observations=observations, **arrays)
    with pytest.raises(InputError, match=r"nan.npz: observations\[2, 1\] is nan"):
        load(path)


def test_corrupt_files(tmp_path, tiny_dataset):
    save(tiny_dataset, tmp_path / "good.hdf5")
    data = (tmp_path / "good.hdf5").read_bytes()
    (tmp_path / "cut.hdf5").write_bytes(data[: len(data) // 2])
    with pytest.raises(InputError, match="cut.hdf5: not a readable HDF5 file"):
        load(tmp_path / "cut.hdf5")
    (tmp_path / "junk.npz").write_bytes(b"not a zip file at all")
    with pytest.raises(InputError, match="junk.npz: not a readable .npz archive"):
        load(tmp_path / "junk.npz")
    (tmp_path / "folder").mkdir()
    with pytest.raises(InputError, match="not a Minari dataset folder"):
        load(tmp_path / "folder")


def test_path_resolution_errors(tmp_path, monkeypatch):
    (tmp_path / "x.csv").write_text("1,2")
    with pytest.raises(InputError, match="unknown extension '.csv'"):
        load(tmp_path / "x.csv")
    with pytest.raises(InputError, match="no such file"):
        load(tmp_path / "missing.npz")
    with pytest.raises(InputError, match="no such Minari dataset"):
        load("minari:nothing/here-v0")
    with pytest.raises(InputError, match="unknown extension '.csv'"):
        save(None, tmp_path / "y.csv")
    with pytest.raises(InputError, match="not a Minari dataset id"):
        save(None, "minari:no version")
    monkeypatch.setattr(shipped, "manifest", lambda: {"datasets": {"toy-medium": {"file": "toy.npz"}}})
    with pytest.raises(InputError, match="shipped datasets: toy-medium"):
        load("halfcheetah-expert")


def test_shipped_name_is_loaded(tmp_path, monkeypatch, tiny_dataset, assert_same):
    save(tiny_dataset, tmp_path / "toy.npz")
    monkeypatch.setattr(shipped, "find", lambda name: tmp_path / "toy.npz" if name == "toy-medium" else None)
    assert_same(load("toy-medium"), tiny_dataset)


def test_save_refuses_unsafe_targets(tmp_path, tiny_dataset):
    save(tiny_dataset, tmp_path / "a.npz")
    with pytest.raises(InputError, match="exists"):
        save(tiny_dataset, tmp_path / "a.npz", overwrite=False)
    (tmp_path / "precious").mkdir()
    (tmp_path / "precious" / "notes.txt").write_text("keep me")
    with pytest.raises(InputError, match="not a Minari dataset folder; refusing"):
        save(tiny_dataset, tmp_path / "precious")
    (tmp_path / "dir.npz").mkdir()
    with pytest.raises(InputError, match="is a folder"):
        save(tiny_dataset, tmp_path / "dir.npz")
    assert (tmp_path / "precious" / "notes.txt").read_text() == "keep me"


def test_failed_write_leaves_nothing(tmp_path, tiny_dataset, monkeypatch):
    def fail(*args, **kwargs):
        raise RuntimeError("disk full")

    monkeypatch.setattr(h5py.Group, "create_dataset", fail)
    for dest in ("a.hdf5", "m-v0"):
        with pytest.raises((RuntimeError, InputError), match="disk full"):
            save(tiny_dataset, tmp_path / dest)
    assert not list(tmp_path.iterdir())
