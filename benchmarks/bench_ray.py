"""`xted bench` run both ways, the local executor and Ray tasks, and the overhead Ray adds.

    python benchmarks/bench_ray.py [--gaps thigh,gravity] [--columns "Src,Tgt+Src,Tgt+Oracle,Tgt+Src DARA"]
        [--seeds 0] [--steps 500] [--eval-every 250] [--eval-episodes 1] [--transitions 2000]
        [--num-cpus N] [--json FILE]

One grid (by default 2 gaps x 4 columns x 1 seed: 8 learner cells in 8 groups of seeds, so 8 Ray
tasks, plus 2 oracle relabellings) is computed from scratch by the local executor, then by the Ray
executor on a local instance (``--num-cpus``, default: this machine's; its workers start fresh),
each into its own temporary store and cache. Also measured: the local instance's start, the median
round trip of a trivial task (one at a time, after warm-up), the time per trivial task when many
are in flight, and the import of xted's task module that a fresh worker pays before its first
task (in a subprocess). Checks that both ways stored the same
results (timings aside) and prints one JSON object.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import ray

from xted.pipelines.bench.config import BenchConfig, RayConfig
from xted.pipelines.bench.run import run_bench

TIMINGS = ("seconds", "updates_per_second")


def stored(folder: Path) -> dict[str, dict]:
    return {path.name: {k: v for k, v in json.loads(path.read_text()).items() if k not in TIMINGS}
            for path in sorted(folder.rglob("*.json"))}


def timed(fn) -> tuple[float, object]:
    began = time.perf_counter()
    value = fn()
    return time.perf_counter() - began, value


@ray.remote
def nothing() -> None:
    return None


def trivial_tasks() -> dict:
    """Round trip of a task that does nothing (one at a time, after warm-up), and time per task with
    500 in flight, on the running instance."""
    ray.get([nothing.remote() for _ in range(4 * int(ray.cluster_resources()["CPU"]))])  # workers up
    round_trips = [timed(lambda: ray.get(nothing.remote()))[0] for _ in range(50)]
    in_flight, _ = timed(lambda: ray.get([nothing.remote() for _ in range(500)]))
    return {"trivial_task_round_trip_median_ms": 1e3 * statistics.median(round_trips),
            "trivial_task_in_flight_ms_per_task": 1e3 * in_flight / 500}


def task_module_import_s() -> float:
    """What a fresh worker pays before its first bench task: importing the task module (and JAX)."""
    code = ("import time; began = time.perf_counter(); import xted.pipelines.bench.ray_executor; "
            "print(time.perf_counter() - began)")
    return float(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--envs", default="halfcheetah")
    parser.add_argument("--gaps", default="thigh,gravity")
    parser.add_argument("--columns", default="Src,Tgt+Src,Tgt+Oracle,Tgt+Src DARA")
    parser.add_argument("--seeds", default="0")
    parser.add_argument("--steps", type=int, default=500)
    parser.add_argument("--eval-every", type=int, default=250)
    parser.add_argument("--eval-episodes", type=int, default=1)
    parser.add_argument("--transitions", type=int, default=2000)
    parser.add_argument("--num-cpus", type=int, default=None, help="Ray's CPUs (default: this machine's).")
    parser.add_argument("--json", type=Path, default=None, help="Also write the numbers here.")
    args = parser.parse_args()

    def config(folder: Path) -> BenchConfig:
        return BenchConfig(
            envs=tuple(args.envs.split(",")), gaps=tuple(args.gaps.split(",")), columns=tuple(args.columns.split(",")),
            seeds=tuple(int(seed) for seed in args.seeds.split(",")), steps=args.steps, eval_every=args.eval_every,
            eval_episodes=args.eval_episodes, transitions=args.transitions, store=str(folder / "store"),
            cache=str(folder / "cache"))

    quiet = dict(progress=False, echo=lambda message: None)
    with tempfile.TemporaryDirectory(prefix="bench-ray-") as work:
        local_dir, ray_dir = Path(work) / "local", Path(work) / "ray"
        local_s, computed = timed(lambda: run_bench(config(local_dir), **quiet))
        start_s, _ = timed(lambda: ray.init(num_cpus=args.num_cpus, include_dashboard=False))
        try:
            numbers = {"ray_cpus": int(ray.cluster_resources()["CPU"]), "local_instance_start_s": start_s}
            ray_s, _ = timed(lambda: run_bench(config(ray_dir), ray=RayConfig(), **quiet))  # fresh workers
            numbers.update(trivial_tasks())
        finally:
            ray.shutdown()
        numbers["task_module_import_s"] = task_module_import_s()
        local, on_ray = stored(local_dir / "store"), stored(ray_dir / "store")
    learners = [name for name in computed if not name.startswith(("edit-", "oracle-"))]
    numbers = {
        "learner_cells": len(learners), "data_cells": len(computed) - len(learners),
        "local_executor_s": local_s, "ray_executor_s": ray_s,
        "ray_executor_with_instance_start_s": ray_s + numbers["local_instance_start_s"], **numbers,
        "same_results": local == on_ray and len(local) == len(computed),
    }
    text = json.dumps(numbers, indent=1)
    print(text)
    if args.json is not None:
        args.json.write_text(text + "\n")


if __name__ == "__main__":
    main()
