"""Your own target and source data, in a domain xted simulates (halfcheetah or walker2d).

Train a prior on the target, edit the source, measure the edit by replaying it in the target
simulator and with a dynamics proxy fitted to the target, train IQL on target + edited and save it.

    python examples/own_data_with_simulator.py --target my_target.hdf5 --source my_source.hdf5 --env halfcheetah
"""

import argparse

import xted


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--target", required=True, help="a .npz / D4RL .hdf5 file, minari:ID, or a shipped name")
    parser.add_argument("--source", required=True)
    parser.add_argument("--env", required=True, help="halfcheetah or walker2d: the target domain")
    parser.add_argument("--out", default="runs/own-data", help="folder for the prior, the edit and the policy")
    parser.add_argument("--preset", default="cpu", help="prior preset: cpu, paper or tiny (a smoke test)")
    parser.add_argument("--prior-steps", type=int, default=20_000)
    parser.add_argument("--policy-steps", type=int, default=30_000)
    parser.add_argument("--eval-episodes", type=int, default=10)
    parser.add_argument("--proxy-steps", type=int, default=20_000)
    args = parser.parse_args()

    target, source = xted.load_dataset(args.target), xted.load_dataset(args.source)
    prior = xted.train_prior(target, out=f"{args.out}/prior", preset=args.preset, steps=args.prior_steps)
    edited = prior.edit(source, kappa=0.5, seed=0, progress=True)
    print(edited.metadata["edit"]["report"]["guard"]["verdict"])  # the guard: what it kept, and why

    report = xted.measure_edit(source, edited, target=target, env=args.env, proxy_steps=args.proxy_steps)
    print("one-step error, simulator (source -> edited): "
          f"{report['simulator']['source']['mae']:.3f} -> {report['simulator']['edited']['mae']:.3f}")
    print(f"one-step error, target proxy: {report['proxy']['source']:.3f} -> {report['proxy']['edited']:.3f}")

    policy = xted.train_policy("iql", target, sources=[edited], steps=args.policy_steps, env=args.env,
                               eval_every=args.policy_steps, eval_episodes=args.eval_episodes)
    print(f"IQL on target + edited: normalised score {policy.scores['final_score']:.1f}")
    print(f"policy saved in {policy.save(f'{args.out}/policy')}")


if __name__ == "__main__":
    main()
