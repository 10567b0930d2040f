"""Does editing help the learner? The paper's Table 1 protocol on the shipped data.

    python benchmarks/main_table.py --env halfcheetah --prior PRIOR --target halfcheetah-medium-replay \
        --out runs/main_table [--gaps thigh gravity friction] [--algos iql] [--steps 30000] \
        [--seeds 0,1,2] [--kappa 0.5] [--edit FIELD=VALUE ...] [--edited-rewards prior|proxy|simulator]

For each gap the shipped 20k source is edited with the prior (as ``xted edit`` does), then each
algorithm trains on Target, Target+Source and Target+Edited (as ``xted policy`` does; evaluated in
the target env, normalised score of the last evaluation, mean and std over seeds). Next to the
scores: each mixed-in dataset's simulator dynamics MAE in the target env, and its rewards' error
against the target env's own (MAE and bias, recorded minus replayed). The edited transitions keep
the rewards the prior denoised (``--edited-rewards prior``, what ``xted edit`` gives), or get those
of a reward proxy fitted to the target (``proxy``: ``xted edit --relabel-rewards``), or the target
simulator's own (``simulator``: a diagnostic that no user without the target simulator has).

Everything lands in ``--out`` (edited datasets, per-seed results), so an interrupted run resumes
where it stopped. One ``--out`` holds one set of edit and training settings
(``settings.json``); another setting needs another folder.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import json
from pathlib import Path

import numpy as np

from xted.analysis import ProxyConfig, fit_reward_proxy, relabel_rewards
from xted.config import apply_overrides
from xted.data import load, save
from xted.diffusion.editor import EditConfig, edit_dataset
from xted.diffusion.prior import load_prior
from xted.envs import parse_domain
from xted.envs.dynamics import dataset_dynamics_error, replayed_rewards, reward_error
from xted.errors import InputError
from xted.rl.offline_train import train_offline
from xted.resume import resume_or_record


def check_settings(out: Path, settings: dict) -> None:
    try:
        resume_or_record(out / "settings.json", settings)
    except InputError as err:
        raise SystemExit(str(err)) from None


def replayed_in_target(domain, extra) -> dict:
    """A mixed-in dataset's dynamics MAE and reward MAE and bias in the target simulator (NaN for none)."""
    if extra is None:
        return dict.fromkeys(("mixed_in_sim_mae", "mixed_in_reward_mae", "mixed_in_reward_bias"), float("nan"))
    rewards = reward_error(domain, extra)
    return {"mixed_in_sim_mae": dataset_dynamics_error(domain, extra).mae,
            "mixed_in_reward_mae": rewards.mae, "mixed_in_reward_bias": rewards.bias}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--env", required=True)
    parser.add_argument("--prior", type=Path, required=True)
    parser.add_argument("--target", required=True)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--gaps", nargs="+", default=["thigh", "gravity", "friction"])
    parser.add_argument("--algos", nargs="+", default=["iql"])
    parser.add_argument("--steps", type=int, default=30_000)
    parser.add_argument("--seeds", default="0,1,2")
    parser.add_argument("--eval-every", type=int, default=10_000)
    parser.add_argument("--kappa", type=float, default=0.5)
    parser.add_argument("--edit", nargs="*", default=[], help="EditConfig overrides, e.g. target_return=0.5")
    parser.add_argument("--edited-rewards", choices=["prior", "proxy", "simulator"], default="prior",
                        help="Rewards of the edits: as denoised, from a target reward proxy, or the target simulator's.")
    args = parser.parse_args()

    seeds = [int(s) for s in args.seeds.split(",")]
    edit = dataclasses.replace(apply_overrides(EditConfig(), args.edit), kappa=args.kappa)
    check_settings(args.out, {"env": args.env, "prior": str(args.prior), "target": args.target,
                              "edit": edit.__dict__, "steps": args.steps, "seeds": seeds,
                              "eval_every": args.eval_every, "edited_rewards": args.edited_rewards})
    domain = parse_domain(args.env)
    target = load(args.target)
    prior = load_prior(args.prior)

    @functools.cache
    def target_reward_proxy():  # fitted once, and only if an edit still has to be made
        return fit_reward_proxy(target, ProxyConfig())

    def reward_edits(edited):
        if args.edited_rewards == "proxy":
            return relabel_rewards(edited, target_reward_proxy())
        if args.edited_rewards == "simulator":
            rewards = replayed_rewards(domain, edited.observations, edited.actions)
            return dataclasses.replace(edited, rewards=rewards.astype(edited.rewards.dtype),
                                       metadata={**edited.metadata, "rewards": "the target simulator's"})
        return edited

    mixes: dict[str, object] = {"target": None}
    for gap in args.gaps:
        mixes[f"source-{gap}"] = load(f"{args.env}-{gap}")
        edited_path = args.out / f"edited-{gap}.npz"
        if not edited_path.exists():
            edited, _ = edit_dataset(prior, mixes[f"source-{gap}"], edit)
            save(reward_edits(edited), edited_path)
        mixes[f"edited-{gap}"] = load(edited_path)

    measured = {mix: replayed_in_target(domain, extra) for mix, extra in mixes.items()}

    rows = []
    for algo in args.algos:
        for mix, extra in mixes.items():
            results = train_offline(algo, target, [] if extra is None else [extra], domain, args.steps, seeds,
                                    eval_every=args.eval_every, out_dir=args.out / f"{algo}-{mix}")
            scores = [r["final_score"] for r in results]
            rows.append({"algo": algo, "data": mix, "scores": scores, "mean": float(np.mean(scores)),
                         "std": float(np.std(scores)), "best": float(np.mean([r["best_score"] for r in results])),
                         **measured[mix]})
            print(json.dumps(rows[-1]), flush=True)

    print(f"\n{args.env}, target {args.target}, {args.steps} steps, seeds {args.seeds}, kappa {args.kappa} {args.edit}"
          f", rewards of the edits: {args.edited_rewards}")
    print("| algo | data | score (mean ± std, last eval) | best eval (mean) | mixed-in data in the target env: "
          "dynamics MAE | reward MAE (bias) |")
    print("|---|---|---|---|---|---|")
    for row in rows:
        data = "Target" if row["data"] == "target" else "Target + " + row["data"].replace("-", " (", 1) + ")"
        measured = "| | |" if np.isnan(row["mixed_in_sim_mae"]) else (
            f"| {row['mixed_in_sim_mae']:.3f} | {row['mixed_in_reward_mae']:.3f} ({row['mixed_in_reward_bias']:+.3f}) |")
        print(f"| {row['algo']} | {data} | {row['mean']:.1f} ± {row['std']:.1f} | {row['best']:.1f} {measured}")


if __name__ == "__main__":
    main()
