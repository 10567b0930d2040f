"""Reward-free data end to end (the paper's real-robot setting): load, train a prior without the
reward stream, edit, behaviour-clone on target + edited; and high-dimensional (embedding) states."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from conftest import build_dataset

import xted
from xted.cli.main import main
from xted.data import Dataset, formats
from xted.diffusion.config import preset
from xted.errors import InputError


def reward_free(**kwargs) -> Dataset:
    return dataclasses.replace(build_dataset(**kwargs), rewards=None)


def test_a_dataset_without_rewards():
    data = reward_free(lengths=(5, 7))
    assert not data.has_rewards and data.metadata["reward_free"] is True
    np.testing.assert_array_equal(data.rewards, np.zeros(12, np.float32))
    summary = data.summary()
    assert summary["rewards"] is False and summary["return_mean"] is None
    assert build_dataset().has_rewards and build_dataset().summary()["rewards"] is True
    assert not Dataset.concatenate([data, build_dataset()]).has_rewards  # some rewards unknown: none known
    assert not data.select_episodes([1]).has_rewards
    with pytest.raises(InputError, match="says the data has no rewards, but rewards has nonzero entries"):
        dataclasses.replace(data, rewards=np.ones(12))


@pytest.mark.parametrize("suffix", [".npz", ".hdf5", "-minari"])
def test_reward_free_files_round_trip(suffix, tmp_path):
    data = reward_free(lengths=(5, 7))
    path = tmp_path / f"robot{suffix}"
    formats.save(data, path)
    back = formats.load(path)
    assert not back.has_rewards and back.fingerprint() == data.fingerprint()
    if suffix == ".npz":
        with np.load(path) as archive:
            assert "rewards" not in archive.files  # the file holds no made-up rewards


def test_a_file_without_rewards_loads_as_reward_free(tmp_path):
    data = build_dataset(lengths=(5, 7))
    np.savez(tmp_path / "demos.npz", **{k: getattr(data, k) for k in ("observations", "actions", "terminals",
                                                                     "timeouts", "next_observations")})
    loaded = xted.load_dataset(tmp_path / "demos.npz")
    assert not loaded.has_rewards and len(loaded) == 12
    assert main(["data", "info", str(tmp_path / "demos.npz")]) == 0


@pytest.mark.slow
def test_reward_free_prior_edit_and_bc(tmp_path):
    target, source = reward_free(lengths=(9, 10, 12), seed=0), reward_free(lengths=(9, 12), seed=1)
    prior = xted.train_prior(target, out=tmp_path / "prior", steps=3, progress=False, preset="tiny")
    assert not prior.config.use_reward and not prior.config.return_condition  # turned off by the data
    edited = prior.edit(source, kappa=0.5, seed=0)
    assert not edited.has_rewards and not np.allclose(edited.observations[1:9], source.observations[1:9])
    policy = xted.train_policy("bc", target, sources=[edited], steps=10, progress=False, hidden=(8, 8))
    assert policy.act(target.observations[:3]).shape == (3, 2)
    with pytest.raises(InputError, match="iql needs rewards.*train bc"):
        xted.train_policy("iql", target, sources=[edited], steps=1)
    with pytest.raises(InputError, match="reward stream or return conditioning needs rewards"):
        xted.train_prior(target, out=tmp_path / "other", steps=1, use_reward=True, preset="tiny")
    rewarded = xted.train_prior(build_dataset(lengths=(9, 10, 12)), out=tmp_path / "rewarded", steps=1,
                                progress=False, preset="tiny")
    with pytest.raises(InputError, match="this prior's reward stream needs rewards"):
        rewarded.edit(source)


def test_reward_free_from_the_command_line(tmp_path, capsys):
    target, source = tmp_path / "target.npz", tmp_path / "source.npz"
    formats.save(reward_free(lengths=(9, 10, 12), seed=0), target)
    formats.save(reward_free(lengths=(9, 12), seed=1), source)
    assert main(["train", "--target", str(target), "--out", str(tmp_path / "prior"), "--steps", "2",
                 "--preset", "tiny"]) == 0
    edited = tmp_path / "edited.npz"
    assert main(["edit", "--prior", str(tmp_path / "prior"), "--source", str(source), "--out", str(edited)]) == 0
    assert not formats.load(edited).has_rewards
    capsys.readouterr()
    assert main(["policy", "--algo", "bc", "--target", str(target), "--source", str(edited), "--steps", "5",
                 "--set", "hidden=8,8", "--save", str(tmp_path / "bc"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["saved"] == [str(tmp_path / "bc" / "seed_0")]
    assert main(["policy", "--algo", "td3bc", "--target", str(target), "--steps", "5",
                 "--save", str(tmp_path / "td3")]) == 2
    assert "td3bc needs rewards" in capsys.readouterr().err


@pytest.mark.slow
def test_embedding_states_at_the_cpu_preset(tmp_path):
    """1024-d states (the paper's DecisionNCE embeddings): the cpu preset caps stream widths at 1024,
    the paper's 1x for them, and a prior trains and edits at that size."""
    config = preset("cpu", 1024, 7, rewards=False)
    assert config.denoiser.width("state") == 1024 and config.denoiser.width("action") == 32
    assert preset("cpu", 17, 6).denoiser.width("state") == 68  # the shipped priors' widths are unchanged
    target = reward_free(lengths=(6, 6), obs_dim=1024, act_dim=7)
    prior = xted.train_prior(target, out=tmp_path / "prior", steps=1, progress=False, horizon=4, batch_size=2,
                             num_timesteps=4)
    assert prior.config.max_width == 1024
    edited = prior.edit(target, kappa=0.5)
    assert edited.observations.shape == (12, 1024) and not edited.has_rewards
