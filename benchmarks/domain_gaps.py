"""How large the domain gaps are (the paper's appendix table, plus the simulator's ground truth).

    python benchmarks/domain_gaps.py [--envs halfcheetah walker2d] [--episodes 10]

Per env and gap: (a) the simulator dynamics MAE of the shipped source data replayed in the target
simulator, next to the shipped target data's; (b) the greedy return of the shipped source-domain
SAC policy in the target domain versus in its own domain, and the target policy's in the target.
Prints a markdown table.
"""

from __future__ import annotations

import argparse

from xted.data import load
from xted.data.shipped import policies_dir
from xted.envs import PAPER_GAPS, parse_domain
from xted.envs.dynamics import dataset_dynamics_error
from xted.rl.evaluation import evaluate
from xted.rl.policy_io import Policy


def greedy_return(policy_name: str, domain, episodes: int) -> float:
    actor = Policy.load(policies_dir() / f"{policy_name}-expert.msgpack")
    return evaluate(actor.act, domain, episodes, seed=123)["return_mean"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--envs", nargs="+", default=["halfcheetah", "walker2d"])
    parser.add_argument("--episodes", type=int, default=10)
    args = parser.parse_args()
    print("| env | gap | dynamics MAE of source data in target sim | of target (medium-replay) data "
          "| source policy return in target | in source | target policy in target |")
    print("|---|---|---|---|---|---|---|")
    for env in args.envs:
        target = parse_domain(env)
        target_mae = dataset_dynamics_error(target, load(f"{env}-medium-replay")).mae
        target_return = greedy_return(env, target, args.episodes)
        for gap in PAPER_GAPS[env]:
            source = parse_domain(env, gap)
            print(f"| {env} | {gap} | {dataset_dynamics_error(target, load(source.name)).mae:.4f} | {target_mae:.2e} "
                  f"| {greedy_return(source.name, target, args.episodes):.0f} "
                  f"| {greedy_return(source.name, source, args.episodes):.0f} | {target_return:.0f} |", flush=True)


if __name__ == "__main__":
    main()
