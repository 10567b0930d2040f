"""The simulator's check of the bench's augmentation data before any learner reads it.

    python benchmarks/augment_quality.py --envs halfcheetah walker2d --targets medium-replay \
        [--columns "Tgt (Edit)" "Tgt (Gen)" "Tgt S4RL" "Tgt SER"] [--out benchmarks/results/augment_quality.jsonl]

For each target and augmentation column, the data cell the bench's learners would read is made
(or read from the cache: the same store and cache as ``xted bench``, so the learners reuse it) and
every transition replayed in the target simulator: the mean absolute error of its next state
(``sim_mae``, over state dimensions), the share of transitions whose error exceeds 1 (``over_1``),
the mean absolute error of its reward against the simulator's for its (s, a) (``reward_mae``), and
how far the data's rewards and states sit from the target's (mean and std ratios). The target
itself is a recording of that simulator (its error is ~0), so the error says what a learner would
be taught that the target's dynamics do not do.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from xted.envs import parse_domain
from xted.envs.dynamics import dynamics_error, replayed_rewards
from xted.pipelines.bench.columns import AUGMENT_COLUMNS
from xted.pipelines.bench.config import BenchConfig
from xted.pipelines.bench.grid import plan
from xted.pipelines.bench.run import data_of


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--envs", nargs="+", default=["halfcheetah", "walker2d"])
    parser.add_argument("--targets", nargs="+", default=["medium-replay"])
    parser.add_argument("--columns", nargs="+", default=list(AUGMENT_COLUMNS))
    parser.add_argument("--store", default=BenchConfig.store)
    parser.add_argument("--cache", default=BenchConfig.cache)
    parser.add_argument("--out", type=Path, default=None, help="Append one JSON line per target and column.")
    args = parser.parse_args()
    grid = plan(BenchConfig(envs=tuple(args.envs), targets=tuple(args.targets), columns=tuple(args.columns),
                            seeds=(0,), store=args.store, cache=args.cache))
    print("| env | target | column | sim MAE | share > 1 | reward MAE | reward mean (target) | state std / target's |")
    print("|---|---|---|---|---|---|---|---|")
    for row in grid.rows:
        if not row.cells:
            continue
        target = grid.datasets[f"{row.env}-{row.target}"]
        data, _ = data_of(grid, row.cells[0].data_cell, progress=True)
        error = dynamics_error(parse_domain(row.env), data.observations, data.actions, data.require_next_observations(),
                               replay_states_at_clip=True)
        finite = np.isfinite(error.mae_per_transition)
        rewards = replayed_rewards(parse_domain(row.env), data.observations, data.actions)
        record = {"env": row.env, "target": row.target, "column": row.column, "data_key": row.cells[0].data_cell.key,
                  "transitions": len(data), "sim_mae": float(np.mean(error.mae_per_transition[finite])),
                  "unstable": int((~finite).sum()), "over_1": float(np.mean(error.mae_per_transition[finite] > 1.0)),
                  "reward_mae": float(np.nanmean(np.abs(rewards - data.rewards))),
                  "reward_mean": float(data.rewards.mean()), "target_reward_mean": float(target.rewards.mean()),
                  "state_std_ratio": float(np.median(data.observations.std(0) / target.observations.std(0)))}
        print(f"| {row.env} | {row.target} | {row.column} | {record['sim_mae']:.3f} | {record['over_1']:.1%} | "
              f"{record['reward_mae']:.3f} | "
              f"{record['reward_mean']:.2f} ({record['target_reward_mean']:.2f}) | {record['state_std_ratio']:.2f} |")
        if args.out is not None:
            with args.out.open("a") as f:
                f.write(json.dumps(record) + "\n")


if __name__ == "__main__":
    main()
