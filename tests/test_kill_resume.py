"""Kill safety: a run SIGKILLed mid-way and started again ends where an uninterrupted run ends."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import jax
import numpy as np
import pytest
from conftest import build_dataset

from xted.data import save
from xted.diffusion.prior import load_prior
from xted.envs import parse_domain
from xted.pipelines.behaviour_data import build_dataset as make_data
from xted.rl.online import actor_checkpoint
from xted.rl.policy_io import Policy

XTED = [sys.executable, "-c", "from xted.cli.main import run; run()"]


def run_killed_when(args: list[str], ready, timeout: float = 300.0) -> None:
    """Start ``xted ARGS``, SIGKILL it as soon as ``ready()`` holds, and check it was killed mid-run."""
    process = subprocess.Popen([*XTED, *args], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                               start_new_session=True)
    deadline = time.time() + timeout
    while not ready():
        assert process.poll() is None, "the run finished before it could be killed"
        assert time.time() < deadline
        time.sleep(0.05)
    os.killpg(process.pid, signal.SIGKILL)
    assert process.wait() == -signal.SIGKILL


def xted(args: list[str]) -> str:
    return subprocess.run([*XTED, *args], capture_output=True, text=True, check=True).stdout


def assert_trees_equal(a, b) -> None:
    for x, y in zip(jax.tree_util.tree_leaves(a), jax.tree_util.tree_leaves(b), strict=True):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))


@pytest.fixture(scope="module")
def tiny_files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("kill")
    save(build_dataset(lengths=(12, 9, 15), obs_dim=3, act_dim=2, seed=0), folder / "target.npz")
    return folder


@pytest.fixture(scope="module")
def tiny_halfcheetah(tmp_path_factory):
    path = tmp_path_factory.mktemp("kill") / "halfcheetah-random.npz"
    save(make_data(parse_domain("halfcheetah"), "random", 300, None, progress=False), path)
    return path


@pytest.mark.slow
def test_online_training_killed_and_resumed(tmp_path):
    def args(out: Path) -> list[str]:
        return ["online", "train", "--env", "halfcheetah", "--algo", "td3", "--out", str(out), "--steps", "2000",
                "--start-steps", "500", "--checkpoint-every", "1000", "--eval-episodes", "1"]

    run_killed_when(args(tmp_path / "killed"), lambda: (tmp_path / "killed" / "evals.csv").exists())
    xted(args(tmp_path / "killed"))
    xted(args(tmp_path / "straight"))
    assert_trees_equal(Policy.load(actor_checkpoint(tmp_path / "killed", 2000)).params,
                       Policy.load(actor_checkpoint(tmp_path / "straight", 2000)).params)


@pytest.mark.slow
def test_prior_training_killed_and_resumed(tmp_path, tiny_files):
    def args(out: Path) -> list[str]:
        return ["train", "--target", str(tiny_files / "target.npz"), "--out", str(out), "--steps", "300",
                "--checkpoint-every", "100", "--set", "width_override=8", "--set", "state_blocks=1",
                "--set", "action_blocks=1", "--set", "cond_dim=16", "--set", "horizon=5", "--set", "batch_size=8",
                "--set", "num_timesteps=10", "--set", "warmup_steps=0"]

    run_killed_when(args(tmp_path / "killed"), lambda: (tmp_path / "killed" / "checkpoints" / "100").exists())
    xted(args(tmp_path / "killed"))
    xted(args(tmp_path / "straight"))
    killed, straight = load_prior(tmp_path / "killed"), load_prior(tmp_path / "straight")
    assert killed.step == straight.step == 300
    assert_trees_equal(killed.params, straight.params)


@pytest.mark.slow
def test_offline_policy_killed_and_rerun(tmp_path, tiny_halfcheetah):
    def args(out: Path) -> list[str]:
        return ["policy", "--algo", "td3bc", "--target", str(tiny_halfcheetah), "--env", "halfcheetah",
                "--steps", "3000", "--eval-every", "3000", "--seeds", "0", "--eval-episodes", "1",
                "--out", str(out), "--json"]

    started = time.time()
    run_killed_when(args(tmp_path / "killed"), lambda: time.time() - started > 5)
    # Seeds train together and each result is written whole when they finish: nothing partial is left.
    assert not (tmp_path / "killed").exists() or not any((tmp_path / "killed").iterdir())
    killed = json.loads(xted(args(tmp_path / "killed")))
    straight = json.loads(xted(args(tmp_path / "straight")))
    assert killed["scores"] == straight["scores"]
