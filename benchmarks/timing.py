"""Timing helpers shared by the benchmark scripts: medians of repeated calls, an update's XLA FLOP
count and time, and the machine's fp32 matmul peak measured in the same run."""

from __future__ import annotations

import time

import jax
import jax.numpy as jnp
import numpy as np


def median_seconds(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        jax.block_until_ready(fn())
        times.append(time.perf_counter() - start)
    return float(np.median(times))


def time_update(update, state, *args, repeats: int) -> tuple[float, float, object]:
    """(XLA-counted FLOPs, median seconds, final state) of ``state = update(state, *args)[0]``."""
    cost = update.lower(state, *args).compile().cost_analysis()
    flops = (cost[0] if isinstance(cost, list) else cost)["flops"]
    holder = {"state": state}

    def run():
        holder["state"], metrics = update(holder["state"], *args)
        return metrics

    run()
    return flops, median_seconds(run, repeats), holder["state"]


def matmul_peak(n: int = 2048, repeats: int = 10) -> float:
    """fp32 GFLOP/s of one n x n matmul through XLA."""
    a = jnp.ones((n, n), jnp.float32)
    f = jax.jit(lambda x: x @ x)
    jax.block_until_ready(f(a))
    return 2 * n**3 / median_seconds(lambda: f(a), repeats) / 1e9
