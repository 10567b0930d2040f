"""The public Python API (``import xted``): the pipeline a notebook runs, on tiny settings."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from conftest import build_dataset

import xted
from xted.errors import InputError


def test_import_xted_stays_light():
    code = "import sys, xted; xted.__all__; print(sorted(m for m in ('jax', 'flax', 'mujoco') if m in sys.modules))"
    assert subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip() == "[]"


@pytest.mark.slow
def test_train_edit_measure_through_the_public_names(tmp_path):
    target = build_dataset(lengths=(9, 10, 12), seed=0)
    source = build_dataset(lengths=(9, 12), seed=1)
    np.savez(tmp_path / "target.npz", **{k: getattr(target, k) for k in
                                         ("observations", "actions", "rewards", "terminals", "timeouts")})
    loaded = xted.load_dataset(tmp_path / "target.npz")
    prior = xted.train_prior(loaded, out=tmp_path / "prior", steps=3, progress=False, preset="tiny")
    assert isinstance(prior, xted.Prior) and prior.step == 3 and prior.config.horizon == 4
    assert xted.load_prior(tmp_path / "prior").step == 3  # the folder, reloaded
    edited = prior.edit(source, kappa=0.5, seed=0, guard=False)
    again = xted.load_prior(tmp_path / "prior").edit(source, kappa=0.5, seed=0, guard=False)
    guarded = prior.edit(source, kappa=0.5, seed=0)  # the default: the target model was fitted when training ended
    assert guarded.metadata["edit"]["report"]["guard"]["windows"] == edited.metadata["edit"]["report"]["windows"]
    assert isinstance(edited, xted.Dataset) and len(edited) == len(source)
    np.testing.assert_array_equal(edited.observations, again.observations)  # same seed, same edit
    assert not np.allclose(edited.observations[1:9], source.observations[1:9])
    report = xted.measure_edit(source, edited, target=target, proxy_steps=20)
    assert set(report) == {"proxy", "content", "shift"} and report["proxy"]["edited"] >= 0
    assert set(report["shift"]) == {"return_per_1000_steps"}  # no env named: no forward-velocity column
    assert set(xted.measure_edit(source, edited)) == {"content"}
    with pytest.raises(InputError, match="EditConfig has no field bogus"):
        prior.edit(source, bogus=1)
    with pytest.raises(InputError, match="PriorConfig has no field widht"):
        xted.train_prior(target, out=tmp_path / "other", steps=1, widht=3)


def test_load_prior_takes_a_shipped_prior_by_name():
    prior = xted.load_prior("halfcheetah-medium-replay-cpu")
    assert prior.env == "halfcheetah" and prior.config.state_dim == 17
    with pytest.raises(InputError, match="shipped priors: halfcheetah-medium-replay-cpu"):
        xted.load_prior("no-such-prior")


@pytest.mark.slow
def test_train_save_load_a_policy_without_a_simulator(tmp_path):
    target = build_dataset(lengths=(9, 10, 12), seed=0)
    source = build_dataset(lengths=(9, 12), seed=1)
    policy = xted.train_policy("td3bc", target, sources=[source], steps=20, seed=3, progress=False, hidden=(8, 8),
                               batch_size=16)
    assert isinstance(policy, xted.Policy) and policy.scores["final_score"] is None
    assert policy.meta["data"] == [target.fingerprint(), source.fingerprint()] and policy.meta["seed"] == 3
    loaded = xted.load_policy(policy.save(tmp_path / "policy"))
    np.testing.assert_array_equal(loaded.act(target.observations), policy.act(target.observations))
    assert np.abs(policy.act(target.observations)).max() <= 1.0
    again = xted.train_policy("td3bc", target, sources=[source], steps=20, seed=3, progress=False, hidden=(8, 8),
                              batch_size=16)
    np.testing.assert_array_equal(again.act(target.observations), policy.act(target.observations))  # same seed
    with pytest.raises(InputError, match="TD3BCConfig has no field expectile"):
        xted.train_policy("td3bc", target, steps=1, expectile=0.9)
    with pytest.raises(InputError, match="give env too"):
        xted.train_policy("bc", target, steps=1, gap="thigh")
    with pytest.raises(InputError, match="does not exist"):
        xted.load_policy(tmp_path / "nothing")


def test_split_heldout_gives_the_episodes_train_prior_leaves_out(tmp_path, monkeypatch):
    import xted.diffusion.prior
    import xted.diffusion.training

    target = build_dataset(lengths=(9, 10, 12, 11), seed=0)
    trained_on = []
    monkeypatch.setattr(xted.diffusion.training, "train_prior_folder", lambda data, out, *a, **k: trained_on.append(data))
    monkeypatch.setattr(xted.diffusion.prior, "load_prior", lambda path: None)
    xted.train_prior(target, out=tmp_path / "prior", heldout_episodes=2, preset="tiny")
    train, heldout = xted.split_heldout(target, 2)
    assert trained_on[0].fingerprint() == train.fingerprint()
    assert train.num_episodes == heldout.num_episodes == 2 and len(train) + len(heldout) == len(target)
