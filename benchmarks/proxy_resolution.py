"""How finely can a model learned from N target transitions resolve the dynamics?

    python benchmarks/proxy_resolution.py --env halfcheetah --data runs/data/halfcheetah-medium-200k.npz \
        --transitions 20000 60000 198000 [--heldout-episodes 2] [--steps 20000]

Fits the dynamics proxy (``xted.analysis.proxy``, an MLP trained by supervised regression: the
easiest form of the problem the prior solves implicitly) to the first N transitions after the
held-out episodes, then replays its predictions in the target simulator: on held-out target
states, and on each shipped source's states. A source gap whose MAE is below these numbers cannot
be told apart from the model's own error, so no edit learned from that much target data can
remove it as the simulator measures it.
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from xted.analysis import ProxyConfig, fit_proxy
from xted.data import load
from xted.envs import parse_domain
from xted.envs.dynamics import dataset_dynamics_error, dynamics_error


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--env", required=True)
    parser.add_argument("--data", required=True, help="Target data (episodes in order).")
    parser.add_argument("--transitions", nargs="+", type=int, required=True)
    parser.add_argument("--heldout-episodes", type=int, default=2)
    parser.add_argument("--gaps", nargs="+", default=["gravity", "friction", "thigh"])
    parser.add_argument("--steps", type=int, default=20_000)
    args = parser.parse_args()

    domain = parse_domain(args.env)
    data = load(args.data)
    heldout = data.select_episodes(np.arange(args.heldout_episodes))
    rest = data.select_episodes(np.arange(args.heldout_episodes, data.num_episodes))
    sources = {gap: load(f"{args.env}-{gap}") for gap in args.gaps}
    gaps = {f"{gap}_source_gap": dataset_dynamics_error(domain, d).mae
            for gap, d in sources.items()}

    def resolution(proxy, d) -> float:
        return dynamics_error(domain, d.observations, d.actions, proxy.predict(d.observations, d.actions)).mae

    for n in args.transitions:
        ends = np.cumsum(rest.episode_lengths())
        episodes = int(np.searchsorted(ends, n) + 1)
        train = rest.select_episodes(np.arange(min(episodes, rest.num_episodes)))
        proxy = fit_proxy(train, ProxyConfig(steps=args.steps), progress=False)
        row = {"env": args.env, "data": args.data, "train_transitions": len(train), "steps": args.steps,
               "heldout_target": resolution(proxy, heldout),
               **{f"{gap}_source_states": resolution(proxy, d) for gap, d in sources.items()}, **gaps}
        print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main()
