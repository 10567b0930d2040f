"""Reward-free demonstrations (the paper's real-robot setting): edit, then behaviour-clone.

A dataset without rewards (a file with no ``rewards`` array) trains a prior without its reward
stream; the edit leaves rewards absent; BC learns from target + edited actions alone.

    python examples/reward_free_bc.py --target robot_target.npz --source robot_source.npz
"""

import argparse

import xted


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--target", required=True, help="reward-free target demonstrations")
    parser.add_argument("--source", required=True, help="reward-free source demonstrations")
    parser.add_argument("--out", default="runs/reward-free", help="folder for the prior and the policy")
    parser.add_argument("--preset", default="cpu", help="prior preset: cpu, paper or tiny (a smoke test)")
    parser.add_argument("--prior-steps", type=int, default=20_000)
    parser.add_argument("--policy-steps", type=int, default=30_000)
    args = parser.parse_args()

    target, source = xted.load_dataset(args.target), xted.load_dataset(args.source)
    print(f"target: {len(target)} transitions, {target.observation_dim}-d states, rewards: {target.has_rewards}")
    prior = xted.train_prior(target, out=f"{args.out}/prior", preset=args.preset, steps=args.prior_steps)
    print(f"prior streams: {', '.join(prior.config.denoiser.streams)}")
    edited = prior.edit(source, kappa=0.5, seed=0, progress=True)
    print(edited.metadata["edit"]["report"]["guard"]["verdict"])  # the guard: what it kept, and why

    kept = xted.measure_edit(source, edited)["content"]["matched"]
    print("content the edit kept (source vs edited episode): " + ", ".join(f"{k} {v:.3f}" for k, v in kept.items()))
    policy = xted.train_policy("bc", target, sources=[edited], steps=args.policy_steps, learning_rate=1e-4)
    print(f"BC policy saved in {policy.save(f'{args.out}/policy')}")


if __name__ == "__main__":
    main()
