"""``xted bench --executor ray`` on a local Ray instance of 2 CPUs: the same results as the local
executor (bitwise), a killed worker's task run again, and cells that still fail reported by name."""

from __future__ import annotations

import dataclasses
import json
import os
import signal
from pathlib import Path

import pytest

from xted.cli.main import main
from xted.pipelines.bench import store
from xted.pipelines.bench.config import BenchConfig, RayConfig
from xted.pipelines.bench.grid import plan
from xted.pipelines.bench.run import CellsFailed, Work, run_bench

ray = pytest.importorskip("ray")

TIMINGS = ("seconds", "updates_per_second", "group_seconds")


@pytest.fixture(scope="module")
def local_ray():
    """One local instance for the module: ``run_bench`` uses a Ray already initialised in its process."""
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield
    ray.shutdown()


def stored(folder: Path) -> dict[str, dict]:
    """Every result in a store by file name, without the timings (which differ run to run)."""
    results = {}
    for path in sorted(folder.rglob("*.json")):
        results[path.name] = {name: value for name, value in json.loads(path.read_text()).items()
                              if name not in TIMINGS}
    return results


@pytest.mark.slow
def test_ray_and_local_executors_store_the_same_results(tmp_path, local_ray, capsys):
    """Two learner groups (Tgt; Tgt+Oracle, which waits for its oracle task), real IQL, on CPU."""
    options = ["--envs", "halfcheetah", "--gaps", "thigh", "--columns", "Tgt,Tgt+Oracle", "--seeds", "0,1",
               "--steps", "200", "--eval-every", "100", "--eval-episodes", "1", "--transitions", "2000"]
    for executor in ("local", "ray"):
        assert main(["bench", "run", *options, "--executor", executor, "--store", str(tmp_path / executor / "store"),
                     "--cache", str(tmp_path / executor / "cache")]) == 0
        assert "5 cells computed" in capsys.readouterr().out  # the oracle and 2 x 2 learner cells
    local, on_ray = stored(tmp_path / "local" / "store"), stored(tmp_path / "ray" / "store")
    assert len(local) == 5 and local.keys() == on_ray.keys()
    for name in local:
        assert on_ray[name] == local[name], name  # scores and eval curves compared as exact floats
    curves = [json.dumps(result["evals"]) for result in local.values() if "evals" in result]
    assert len(curves) == 4 and len(set(curves)) == 4  # every cell's curve its own: equality is no accident


def fake_work(attempts: Path, deaths: dict[str, int], fail_data: bool = False) -> Work:
    """Training that records each attempt in ``attempts/KEY`` and SIGKILLs its own worker while a
    group (by column) has died fewer than ``deaths[column]`` times; data made by a fake that raises
    where ``fail_data``. Closures, so Ray ships them to the workers by value."""

    def train_group(group, training, progress):
        marker = attempts / group[0].key
        done = int(marker.read_text()) if marker.exists() else 0
        marker.write_text(str(done + 1))
        if done < deaths.get(group[0].column, 0):
            os.kill(os.getpid(), signal.SIGKILL)
        size = sum(len(data) for data in training)
        return [{"seed": cell.seed, "final_score": size + cell.seed, "best_score": size + cell.seed,
                 "evals": [{"step": 1, "normalized_score": size + cell.seed}], "updates_per_second": 1.0}
                for cell in group]

    def make_data(cell, source):
        if fail_data:
            raise RuntimeError("no oracle today")
        return source

    return Work(make_data=make_data, train_group=train_group)


def attempts_of(attempts: Path, group_key: str) -> int:
    return int((attempts / group_key).read_text())


@pytest.mark.slow
def test_a_killed_worker_is_retried_and_cells_that_still_fail_are_reported(tmp_path, local_ray):
    attempts = tmp_path / "attempts"
    attempts.mkdir()
    config = BenchConfig(envs=("halfcheetah",), gaps=("thigh",), columns=("Tgt", "Tgt+Oracle"), seeds=(0,),
                         steps=10, eval_every=10, eval_episodes=1, transitions=200, store=str(tmp_path / "store"),
                         cache=str(tmp_path / "cache"))

    def run(config, work, retries):
        return run_bench(config, progress=False, echo=lambda message: None, ray=RayConfig(retries=retries), work=work)

    # Each group's worker dies on its first attempt: the retry stores every cell.
    computed = run(config, fake_work(attempts, {"Tgt": 1, "Tgt+Oracle": 1}), retries=1)
    learners = list(plan(config).learners.values())
    assert len(computed) == 3 and all(store.read_result(config.store, cell) is not None for cell in learners)
    assert [attempts_of(attempts, cell.key) for cell in learners] == [2, 2]

    # Tgt's worker always dies: after 1 + 2 attempts its cell is reported; Tgt+Oracle's is stored.
    config = dataclasses.replace(config, seeds=(1,))
    with pytest.raises(CellsFailed) as failure:
        run(config, fake_work(attempts, {"Tgt": 99}), retries=2)
    tgt, oracle = plan(config).learners.values()
    assert failure.value.failed == [(tgt.name, "its worker died, 3 times")]
    assert failure.value.computed == [oracle.name]
    assert attempts_of(attempts, tgt.key) == 3
    assert store.read_result(config.store, tgt) is None and store.read_result(config.store, oracle) is not None

    # A data cell that raises is reported at once (no retry), and so is the learner that reads it.
    config = dataclasses.replace(config, seeds=(2,), cache=str(tmp_path / "other-cache"))
    with pytest.raises(CellsFailed) as failure:
        run(config, fake_work(attempts, {}, fail_data=True), retries=2)
    tgt, oracle = plan(config).learners.values()
    assert dict(failure.value.failed) == {
        oracle.data_cell.name: "RuntimeError: no oracle today",
        oracle.name: f"reads {oracle.data_cell.name}, which failed"}
    assert failure.value.computed == [tgt.name] and not (attempts / oracle.key).exists()


@pytest.mark.slow
def test_a_prior_the_bench_trains_is_trained_by_the_driver_before_its_edit_task(tmp_path, local_ray):
    """halfcheetah-medium has no shipped prior: the driver trains it (2 steps) into its cache, and the
    edit task on the worker reads that folder."""
    config = BenchConfig(envs=("halfcheetah",), targets=("medium",), gaps=("thigh",), columns=("Tgt+Edited",),
                         seeds=(0,), steps=10, eval_every=10, eval_episodes=1, transitions=2500, kappa=0.05,
                         prior_steps=2, store=str(tmp_path / "store"), cache=str(tmp_path / "cache"))
    (cell,) = plan(config).learners.values()
    computed = run_bench(config, progress=False, echo=lambda message: None, ray=RayConfig())
    assert computed[0] == cell.data_cell.prior_cell.name and set(computed[1:]) == {cell.data_cell.name, cell.name}
    assert store.read_result(config.store, cell.data_cell.prior_cell)["steps"] == 2
    assert store.read_result(config.store, cell)["edit_key"] == cell.data_cell.key
