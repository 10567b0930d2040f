"""``xted policy`` through the real CLI entry point, on a few hundred random halfcheetah steps."""

from __future__ import annotations

import json

import pytest

import xted.rl.offline_train
from xted.cli.main import main
from xted.data import save
from xted.pipelines.behaviour_data import build_dataset
from xted.envs import parse_domain


@pytest.fixture(scope="module")
def halfcheetah(tmp_path_factory):
    path = tmp_path_factory.mktemp("data") / "halfcheetah-random.npz"
    save(build_dataset(parse_domain("halfcheetah"), "random", 300, None, progress=False), path)
    return path


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
