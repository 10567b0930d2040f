"""Which edited stream helps or breaks the learner: IQL on the target plus a source whose states,
actions and rewards are each taken from the source or from its edit.

    python benchmarks/edit_streams.py --env halfcheetah --target halfcheetah-medium-replay \
        --source halfcheetah-thigh --edited EDITED.npz [--variants S:A:R ...] [--steps 10000] \
        [--seeds 0 1 2] [--eval-episodes 5] [--out runs/edit_streams.jsonl]

A variant names where each stream comes from, ``s`` (source) or ``e`` (edit), in the order
states:actions:rewards; ``e:e:e`` is the edit itself, ``s:s:s`` the source. States come with their
next states. Edited actions are clipped to the source's action range (``--no-clip``: as the edit
wrote them). ``--added DATA`` trains on target + DATA as given instead (a control:
target-domain data and its edit).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

import numpy as np

from xted.data import Dataset, load
from xted.envs import parse_domain
from xted.rl.offline_train import train_offline

DEFAULT_VARIANTS = ("e:e:e", "e:s:e", "s:e:s", "s:s:e", "e:e:s")


def mix(source: Dataset, edited: Dataset, variant: str, clip: bool = True) -> Dataset:
    """The source with each of states, actions, rewards taken from ``edited`` where ``variant`` says ``e``."""
    picks = variant.split(":")
    if len(picks) != 3 or set(picks) - {"s", "e"}:
        raise SystemExit(f"variant {variant!r}: expected three of s/e joined by ':' (states:actions:rewards)")
    if len(source) != len(edited):
        raise SystemExit(f"the edit has {len(edited)} transitions, the source {len(source)}")
    low, high = source.actions.min(axis=0), source.actions.max(axis=0)
    states = edited if picks[0] == "e" else source
    return dataclasses.replace(
        source,
        observations=states.observations, next_observations=states.require_next_observations(),
        actions=(np.clip(edited.actions, low, high) if clip else edited.actions) if picks[1] == "e" else source.actions,
        rewards=(edited if picks[2] == "e" else source).rewards, extras={},
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--env", required=True)
    parser.add_argument("--target", required=True)
    parser.add_argument("--source")
    parser.add_argument("--edited")
    parser.add_argument("--variants", nargs="+", default=list(DEFAULT_VARIANTS))
    parser.add_argument("--added", nargs="+", default=[], help="Datasets to add to the target as they are.")
    parser.add_argument("--no-clip", action="store_true", help="Edited actions as the edit wrote them.")
    parser.add_argument("--steps", type=int, default=10_000)
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    parser.add_argument("--eval-episodes", type=int, default=5)
    parser.add_argument("--out", type=Path, default=None, help="Append one JSON line per variant.")
    args = parser.parse_args()
    if not args.added and not (args.source and args.edited):
        parser.error("give --source and --edited, or --added")

    target, domain = load(args.target), parse_domain(args.env)
    runs = [(f"added {name}", load(name)) for name in args.added]
    if args.source and args.edited:
        source, edited = load(args.source), load(args.edited)
        runs += [(variant, mix(source, edited, variant, clip=not args.no_clip)) for variant in args.variants]
    for name, data in runs:
        results = train_offline("iql", target, [data], domain, steps=args.steps, seeds=args.seeds,
                                eval_every=args.steps // 2, eval_episodes=args.eval_episodes, progress=False)
        scores = [[e["normalized_score"] for e in r["evals"]] for r in results]
        final = [s[-1] for s in scores]
        row = {"env": args.env, "target": args.target, "source": args.source, "edited": args.edited, "variant": name,
               "clip": not args.no_clip, "steps": args.steps, "seeds": args.seeds, "scores": scores,
               "mean": float(np.mean(final)), "std": float(np.std(final))}
        print(f"{name:>24s}  {row['mean']:5.1f} ± {row['std']:.1f}", flush=True)
        if args.out:
            with args.out.open("a") as f:
                f.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()
