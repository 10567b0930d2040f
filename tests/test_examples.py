"""Every script in ``examples/`` runs as written, on tiny settings (its own flags), in-process."""

from __future__ import annotations

import dataclasses
import runpy
import sys
from pathlib import Path

import pytest
from conftest import build_dataset, first_steps

import xted

EXAMPLES = Path(__file__).parent.parent / "examples"


def run_example(name: str, *args: str, monkeypatch) -> None:
    monkeypatch.setattr(sys, "argv", [name, *args])
    runpy.run_path(str(EXAMPLES / name), run_name="__main__")


def test_every_example_has_a_test():
    tested = {"simulator_benchmark.py", "own_data_with_simulator.py", "own_data_without_simulator.py",
              "reward_free_bc.py"}
    assert {p.name for p in EXAMPLES.glob("*.py")} == tested


@pytest.mark.slow
def test_simulator_benchmark(monkeypatch, capsys):
    run_example("simulator_benchmark.py", "--policy-steps", "20", "--eval-episodes", "1", "--source-episodes", "1",
                monkeypatch=monkeypatch)
    out = capsys.readouterr().out
    assert "one-step error in the target simulator" in out and "Tgt+Edited: normalised score" in out


@pytest.fixture
def own_data(tmp_path):
    """A small halfcheetah target and 2x-thigh source, as a user's own files."""
    target, source = tmp_path / "target.hdf5", tmp_path / "source.npz"
    xted.save_dataset(first_steps("halfcheetah-medium", 60, next_observations=True), target)
    xted.save_dataset(first_steps("halfcheetah-thigh", 40, next_observations=True), source)
    return str(target), str(source)


@pytest.mark.slow
def test_own_data_with_simulator(own_data, tmp_path, monkeypatch, capsys):
    run_example("own_data_with_simulator.py", "--target", own_data[0], "--source", own_data[1], "--env",
                "halfcheetah", "--out", str(tmp_path / "run"), "--preset", "tiny", "--prior-steps", "3",
                "--policy-steps", "20", "--eval-episodes", "1", "--proxy-steps", "20", monkeypatch=monkeypatch)
    assert "IQL on target + edited" in capsys.readouterr().out
    assert xted.load_policy(tmp_path / "run" / "policy").scores["final_score"] is not None


@pytest.mark.slow
def test_own_data_without_simulator(own_data, tmp_path, monkeypatch, capsys):
    run_example("own_data_without_simulator.py", "--target", own_data[0], "--source", own_data[1],
                "--out", str(tmp_path / "run"), "--preset", "tiny", "--prior-steps", "3", "--policy-steps", "20",
                "--proxy-steps", "20", monkeypatch=monkeypatch)
    assert "its action for the first target state" in capsys.readouterr().out
    assert len(xted.load_dataset(tmp_path / "run" / "edited.hdf5")) == 80
    assert xted.load_policy(tmp_path / "run" / "policy").meta["domain"] is None


@pytest.mark.slow
def test_reward_free_bc(tmp_path, monkeypatch, capsys):
    target, source = tmp_path / "robot_target.npz", tmp_path / "robot_source.npz"
    xted.save_dataset(dataclasses.replace(build_dataset(lengths=(9, 10, 12), seed=0), rewards=None), target)
    xted.save_dataset(dataclasses.replace(build_dataset(lengths=(9, 12), seed=1), rewards=None), source)
    run_example("reward_free_bc.py", "--target", str(target), "--source", str(source), "--out",
                str(tmp_path / "run"), "--preset", "tiny", "--prior-steps", "3", "--policy-steps", "20",
                monkeypatch=monkeypatch)
    out = capsys.readouterr().out
    assert "rewards: False" in out and "prior streams: state, action\n" in out
    assert xted.load_policy(tmp_path / "run" / "policy").meta["algo"] == "bc"


def test_the_d3rlpy_hand_off_in_the_docs(tmp_path, monkeypatch):
    d3rlpy = pytest.importorskip("d3rlpy")  # an optional library: this block runs where it is installed
    doc = (Path(__file__).parent.parent / "docs" / "own_data.md").read_text()
    block = doc.split("```python\nimport d3rlpy\n", 1)[1].split("```", 1)[0]
    xted.save_dataset(first_steps("halfcheetah-medium", 50, next_observations=True), tmp_path / "edited.hdf5")
    monkeypatch.chdir(tmp_path)
    scope: dict = {"d3rlpy": d3rlpy}
    exec("import d3rlpy\n" + block, scope)
    assert len(scope["mdp"].episodes) == 2


@pytest.mark.slow
def test_the_readme_python_example(tmp_path, monkeypatch):
    """README's Python block as written, with its step counts made tiny (the only changes)."""
    readme = (Path(__file__).parent.parent / "README.md").read_text()
    block = readme.split("```python\n", 1)[1].split("```", 1)[0]
    tiny = {"steps=30_000": "steps=20, eval_episodes=1",
            'env="halfcheetah")  # proxy': 'env="halfcheetah", proxy_steps=20)  # proxy'}
    for written, quick in tiny.items():
        assert block.count(written) == 1, written
        block = block.replace(written, quick)
    monkeypatch.chdir(tmp_path)
    scope: dict = {}
    exec(block, scope)
    assert scope["action"].shape == (6,) and scope["report"]["simulator"]["edited"]["n"] == 20_000
    assert (tmp_path / "runs" / "policy" / "policy.msgpack").exists()
