"""One cell of the paper's Table 1 with the shipped data: halfcheetah, a 2x-thigh source.

Edit the source with the shipped prior, measure the edit in the target simulator, train IQL on
target + edited and evaluate it there; compare with target + the unedited source.

    python examples/simulator_benchmark.py                   # about 25 min on 2 CPU cores
    python examples/simulator_benchmark.py --policy-steps 100 --eval-episodes 1 --source-episodes 2  # a quick look
"""

import argparse

import xted


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--gap", default="thigh", help="thigh, gravity or friction")
    parser.add_argument("--policy-steps", type=int, default=30_000)
    parser.add_argument("--eval-episodes", type=int, default=10)
    parser.add_argument("--source-episodes", type=int, default=None, help="edit only the first N source episodes")
    args = parser.parse_args()

    target = xted.load_dataset("halfcheetah-medium-replay")
    source = xted.load_dataset(f"halfcheetah-{args.gap}")
    if args.source_episodes is not None:
        source = source.select_episodes(range(args.source_episodes))
    prior = xted.load_prior("halfcheetah-medium-replay-cpu")
    edited = prior.edit(source, kappa=0.5, seed=0, progress=True)
    print(edited.metadata["edit"]["report"]["guard"]["verdict"])  # the guard: what it kept, and why

    report = xted.measure_edit(source, edited, env="halfcheetah")
    sim = report["simulator"]
    print(f"one-step error in the target simulator: source {sim['source']['mae']:.3f}, "
          f"edited {sim['edited']['mae']:.3f}")

    for name, sources in (("Tgt+Src", [source]), ("Tgt+Edited", [edited])):
        policy = xted.train_policy("iql", target, sources=sources, steps=args.policy_steps, env="halfcheetah",
                                   eval_every=args.policy_steps, eval_episodes=args.eval_episodes)
        print(f"{name}: normalised score {policy.scores['final_score']:.1f}")


if __name__ == "__main__":
    main()
