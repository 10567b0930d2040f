"""Does editing pull a source onto the target dynamics once its gap exceeds what the prior resolves?

    python benchmarks/gap_scaling.py --env halfcheetah --prior PRIOR --policy halfcheetah-gravity \
        --gaps gravity=2 gravity=3 gravity=4 [--transitions 20000] [--kappa 0.5 0.7] [--edit FIELD=VALUE ...]

For each gap, ``transitions`` steps are collected in that source domain with one shipped expert
policy (``--policy NAME`` = ``xted/assets/policies/NAME-expert.msgpack``, the same behaviour for
every gap, so only the dynamics change), replayed in the target simulator (the source's gap), then
edited with the prior and replayed again. One markdown row per gap and kappa, with the
forward-velocity correlation against mismatched episodes (task content kept).
"""

from __future__ import annotations

import argparse
import dataclasses

from xted.analysis import content_similarity
from xted.fields import apply_overrides
from xted.data import Dataset
from xted.data.shipped import policies_dir
from xted.diffusion.editor import EditConfig, edit_dataset
from xted.diffusion.prior import load_prior
from xted.envs import parse_domain
from xted.envs.dynamics import dataset_dynamics_error
from xted.envs.make import forward_velocity_index
from xted.rl.collect import collect
from xted.rl.policy_io import Policy


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--env", required=True)
    parser.add_argument("--prior", required=True)
    parser.add_argument("--policy", required=True)
    parser.add_argument("--gaps", nargs="+", required=True)
    parser.add_argument("--transitions", type=int, default=20000)
    parser.add_argument("--kappa", nargs="+", type=float, default=[0.5])
    parser.add_argument("--edit", nargs="*", default=[])
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    target = parse_domain(args.env)
    prior = load_prior(args.prior)
    actor = Policy.load(policies_dir() / f"{args.policy}-expert.msgpack")
    forward = forward_velocity_index(target)

    def sim(data: Dataset) -> float:
        return dataset_dynamics_error(target, data).mae

    print("| gap | kappa | sim MAE source -> edited (ratio) | fwd-velocity corr matched / mismatched |")
    print("|---|---|---|---|")
    for gap in args.gaps:
        arrays, _ = collect(actor.act, parse_domain(args.env, gap), args.transitions, args.seed, progress=False)
        source = Dataset(**arrays)
        before = sim(source)
        for kappa in args.kappa:
            config = dataclasses.replace(apply_overrides(EditConfig(), args.edit), kappa=kappa, seed=args.seed)
            edited, _ = edit_dataset(prior, source, config)
            after = sim(edited)
            content = content_similarity(source, edited, forward)
            print(f"| {gap} | {kappa} | {before:.3f} -> {after:.3f} ({after / before:.2f}) "
                  f"| {content['matched']['forward_velocity_correlation']:.2f} / "
                  f"{content['mismatched']['forward_velocity_correlation']:.2f} |", flush=True)


if __name__ == "__main__":
    main()
