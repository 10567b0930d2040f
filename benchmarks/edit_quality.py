"""Per-gap editing quality of a trained prior: simulator truth, the paper's learned proxy, task content.

    python benchmarks/edit_quality.py --env halfcheetah --prior PRIOR --target halfcheetah-medium-replay \
        [--heldout-episodes 2] [--gaps gravity friction thigh] [--kappa 0.5] [--temperature T ...]
        [--floor-seeds 3] [--edit FIELD=VALUE ...] [--project-dynamics] [--out runs/edit_quality.jsonl]

The prior must have been trained with the same ``--heldout-episodes`` (the split is deterministic):
those target episodes measure the floor (the same edit applied to target data the prior never saw),
with ``--floor-seeds`` edit seeds (mean, spread and transition count reported: the held-out
episodes are few, walker2d's about 300 transitions).
A dynamics proxy (MLP) is fitted to the prior's training episodes. Reported per gap and kappa:

- simulator MAE (every transition replayed in the target simulator) of the source and its edit
  (every edited transition counts), with the share of edited next states the editor clipped into
  walker2d's observation space (velocities within +-10);
- proxy MAE, ``|proxy(s, a) - s'|`` (the paper's measure) of the source and its edit;
- task content kept (``xted.analysis.content``): low-pass and low-frequency magnitude differences
  and forward-velocity correlation, matched pairs and mismatched pairs (chance level);
- the learnability reference: the simulator MAE of the proxy's *own* predictions, on held-out
  target states and on the source's states - what a model learned from this target data resolves.
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import json
from pathlib import Path

import numpy as np

from xted.analysis import ProxyConfig, edit_report, fit_proxy
from xted.fields import apply_overrides
from xted.data import load, split_heldout
from xted.diffusion.editor import EditConfig
from xted.pipelines.edit import edit_source
from xted.diffusion.prior import load_prior
from xted.envs import parse_domain
from xted.envs.dynamics import dynamics_error


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--env", required=True)
    parser.add_argument("--prior", type=Path, required=True)
    parser.add_argument("--target", required=True)
    parser.add_argument("--heldout-episodes", type=int, default=2)
    parser.add_argument("--gaps", nargs="+", default=["gravity", "friction", "thigh"])
    parser.add_argument("--kappa", nargs="+", type=float, default=[0.5])
    parser.add_argument("--temperature", nargs="+", type=float, default=None,
                        help="Reverse-chain noise temperatures to sweep (default: EditConfig's, or --edit's).")
    parser.add_argument("--floor-seeds", type=int, default=3, help="Edit seeds the floor is averaged over.")
    parser.add_argument("--edit", nargs="*", default=[],
                        help="EditConfig overrides (e.g. iterations=2 target_return=0.5), for every kappa.")
    parser.add_argument("--project-dynamics", action="store_true",
                        help="Project each edited window onto the rollout of a dynamics proxy fitted to the prior's "
                        "training episodes (a second proxy, seed + 1, so the measuring one is not the projecting one).")
    parser.add_argument("--dynamics-weight", nargs="+", type=float, default=None,
                        help="With --project-dynamics: the weights of the model's predictions to sweep "
                        "(EditConfig.dynamics_weight; default its own, or --edit's).")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=None, help="Append one JSON line per row.")
    args = parser.parse_args()

    domain = parse_domain(args.env)
    train, heldout = split_heldout(load(args.target), args.heldout_episodes)
    prior = load_prior(args.prior)
    proxy = fit_proxy(train, ProxyConfig(seed=args.seed))
    dynamics = fit_proxy(train, ProxyConfig(seed=args.seed + 1)) if args.project_dynamics else None

    def proxy_resolution(data) -> float:
        return dynamics_error(domain, data.observations, data.actions, proxy.predict(data.observations, data.actions)).mae

    resolution_heldout = proxy_resolution(heldout)
    print(f"proxy's own simulator MAE on held-out target states: {resolution_heldout:.3f}")
    print("| gap | kappa | sim MAE source -> edited (ratio) | proxy MAE source -> edited (ratio) "
          "| proxy's sim MAE on source states | low-pass diff matched / mismatched "
          "| low-freq magnitude diff matched / mismatched | fwd-velocity corr matched / mismatched "
          "| floor sim (seeds) / proxy | edited next states clipped into the observation space | edit time |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    sources = {gap: load(f"{args.env}-{gap}") for gap in args.gaps}
    resolution_sources = {gap: proxy_resolution(d) for gap, d in sources.items()}
    base = apply_overrides(EditConfig(), args.edit)
    for kappa, temperature, weight in itertools.product(args.kappa, args.temperature or [base.temperature],
                                                        args.dynamics_weight or [base.dynamics_weight]):
        config = dataclasses.replace(base, kappa=kappa, temperature=temperature, dynamics_weight=weight, seed=args.seed)
        floors = []
        for seed in range(args.seed, args.seed + args.floor_seeds):
            floor, _ = edit_source(prior, heldout, dataclasses.replace(config, seed=seed), project_onto=dynamics)
            floors.append(edit_report(domain, heldout, floor, proxy))
        sims = [f["simulator"]["edited"]["mae"] for f in floors]
        floor_row = {"sim": float(np.mean(sims)), "sim_std": float(np.std(sims)), "sim_seeds": sims,
                     "n": floors[0]["simulator"]["edited"]["n"],
                     "proxy": float(np.mean([f["proxy"]["edited"] for f in floors]))}
        for gap, source in sources.items():
            edited, report = edit_source(prior, source, config, project_onto=dynamics)
            measured = edit_report(domain, source, edited, proxy)
            content = measured["content"]
            row = {
                "env": args.env, "gap": gap, "kappa": kappa, "edit": args.edit,
                "project_dynamics": args.project_dynamics,
                "edit_config": dataclasses.asdict(config), "prior": str(args.prior),
                "target": args.target, "source_sha256": source.fingerprint(),
                "sim_source": measured["simulator"]["source"]["mae"], "sim_edited": measured["simulator"]["edited"]["mae"],
                "sim_edited_n": measured["simulator"]["edited"]["n"],
                "edited_clipped_to_observation_space": report["clipped_to_observation_space"] / report["transitions"],
                "proxy_source": measured["proxy"]["source"], "proxy_edited": measured["proxy"]["edited"],
                "proxy_resolution_source": resolution_sources[gap], "proxy_resolution_heldout": resolution_heldout,
                "floor": floor_row, "content": content, "edit_seconds": report["seconds"],
            }
            m, mm = content["matched"], content["mismatched"]
            shown = f"{kappa} T={temperature}" + (f" w={weight}" if dynamics is not None else "")
            print(f"| {gap} | {shown} | {row['sim_source']:.3f} -> {row['sim_edited']:.3f} "
                  f"({row['sim_edited'] / row['sim_source']:.2f}) "
                  f"| {row['proxy_source']:.3f} -> {row['proxy_edited']:.3f} ({row['proxy_edited'] / row['proxy_source']:.2f}) "
                  f"| {row['proxy_resolution_source']:.3f} "
                  f"| {m['low_pass_difference']:.2f} / {mm['low_pass_difference']:.2f} "
                  f"| {m['low_freq_magnitude_difference']:.2f} / {mm['low_freq_magnitude_difference']:.2f} "
                  f"| {m['forward_velocity_correlation']:.2f} / {mm['forward_velocity_correlation']:.2f} "
                  f"| {floor_row['sim']:.3f} ± {floor_row['sim_std']:.3f} (n={floor_row['n']}) / {floor_row['proxy']:.3f} "
                  f"| {row['edited_clipped_to_observation_space']:.1%} | {report['seconds']:.0f} s |", flush=True)
            if args.out:
                with args.out.open("a") as f:
                    f.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()
