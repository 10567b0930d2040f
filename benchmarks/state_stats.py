"""Halfcheetah datasets' state statistics the edit diagnosis quotes (BENCHMARKS.md, "Which edited
stream breaks the learner"): mean forward velocity, how well the root pitch's finite difference
matches its recorded velocity (1 for a physical trajectory), and the share of actions outside [-1, 1].

    python benchmarks/state_stats.py DATA [DATA ...]
"""

from __future__ import annotations

import argparse

import numpy as np

from xted.data import load

DT = 0.05  # halfcheetah's control step (frame skip 5 x 0.01 s)
PITCH, FORWARD_VELOCITY, PITCH_VELOCITY = 1, 8, 10  # observation indices


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("datasets", nargs="+", help="halfcheetah dataset paths or shipped names")
    args = parser.parse_args()
    print(f"{'dataset':>48s}  fwd velocity  pitch diff/velocity corr  actions outside [-1, 1]")
    for name in args.datasets:
        data = load(name)
        following = data.require_next_observations()
        pitch_rate = (following[:, PITCH] - data.observations[:, PITCH]) / DT
        corr = np.corrcoef(pitch_rate, following[:, PITCH_VELOCITY])[0, 1]
        outside = np.mean(np.abs(data.actions) > 1.0)
        print(f"{name[-48:]:>48s}  {data.observations[:, FORWARD_VELOCITY].mean():12.2f}  {corr:24.2f}  {outside:23.1%}")


if __name__ == "__main__":
    main()
