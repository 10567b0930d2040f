"""SAC update throughput (one jitted update, batch 256, 256-256 networks) next to the matmul peak.

    python benchmarks/sac_speed.py [--repeats 500]
"""

from __future__ import annotations

import argparse
import json

import jax
import numpy as np

from prior_speed import matmul_peak, time_update
from xted.rl.sac import SACConfig, init_sac, sac_update


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=500)
    args = parser.parse_args()
    config = SACConfig()
    rng = np.random.default_rng(0)
    batch = {"observations": rng.normal(size=(256, 17)).astype(np.float32),
             "actions": rng.uniform(-1, 1, (256, 6)).astype(np.float32),
             "rewards": rng.normal(size=256).astype(np.float32),
             "next_observations": rng.normal(size=(256, 17)).astype(np.float32),
             "terminals": np.zeros(256, np.float32)}
    state = init_sac(jax.random.PRNGKey(0), 17, 6, config)
    flops, seconds, _ = time_update(sac_update, state, batch, config, repeats=args.repeats)
    peak = matmul_peak()
    print(json.dumps({"update_ms": seconds * 1e3, "updates_per_second": 1 / seconds, "gflop_per_update": flops / 1e9,
                      "achieved_gflops": flops / seconds / 1e9, "matmul_peak_gflops": peak}))


if __name__ == "__main__":
    main()
