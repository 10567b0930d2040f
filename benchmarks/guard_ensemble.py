"""Can an ensemble's disagreement tell the guard where its target model cannot judge a source window?

    python benchmarks/guard_ensemble.py --env halfcheetah [--out benchmarks/results/guard_ensemble.jsonl]

The guard keeps an edited window where its target model's one-step error falls by more than the
model's resolution. On sources whose states the target data does not cover, that error measures
distance from the target data as much as dynamics (on halfcheetah gravity and friction the model
rates the source 4x worse than the simulator does, and the guard keeps edits the simulator finds
worse). With the shipped ``ENV-medium-replay-cpu`` prior, its target model and ensemble
(``target_ensemble.msgpack``), per source window (the editor's tiling): the model's error of the
source and of its plain edit, the ensemble's disagreement on the source, the simulator's one-step
MAE of both, and the simulator MAE (and share of windows edited) that the guard's own rule
(:func:`xted.diffusion.guard.required_gain`, :func:`~xted.diffusion.guard.judge_windows`) leaves at
each ``guard_disagreement`` weight, against the per-window oracle. A kept window is the plain edit's
(the guard keeps those bytes, its actions clipped: ``benchmarks/guard_quality.py --edit
guard_disagreement=W`` replays the guarded edit itself).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from xted.data import Dataset, load, shipped
from xted.data.windows import tile_episodes
from xted.diffusion.config import EditConfig
from xted.diffusion.editor import edit_dataset
from xted.diffusion.guard import judge_windows, required_gain, window_means
from xted.diffusion.prior import load_prior
from xted.envs import parse_domain
from xted.envs.dynamics import dynamics_error

WEIGHTS = (0.0, 0.25, 0.5, 1.0, 2.0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--env", required=True, choices=["halfcheetah", "walker2d"])
    parser.add_argument("--gaps", nargs="+", default=["gravity", "friction", "thigh"])
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()

    domain = parse_domain(args.env)
    prior = load_prior(shipped.prior_dir(f"{args.env}-medium-replay-cpu"))
    model, guard = prior.target_model, EditConfig()

    def simulator_errors(data: Dataset) -> np.ndarray:
        return dynamics_error(domain, data.observations, data.actions, data.require_next_observations(),
                              replay_states_at_clip=True).mae_per_transition

    print(f"{args.env}: the target model's resolution {model.resolution:.3f}, {1 + len(model.members)} members")
    for gap in args.gaps:
        source = load(f"{args.env}-{gap}")
        edited, _ = edit_dataset(prior, source, EditConfig(guard=False))
        tiling = tile_episodes(source.episode_bounds(), prior.config.horizon)
        steps, windows, n = tiling.transition_steps, tiling.transition_window, len(tiling.window_rows)
        per_transition = {
            "model_source": model.errors(source.observations, source.actions, source.require_next_observations()),
            "model_edited": model.errors(edited.observations, edited.actions, edited.require_next_observations()),
            "disagreement_source": model.disagreement(source.observations, source.actions),
            "sim_source": simulator_errors(source), "sim_edited": simulator_errors(edited)}
        w = {name: window_means(values[steps], windows, n) for name, values in per_transition.items()}
        states = np.where(tiling.sequence_is_next[:, None], source.require_next_observations()[tiling.sequence_steps],
                          source.observations[tiling.sequence_steps])  # the window states the guard bounds
        farthest = np.abs(prior.normalizer.normalize("observations", states))[tiling.window_rows].max(axis=(1, 2))
        worse = w["sim_edited"] > w["sim_source"]
        rules = {"keep every edit (plain)": np.ones(n, bool), "oracle (the simulator's choice)": ~worse}
        for weight in WEIGHTS:
            needed = required_gain(model.resolution, guard.guard_margin, weight, w["disagreement_source"])
            verdict = judge_windows(w["model_source"], w["model_edited"], farthest > guard.support_z,
                                    np.zeros(n, bool), needed, guard.outside_support)
            rules[f"guard, guard_disagreement {weight}"] = verdict.edit
        row = {"env": args.env, "gap": gap, "resolution": model.resolution, "windows": n,
               "edit_worse_share": float(worse.mean()),
               **{f"{name}_mean": float(values.mean()) for name, values in w.items()}, "rules": {}}
        for name, keep in rules.items():
            mae = np.where(keep[windows], per_transition["sim_edited"][steps], per_transition["sim_source"][steps])
            row["rules"][name] = {"sim_mae": float(mae.mean()), "edited_share": float(keep.mean())}
        print(f"\n{args.env} {gap}: {worse.mean():.0%} of windows worse after the plain edit; the model's error of the "
              f"source {w['model_source'].mean():.3f} (simulator {w['sim_source'].mean():.3f}), of the edit "
              f"{w['model_edited'].mean():.3f} (simulator {w['sim_edited'].mean():.3f}); disagreement on the source "
              f"{w['disagreement_source'].mean():.3f}")
        for name, result in row["rules"].items():
            print(f"  {name:40s} sim MAE {result['sim_mae']:.3f}, {result['edited_share']:.0%} edited")
        if args.out:
            args.out.parent.mkdir(parents=True, exist_ok=True)
            with args.out.open("a") as handle:
                handle.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()
