"""The curve that decides the cpu preset: prior floor and edited/source dynamics error vs training.

    python benchmarks/prior_curve.py --env halfcheetah --target halfcheetah-medium-replay \
        --source halfcheetah-gravity --steps 2000 4000 8000 --out runs/curve [--preset cpu] [--set F=V ...]

Trains (resuming) to each step count, then edits the source and held-out target episodes with
kappa=0.5 and replays everything in the target simulator. The floor is the same edit applied to
target episodes the prior never saw. Prints one JSON line per point and writes them to OUT/curve.jsonl.
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

from xted.fields import apply_overrides
from xted.data import load
from xted.diffusion.editor import EditConfig, edit_dataset
from xted.data import split_heldout
from xted.diffusion.config import preset
from xted.diffusion.prior import load_prior
from xted.diffusion.training import train_prior_folder
from xted.envs import parse_domain
from xted.envs.dynamics import dataset_dynamics_error


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--env", required=True)
    parser.add_argument("--target", required=True)
    parser.add_argument("--source", nargs="+", required=True)
    parser.add_argument("--steps", nargs="+", type=int, required=True)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--preset", default="cpu")
    parser.add_argument("--heldout-episodes", type=int, default=2)
    parser.add_argument("--kappa", type=float, default=0.5)
    parser.add_argument("--set", dest="overrides", nargs="*", default=[])
    args = parser.parse_args()

    domain = parse_domain(args.env)
    train_data, heldout = split_heldout(load(args.target), args.heldout_episodes)
    sources = {name: load(name) for name in args.source}
    config = apply_overrides(preset(args.preset, train_data.observation_dim, train_data.action_dim), args.overrides)
    base = {name: dataset_dynamics_error(domain, d).mae for name, d in {"heldout": heldout, **sources}.items()}
    args.out.mkdir(parents=True, exist_ok=True)
    for steps in args.steps:
        train_prior_folder(train_data, args.out, config, steps, checkpoint_every=max(steps // 4, 1))
        with (args.out / "log.csv").open() as f:
            minutes = float(list(csv.DictReader(f))[-1]["seconds"]) / 60
        prior = load_prior(args.out)
        edit = EditConfig(kappa=args.kappa)
        floor_data, report = edit_dataset(prior, heldout, edit)
        point = {"steps": steps, "train_minutes": round(minutes, 2),
                 "floor": dataset_dynamics_error(domain, floor_data).mae,
                 "heldout_unedited": base["heldout"], "edit_seconds": report["seconds"], "sources": {}}
        for name, data in sources.items():
            edited, _ = edit_dataset(prior, data, edit)
            after = dataset_dynamics_error(domain, edited).mae
            point["sources"][name] = {"source": base[name], "edited": after, "ratio": after / base[name]}
        print(json.dumps(point), flush=True)
        with (args.out / "curve.jsonl").open("a") as f:
            f.write(json.dumps({**point, "preset": args.preset, "overrides": args.overrides}) + "\n")


if __name__ == "__main__":
    main()
