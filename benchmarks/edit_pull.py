"""Which part of a two-policy target an edit moves its source toward (the medium-expert targets).

    python benchmarks/edit_pull.py --env halfcheetah [--gaps thigh gravity friction] [--columns Tgt+Edited]
        [--prior-set walker2d:cross_blocks=2] [--out benchmarks/results/edit_pull.jsonl]

A medium-expert target is the medium policy's episodes, then the expert's (half each). Per source and per
edit of it (the bench's own data cell: read from the bench cache, made there where missing, as
``xted bench run`` would), and for the target's two halves: the mean forward velocity, the return per
1,000 steps, and the share of transitions whose nearest target transition (observations standardised by
the target's statistics; the target's own transitions excluding their own episode) lies in the medium
half. An edit that pulls an expert source toward the target's medium half raises that share and lowers
the velocity from the source's toward the medium half's.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from xted.data import Dataset, load
from xted.envs import parse_domain
from xted.envs.make import forward_velocity_index
from xted.pipelines.bench import run, store
from xted.pipelines.bench.config import BenchConfig
from xted.pipelines.bench.grid import plan

TARGET_LEVEL = "medium-expert"
CHUNK = 2048


def nearest_episode(queries: np.ndarray, reference: np.ndarray, reference_episode: np.ndarray,
                    query_episode: np.ndarray | None = None) -> np.ndarray:
    """The episode of each query's nearest reference row (Euclidean); with ``query_episode``, rows of the
    query's own episode are left out (the reference queried with itself)."""
    found = np.empty(len(queries), dtype=np.int64)
    reference_norms = np.sum(reference * reference, axis=1)
    for start in range(0, len(queries), CHUNK):
        block = queries[start:start + CHUNK]
        distances = reference_norms[None, :] - 2.0 * block @ reference.T
        if query_episode is not None:
            distances[query_episode[start:start + CHUNK, None] == reference_episode[None, :]] = np.inf
        found[start:start + CHUNK] = reference_episode[np.argmin(distances, axis=1)]
    return found


def episode_index(data: Dataset) -> np.ndarray:
    return np.repeat(np.arange(data.num_episodes), data.episode_lengths())


def measures(data: Dataset, nearest: np.ndarray, velocity: int, medium_episodes: int) -> dict:
    returns = data.episode_returns() / data.episode_lengths() * 1000.0
    return {"forward_velocity": float(data.observations[:, velocity].mean()),
            "return_per_1000_steps": float(returns.mean()),
            "nearest_in_medium_half": float(np.mean(nearest < medium_episodes)), "transitions": len(data)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--env", required=True, choices=["halfcheetah", "walker2d"])
    parser.add_argument("--gaps", nargs="+", default=["thigh", "gravity", "friction"])
    parser.add_argument("--columns", nargs="+", default=["Tgt+Edited"], help="Bench columns whose data to measure.")
    parser.add_argument("--prior-set", nargs="*", default=[], help="As xted bench run --prior-set ENV:FIELD=VALUE.")
    parser.add_argument("--store", default="benchmarks/results/bench")
    parser.add_argument("--cache", default="runs/bench-cache")
    parser.add_argument("--out", type=Path, default=None, help="Append one JSON line per dataset.")
    args = parser.parse_args()

    grid = plan(BenchConfig(envs=(args.env,), targets=(TARGET_LEVEL,), gaps=tuple(args.gaps),
                            columns=tuple(args.columns), prior_overrides=tuple(args.prior_set),
                            store=args.store, cache=args.cache))
    target = load(f"{args.env}-{TARGET_LEVEL}")
    medium_episodes = target.num_episodes // 2
    velocity = forward_velocity_index(parse_domain(args.env))
    mean, std = target.observations.mean(axis=0), target.observations.std(axis=0) + 1e-6
    reference, episodes = (target.observations - mean) / std, episode_index(target)

    def nearest(data: Dataset, own_episodes: np.ndarray | None = None) -> np.ndarray:
        return nearest_episode((data.observations - mean) / std, reference, episodes, own_episodes)

    rows = []
    within_target = nearest(target, episodes)  # each target transition's nearest outside its own episode
    for name, wanted in (("target medium half", episodes < medium_episodes),
                         ("target expert half", episodes >= medium_episodes)):
        half = target.select_episodes(np.unique(episodes[wanted]))
        rows.append({"dataset": name, **measures(half, within_target[wanted], velocity, medium_episodes)})
    for gap in args.gaps:
        source = load(f"{args.env}-{gap}")
        rows.append({"dataset": f"{gap} source", **measures(source, nearest(source), velocity, medium_episodes)})
        for cell in run.data_needed([[c] for c in grid.learners.values() if c.gap == gap]):
            data, _ = run.data_of(grid, cell, progress=True)
            rows.append({"dataset": f"{gap} {cell.kind}", "cell": cell.name,
                         "makes": len(store.makes(store.read_result(args.store, cell))),
                         **measures(data, nearest(data), velocity, medium_episodes)})
    print(f"| {args.env} {TARGET_LEVEL} | forward velocity | return per 1,000 steps | "
          "nearest target transition in the medium half |")
    print("|---|---|---|---|")
    for row in rows:
        print(f"| {row['dataset']} | {row['forward_velocity']:.2f} | {row['return_per_1000_steps']:,.0f} | "
              f"{row['nearest_in_medium_half']:.0%} |")
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        with args.out.open("a") as handle:
            for row in rows:
                handle.write(json.dumps({"env": args.env, "target": TARGET_LEVEL, **row}) + "\n")


if __name__ == "__main__":
    main()
