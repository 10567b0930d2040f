"""Your own data, with no simulator: a real robot's logs, or a domain xted does not model.

Train a prior on the target, edit the source, measure the edit with a dynamics proxy fitted to
the target (the paper's measure), train IQL on target + edited without evaluation, save the
policy, load it back and act with it as a controller would.

    python examples/own_data_without_simulator.py --target my_target.hdf5 --source my_source.hdf5
"""

import argparse

import xted


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--target", required=True, help="a .npz / D4RL .hdf5 file, minari:ID, or a shipped name")
    parser.add_argument("--source", required=True)
    parser.add_argument("--out", default="runs/own-data-offline", help="folder for the prior, the edit and the policy")
    parser.add_argument("--preset", default="cpu", help="prior preset: cpu, paper or tiny (a smoke test)")
    parser.add_argument("--prior-steps", type=int, default=20_000)
    parser.add_argument("--policy-steps", type=int, default=30_000)
    parser.add_argument("--proxy-steps", type=int, default=20_000)
    args = parser.parse_args()

    target, source = xted.load_dataset(args.target), xted.load_dataset(args.source)
    prior = xted.train_prior(target, out=f"{args.out}/prior", preset=args.preset, steps=args.prior_steps)
    edited = prior.edit(source, kappa=0.5, seed=0, progress=True)
    print(edited.metadata["edit"]["report"]["guard"]["verdict"])  # the guard: what it kept, and why
    xted.save_dataset(edited, f"{args.out}/edited.hdf5")  # D4RL layout, for any other learner

    report = xted.measure_edit(source, edited, target=target, proxy_steps=args.proxy_steps)
    print(f"one-step error under the target's dynamics proxy: source {report['proxy']['source']:.3f}, "
          f"edited {report['proxy']['edited']:.3f}")

    policy = xted.train_policy("iql", target, sources=[edited], steps=args.policy_steps, env=None)
    folder = policy.save(f"{args.out}/policy")
    controller = xted.load_policy(folder)
    action = controller.act(target.observations[0])
    print(f"policy saved in {folder}; its action for the first target state: {action.round(3).tolist()}")


if __name__ == "__main__":
    main()
