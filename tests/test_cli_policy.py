"""``xted policy`` through the real CLI entry point, on a few hundred random halfcheetah steps."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

import xted.rl.offline_train
from xted.cli.main import main
from xted.data import save
from xted.pipelines.behaviour_data import build_dataset
from xted.envs import parse_domain
from xted.errors import InputError


@pytest.fixture(scope="module")
def halfcheetah(tmp_path_factory):
    path = tmp_path_factory.mktemp("data") / "halfcheetah-random.npz"
    save(build_dataset(parse_domain("halfcheetah"), "random", 300, None, progress=False), path)
    return path


@pytest.mark.slow
def test_policy_json_and_resume(halfcheetah, tmp_path, capsys, monkeypatch):
    args = ["policy", "--algo", "iql", "--target", str(halfcheetah), "--source", str(halfcheetah),
            "--env", "halfcheetah", "--steps", "20", "--seeds", "0,1", "--eval-episodes", "1",
            "--out", str(tmp_path / "run"), "--json"]
    assert main(args) == 0
    out = json.loads(capsys.readouterr().out)
    assert (out["algo"], out["env"], out["domain"]) == ("iql", "halfcheetah", "halfcheetah")
    assert len(out["scores"]) == len(out["best_scores"]) == 2
    assert all(best >= final for best, final in zip(out["best_scores"], out["scores"]))
    assert sorted(p.name for p in (tmp_path / "run").iterdir()) == ["seed_0.json", "seed_1.json"]

    def no_training(*args, **kwargs):
        raise AssertionError("finished seeds were trained again")

    monkeypatch.setattr(xted.rl.offline_train, "_train_group", no_training)
    assert main(args) == 0
    assert json.loads(capsys.readouterr().out)["scores"] == out["scores"]
    assert main([*args, "--steps", "30"]) == 2  # --out holds results of another run
    # Same transition count, other data: refused too, not silently reused.
    other = tmp_path / "other.npz"
    save(build_dataset(parse_domain("halfcheetah"), "random", 300, None, seed=1, progress=False), other)
    other_args = [str(other) if a == str(halfcheetah) else a for a in args]
    rc = main(other_args)
    assert rc == 2 and "data" in capsys.readouterr().err
    monkeypatch.undo()
    assert main([*other_args, "--force"]) == 0  # --force discards the old results and trains afresh
    retrained = json.loads(capsys.readouterr().out)
    assert retrained["scores"] != out["scores"]
    assert main(other_args) == 0  # and the new results are resumed from


@pytest.mark.slow
def test_save_policies_and_resume_from_them(halfcheetah, tmp_path, capsys, monkeypatch):
    from xted.api import load_policy
    from xted.data import load
    from xted.rl.offline_train import seed_policy
    from xted.rl.config import BCConfig

    save_dir = tmp_path / "policies"
    args = ["policy", "--algo", "bc", "--target", str(halfcheetah), "--env", "halfcheetah", "--steps", "30",
            "--seeds", "0,1", "--eval-episodes", "1", "--set", "hidden=16,16", "--save", str(save_dir), "--json"]
    assert main(args) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["saved"] == [str(save_dir / "seed_0"), str(save_dir / "seed_1")]
    policy = load_policy(save_dir / "seed_1")
    assert policy.meta["seed"] == 1 and policy.meta["algo"] == "bc" and policy.scores["final_score"] == out["scores"][1]
    assert policy.meta["data"] == [load(halfcheetah).fingerprint()]
    with pytest.raises(InputError, match="policies of 2 seeds"):
        load_policy(save_dir)
    # The saved policy acts as the one evaluated in training did: standardise, then the actor.
    obs = load(halfcheetah).observations[:7]
    evaluated = seed_policy(BCConfig(hidden=(16, 16)), _actor_state(policy), np.asarray(policy.meta["obs_mean"]),
                            np.asarray(policy.meta["obs_std"]))
    np.testing.assert_allclose(policy.act(obs), evaluated(obs), atol=1e-6)
    np.testing.assert_allclose(policy.act(obs[3]), policy.act(obs)[3], atol=1e-6)
    with pytest.raises(InputError, match="takes 17 features"):
        policy.act(obs[:, :5])
    capsys.readouterr()
    assert main(["online", "evaluate", str(save_dir / "seed_1"), "--env", "halfcheetah", "--episodes", "1",
                 "--json"]) == 0  # the saved policy, deployed in the simulator
    assert json.loads(capsys.readouterr().out)["domain"] == "halfcheetah"

    monkeypatch.setattr(xted.rl.offline_train, "_train_group", lambda *a: pytest.fail("saved seeds were retrained"))
    assert main(args) == 0
    assert json.loads(capsys.readouterr().out)["scores"] == out["scores"]
    assert main([*args, "--steps", "31"]) == 2  # --save holds policies of another run
    monkeypatch.undo()
    assert main([*args, "--steps", "31", "--force"]) == 0
    assert load_policy(save_dir / "seed_0").meta["steps"] == 31


def _actor_state(policy):
    """A TrainState-like holder of a saved policy's parameters, as ``seed_policy`` takes."""
    from flax.training.train_state import TrainState

    from xted.rl.networks import DeterministicPolicy

    module = DeterministicPolicy(tuple(policy.meta["hidden"]), policy.meta["action_dim"])
    return TrainState(step=0, apply_fn=module.apply, params=policy.params, tx=None, opt_state=None)


@pytest.mark.slow
def test_train_without_a_simulator(halfcheetah, tmp_path, capsys, monkeypatch):
    from xted.api import load_policy
    from xted.data import load

    unknown_env = tmp_path / "robot.npz"
    save(dataclasses.replace(load(halfcheetah), metadata={}), unknown_env)
    args = ["policy", "--algo", "iql", "--target", str(unknown_env), "--steps", "20", "--set", "hidden=16,16"]
    assert main(args) == 2 and "give --save DIR" in capsys.readouterr().err  # nothing would come of it
    monkeypatch.setattr(xted.rl.offline_train, "evaluate", lambda *a, **k: pytest.fail("evaluated without an env"))
    assert main([*args, "--save", str(tmp_path / "p")]) == 0
    printed = capsys.readouterr().out
    assert "not evaluated (no env); last losses: " in printed and "value_loss" in printed and "critic_loss" in printed
    policy = load_policy(tmp_path / "p")  # the one seed's folder
    assert policy.meta["domain"] is None and policy.scores["final_score"] is None and policy.kind == "gaussian"
    (last,) = policy.scores["losses"]  # one segment of 20 updates: its mean losses, for judging convergence
    assert last["step"] == 20 and {"value_loss", "actor_loss", "critic_loss", "q"} <= set(last)
    # Data of a known env trains without one too when asked: --env none.
    assert main(["policy", "--target", str(halfcheetah), "--env", "none", "--steps", "5", "--set", "hidden=8,8",
                 "--save", str(tmp_path / "q"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["mean"] is None
    assert main(["policy", "--target", str(halfcheetah), "--env", "none", "--steps", "5"]) == 2
    assert main([*args, "--gap", "thigh", "--save", str(tmp_path / "r")]) == 2


@pytest.mark.slow
def test_dara_with_nested_overrides(halfcheetah, capsys):
    args = ["policy", "--algo", "dara", "--target", str(halfcheetah), "--source", str(halfcheetah),
            "--env", "halfcheetah", "--steps", "5", "--eval-episodes", "1", "--set", "classifier_steps=10",
            "--set", "classifier_hidden=16", "--set", "iql.hidden=32,32", "--set", "iql.normalize_rewards=true"]
    assert main(args) == 0
    assert "dara in halfcheetah" in capsys.readouterr().out


@pytest.mark.parametrize("change", [
    ["--algo", "sac"],
    ["--seeds", "0,x"],
    ["--seeds", "1,1"],
    ["--steps", "0"],
    ["--set", "bogus=1"],
    ["--set", "hidden=64,x"],
    ["--algo", "dara", "--set", "iql=3"],
    ["--algo", "dara"],  # no source to correct
    ["--source", "SMALL"],  # 3-d observations, 2-d actions
    ["--target", "SMALL"],
    ["--env", "walker3d"],
])
def test_bad_input_exits_2(change, halfcheetah, tmp_path, tiny_dataset, monkeypatch):
    monkeypatch.setattr(xted.rl.offline_train, "_train_group", lambda *a: pytest.fail("trained on bad input"))
    save(tiny_dataset, tmp_path / "small.npz")
    change = [str(tmp_path / "small.npz") if c == "SMALL" else c for c in change]
    base = ["policy", "--target", str(halfcheetah), "--env", "halfcheetah", "--steps", "10", "--seeds", "0"]
    assert main([*base, *change]) == 2  # a repeated option's last value wins
