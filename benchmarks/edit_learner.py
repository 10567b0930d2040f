"""What the learner scored beside what the simulator finds, per source and per edit of it (the bench's cells).

    python benchmarks/edit_learner.py --env halfcheetah [--target medium-replay] [--gaps thigh gravity friction]
        [--variant Tgt+Edited --variant Tgt+Guarded --variant "Tgt+Guarded@guard_disagreement=0.5"]
        [--prior-set walker2d:cross_blocks=2] [--out benchmarks/results/edit_learner.jsonl]

A variant is a bench column with its ``--edit`` settings after ``@`` (comma-separated FIELD=VALUE). Per gap, for
the unedited source (Tgt+Src) and each variant's data cell (read from the bench cache, made there where missing, as
``xted bench run`` would): the learner's final score stored for that cell (IQL, the bench's seeds and steps; mean
and std over the seeds found), the share of transitions the edit changed, the one-step error in the target's
simulator (next states; rewards), the distance to the target data (each standardised state-action pair's nearest
target pair, median; the target's own pairs measured outside their own episode), the forward velocity and the
return per 1,000 steps. Which of these moves with the learner's score is what the table is for.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from xted.analysis.content import return_per_1000_steps
from xted.analysis.report import simulator_measures
from xted.data import Dataset, load
from xted.envs import parse_domain
from xted.envs.make import forward_velocity_index
from xted.pipelines.bench import run
from xted.pipelines.bench.config import BenchConfig
from xted.pipelines.bench.grid import plan
from xted.pipelines.bench.report import table_rows

SOURCE_COLUMN = "Tgt+Src"
CHUNK = 2048


def nearest_distance(queries: np.ndarray, reference: np.ndarray, query_episode: np.ndarray | None = None,
                     reference_episode: np.ndarray | None = None) -> np.ndarray:
    """Each query row's Euclidean distance to its nearest reference row; with episodes given, rows of the
    query's own episode are left out (the reference queried with itself)."""
    found = np.empty(len(queries))
    reference_norms = np.sum(reference * reference, axis=1)
    for start in range(0, len(queries), CHUNK):
        block = queries[start:start + CHUNK]
        squared = np.sum(block * block, axis=1)[:, None] + reference_norms[None, :] - 2.0 * block @ reference.T
        if query_episode is not None:
            squared[query_episode[start:start + CHUNK, None] == reference_episode[None, :]] = np.inf
        found[start:start + CHUNK] = np.sqrt(np.maximum(squared.min(axis=1), 0.0))
    return found


def pairs(data: Dataset) -> np.ndarray:
    return np.concatenate([data.observations, data.actions], axis=1)


def measures(data: Dataset, source: Dataset, domain, velocity: int, distance: np.ndarray) -> dict:
    simulator = simulator_measures(domain, data)
    changed = np.any(data.observations != source.observations, axis=1) | np.any(data.actions != source.actions, axis=1)
    return {"changed": float(changed.mean()), "simulator_mae": simulator["mae"], "reward_mae": simulator["reward_mae"],
            "target_distance": float(np.median(distance)), "forward_velocity": float(data.observations[:, velocity].mean()),
            "return_per_1000_steps": return_per_1000_steps(data)}


def parse_variant(text: str) -> tuple[str, tuple[str, ...]]:
    column, _, settings = text.partition("@")
    return column, tuple(setting for setting in settings.split(",") if setting)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--env", required=True, choices=["halfcheetah", "walker2d"])
    parser.add_argument("--target", default="medium-replay")
    parser.add_argument("--gaps", nargs="+", default=["thigh", "gravity", "friction"])
    parser.add_argument("--variant", action="append", default=None,
                        help="COLUMN[@FIELD=VALUE,...]; default: Tgt+Edited, Tgt+Guarded.")
    parser.add_argument("--prior-set", nargs="*", default=[], help="As xted bench run --prior-set ENV:FIELD=VALUE.")
    parser.add_argument("--store", default="benchmarks/results/bench")
    parser.add_argument("--cache", default="runs/bench-cache")
    parser.add_argument("--out", type=Path, default=None, help="Append one JSON line per dataset.")
    args = parser.parse_args()

    domain = parse_domain(args.env)
    velocity = forward_velocity_index(domain)
    target = load(f"{args.env}-{args.target}")
    reference = pairs(target)
    mean, std = reference.mean(axis=0), reference.std(axis=0) + 1e-6
    reference = (reference - mean) / std
    episodes = np.repeat(np.arange(target.num_episodes), target.episode_lengths())
    within_target = float(np.median(nearest_distance(reference, reference, episodes, episodes)))
    target_return = return_per_1000_steps(target)
    print(f"{args.env} {args.target}: median distance of a target pair to the nearest outside its episode {within_target:.3f}, "
          f"forward velocity {target.observations[:, velocity].mean():.2f}, return per 1,000 steps {target_return:,.0f}")

    rows = []
    for gap in args.gaps:
        source = load(f"{args.env}-{gap}")
        for variant in [SOURCE_COLUMN, *(args.variant or ["Tgt+Edited", "Tgt+Guarded"])]:
            column, edit = parse_variant(variant)
            grid = plan(BenchConfig(envs=(args.env,), targets=(args.target,), gaps=(gap,), columns=(column,), edit=edit,
                                    prior_overrides=tuple(args.prior_set), store=args.store, cache=args.cache))
            cells = run.data_needed([[cell] for cell in grid.learners.values()])
            data = source if not cells else run.data_of(grid, cells[0], progress=True)[0]
            score = next(row for row in table_rows(grid) if row["column"] == column)
            distance = nearest_distance((pairs(data) - mean) / std, reference)
            rows.append({"env": args.env, "target": args.target, "gap": gap, "variant": variant,
                         "score": score["mean"], "score_std": score["std"], "seeds": score["n_seeds"],
                         **measures(data, source, domain, velocity, distance)})
    print("| gap | data | learner score | transitions changed | simulator MAE | reward MAE | "
          "distance to target (median) | forward velocity | return per 1,000 steps |")
    print("|---|---|---|---|---|---|---|---|---|")
    for row in rows:
        score = "not run" if row["score"] is None else f"{row['score']:.1f} ± {row['score_std']:.1f}"
        reward = "-" if row["reward_mae"] is None else f"{row['reward_mae']:.3f}"
        print(f"| {row['gap']} | {row['variant']} | {score} | {row['changed']:.0%} | {row['simulator_mae']:.3f} | {reward} | "
              f"{row['target_distance']:.3f} | {row['forward_velocity']:.2f} | {row['return_per_1000_steps']:,.0f} |")
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        with args.out.open("a") as handle:
            for row in rows:
                handle.write(json.dumps({**row, "target_within_itself": within_target}) + "\n")


if __name__ == "__main__":
    main()
