"""Offline RL update throughput: one seed against vmapped seeds, FLOPs per update (XLA cost
analysis) and achieved GFLOP/s next to a matmul peak measured in the same run.

    python benchmarks/offline_speed.py [--target halfcheetah-medium] [--algos iql td3bc bc]
        [--seeds 3] [--chunk 1000] [--repeats 5]

Each measurement is the median over ``repeats`` calls of the same jitted ``lax.scan`` of ``chunk``
updates that ``xted policy`` runs (batches drawn on device), after one warm-up call.
"""

from __future__ import annotations

import argparse
import json

import jax
import jax.numpy as jnp

from timing import matmul_peak, median_seconds
from xted.data import load
from xted.rl.iql import IQLConfig
from xted.rl.offline_train import default_config, init_seeds, init_state, prepare_data, train_seeds, train_steps


def flops_per_update(learner, state, key, arrays) -> float:
    """XLA's count for a one-update scan (a loop body is counted once, whatever its trip count)."""
    cost = train_steps.lower(learner, state, key, arrays, 1).compile().cost_analysis()
    return float((cost[0] if isinstance(cost, list) else cost)["flops"])


def seconds_per_update(fn, chunk: int, repeats: int) -> float:
    jax.block_until_ready(fn())  # compile
    return median_seconds(fn, repeats) / chunk


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--target", default="halfcheetah-medium")
    parser.add_argument("--algos", nargs="+", default=["iql", "td3bc", "bc"])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--chunk", type=int, default=1000)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()

    dataset = load(args.target)
    peak = matmul_peak()
    for name in args.algos:
        learner = default_config(name)
        data = prepare_data(dataset, [], normalize_rewards=isinstance(learner, IQLConfig))
        arrays = {k: jnp.asarray(v) for k, v in data.arrays.items()}
        dims = (dataset.observation_dim, dataset.action_dim)
        key = jax.random.PRNGKey(0)
        state = init_state(learner, key, *dims, 1_000_000)
        one = seconds_per_update(lambda: train_steps(learner, state, key, arrays, args.chunk), args.chunk, args.repeats)

        keys = jax.random.split(key, args.seeds)
        states = init_seeds(learner, keys, *dims, 1_000_000)
        stacked = {**arrays, "rewards": jnp.tile(arrays["rewards"], (args.seeds, 1))}
        many = seconds_per_update(lambda: train_seeds(learner, states, keys, stacked, args.chunk), args.chunk,
                                  args.repeats)

        flops = flops_per_update(learner, state, key, arrays)
        print(json.dumps({
            "algo": name, "gflop_per_update": flops / 1e9,
            "one_seed_updates_per_s": 1 / one, "one_seed_gflops": flops / one / 1e9,
            "seeds": args.seeds, "vmapped_seed_updates_per_s": args.seeds / many,
            "vmapped_gflops": args.seeds * flops / many / 1e9, "vmap_speedup": args.seeds * one / many,
            "matmul_peak_gflops": peak,
        }), flush=True)


if __name__ == "__main__":
    main()
