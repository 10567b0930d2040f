"""The guarded edit against the paper's plain edit, every transition replayed in the target simulator.

    python benchmarks/guard_quality.py --env walker2d [--gaps gravity friction thigh] [--edit FIELD=VALUE ...]
        [--target medium-replay] [--prior FOLDER] [--out benchmarks/results/guard_quality.jsonl]

With the shipped ``ENV-medium-replay-cpu`` prior (its target model shipped beside it), or for another
target level the prior the bench trained for it (``--prior benchmarks/results/priors/ENV/prior-LEVEL-KEY``:
the same two episodes held out; its target model fitted to the rest where it holds none), per source:
simulator one-step MAE of the source, the plain edit and the guarded edit; their reward MAE; the
transitions stepping into a state the target ends an episode on while flagged non-terminal; actions
outside the action space; the guard's counts; the edit's wall time; and the guarded edit's rewards
relabelled by a reward proxy fitted to the prior's training episodes (as ``xted edit --relabel-rewards``
does, but on the edited transitions only), against the prior's own reward stream. The floor is the
plain edit of the two target episodes the prior never saw; the bound the guarded edit is held to is
the larger of the source's error and 1.5x that floor, and its reward error's the source's plus the
floor's.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

import numpy as np

from xted.analysis import ProxyConfig, fit_reward_proxy, relabel_rewards, simulator_measures
from xted.data import load, shipped, split_heldout
from xted.diffusion.config import EditConfig
from xted.diffusion.editor import edit_dataset
from xted.diffusion.guard import fit_target_model
from xted.diffusion.prior import load_prior
from xted.envs import parse_domain
from xted.envs.make import action_bounds
from xted.envs.termination import termination
from xted.fields import apply_overrides

FLOOR_EPISODES = 2  # the shipped priors were trained with these target episodes held out


def validity(env: str, data, source) -> dict:
    """Unflagged steps into a terminal state (all, and among edited transitions) and actions outside the space."""
    rule, (low, high) = termination(env), action_bounds(env)
    unflagged = rule(data.next_observations) & ~data.terminals
    edited = np.any(data.next_observations != source.next_observations, axis=1)
    outside = np.any((data.actions < low) | (data.actions > high), axis=1)
    return {"unflagged_terminal": int(unflagged.sum()), "unflagged_terminal_edited": int((unflagged & edited).sum()),
            "actions_outside": int(outside.sum()), "edited_transitions": int(edited.sum())}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--env", required=True, choices=["halfcheetah", "walker2d"])
    parser.add_argument("--gaps", nargs="+", default=["gravity", "friction", "thigh"])
    parser.add_argument("--edit", nargs="*", default=[], help="EditConfig overrides of the guarded edit.")
    parser.add_argument("--target", default="medium-replay", help="The target level the prior learned.")
    parser.add_argument("--prior", type=Path, default=None, help="The prior (default: the shipped ENV-TARGET-cpu).")
    parser.add_argument("--out", type=Path, default=None, help="Append one JSON line per source.")
    args = parser.parse_args()

    domain = parse_domain(args.env)
    prior = load_prior(args.prior or shipped.prior_dir(f"{args.env}-{args.target}-cpu"))
    guarded = apply_overrides(EditConfig(), args.edit)
    plain = dataclasses.replace(guarded, guard=False)
    train, heldout = split_heldout(load(f"{args.env}-{args.target}"), FLOOR_EPISODES)
    if prior.target_model is None:
        prior = dataclasses.replace(prior, target_model=fit_target_model(train, seed=guarded.seed))
    floor_measures = simulator_measures(domain, edit_dataset(prior, heldout, plain)[0])
    floor, floor_reward = floor_measures["mae"], floor_measures["reward_mae"]
    reward_proxy = fit_reward_proxy(train, ProxyConfig(), progress=False)
    print(f"{args.env}: floor (plain edit of held-out target episodes) {floor:.3f}, its reward MAE {floor_reward:.3f}; "
          f"target model resolution {prior.target_model.resolution:.3f}")
    print("| gap | sim MAE source / plain / guarded (bound) | reward MAE source / plain / guarded / guarded relabelled (bound) "
          "| unflagged terminal plain / guarded | actions outside plain / guarded | windows edited | seconds plain / guarded |")
    print("|---|---|---|---|---|---|---|")
    for gap in args.gaps:
        source = load(f"{args.env}-{gap}")
        row = {"env": args.env, "target": args.target, "gap": gap, "edit_config": dataclasses.asdict(guarded), "floor": floor,
               "floor_reward_mae": floor_reward,
               "resolution": prior.target_model.resolution, "source_sha256": source.fingerprint()}
        row["source"] = simulator_measures(domain, source)
        for name, config in (("plain", plain), ("guarded", guarded)):
            edited, report = edit_dataset(prior, source, config)
            row[name] = {**simulator_measures(domain, edited), **validity(args.env, edited, source),
                         "seconds": report["seconds"], "guard": report.get("guard")}
        relabelled = relabel_rewards(edited, reward_proxy)  # on the edited transitions only, the source's stay
        changed = np.any(edited.next_observations != source.next_observations, axis=1)
        relabelled = dataclasses.replace(relabelled, rewards=np.where(changed, relabelled.rewards, edited.rewards))
        row["guarded_relabelled_reward_mae"] = simulator_measures(domain, relabelled)["reward_mae"]
        row["bound"] = max(row["source"]["mae"], 1.5 * floor)
        s, p, g = row["source"], row["plain"], row["guarded"]
        counts = g["guard"]
        print(f"| {gap} | {s['mae']:.3f} / {p['mae']:.3f} / **{g['mae']:.3f}** ({row['bound']:.3f}) "
              f"| {s['reward_mae']:.3f} / {p['reward_mae']:.3f} / {g['reward_mae']:.3f} "
              f"/ {row['guarded_relabelled_reward_mae']:.3f} ({s['reward_mae'] + floor_reward:.3f}) "
              f"| {p['unflagged_terminal']} / {g['unflagged_terminal_edited']} "
              f"| {p['actions_outside']} / {g['actions_outside']} "
              f"| {counts['edited']} of {counts['windows']} (outside support {counts['source_outside_support']}, "
              f"invalid {counts['source_invalid_edit']}, no gain {counts['source_no_gain']}) "
              f"| {p['seconds']:.1f} / {g['seconds']:.1f} |", flush=True)
        if args.out:
            with args.out.open("a") as f:
                f.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()
