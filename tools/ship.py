"""Build the datasets and behaviour policies shipped with xted (maintainers' tool).

    python tools/ship.py [--runs RUNS] [--envs ENV...] [--domains target gravity ...] [--transitions 20000]

It lives outside the package: it writes into the package's own assets, which the library never does.

From the online run folders ``RUNS/{domain}`` (``xted online train``) it copies the behaviour policies
into ``xted/assets/policies`` (target: expert and medium; sources: expert), then makes every shipped dataset with exactly the command a user would
run (``xted data make ... --out``) and records each file in ``assets/datasets/manifest.json``.
Without ``--runs`` the shipped policies are kept and only the datasets are made again.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import shutil
from pathlib import Path


from xted.atomic import atomic_path
from xted.data.shipped import policies_dir
from xted.pipelines.behaviour_data import BehaviourPolicies, build_dataset
from xted.data.formats import save
from xted.data.shipped import MANIFEST_NAME, assets_dir
from xted.envs import PAPER_GAPS, parse_domain
from xted.rl.policy_io import Policy
from xted.rl.run_folder import read_evals

TARGET_LEVELS = ("medium", "medium-replay", "medium-expert")


def sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def file_entry(path: Path, root: Path) -> dict:
    return {"file": str(path.relative_to(root)), "sha256": sha256(path), "bytes": path.stat().st_size}


def _ship_policies(env: str, gaps: list[str | None], runs: Path, folder: Path) -> dict:
    entries = {}
    for gap in gaps:
        domain = parse_domain(env, gap)
        run = runs / domain.name
        chosen = BehaviourPolicies.from_run(run)
        evals = {int(row["step"]): row for row in read_evals(run)}
        roles = {"expert": chosen.expert}
        if domain.is_target:
            roles["medium"] = chosen.medium
        settings = json.loads((run / "run.json").read_text())["run"]
        init_from, tipping = settings.get("init_from"), settings.get("terminate_above_pitch")
        # The run it started from, as a folder beside it (runs/online/NAME): where it lives here says nothing.
        init = f" --init-from {Path(init_from).name}" if init_from else ""
        init += f" --terminate-above-pitch {tipping}" if tipping is not None else ""
        for role, source in roles.items():
            meta = Policy.load(source).meta
            step, algo = meta["step"], meta.get("algo", "sac")
            dest = folder / f"{domain.name}-{role}.msgpack"
            shutil.copyfile(source, dest)
            entries[dest.stem] = {**file_entry(dest, folder), "domain": domain.name, "role": role, "step": step,
                                  "eval_return": evals[step]["return_mean"],
                                  "eval_normalized_score": evals[step]["normalized_score"],
                                  "trained_steps": int(max(evals)), "command": f"xted online train --env {env}" + (f" --gap {gap}" if gap else "")
                                  + f" --algo {algo} --seed {meta['seed']} --steps {int(max(evals))}{init} --out RUN"}
    return entries


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=Path, default=None, help="online run folders; default: keep the shipped policies")
    parser.add_argument("--envs", nargs="+", default=["halfcheetah", "walker2d"])
    parser.add_argument("--domains", nargs="+", default=["target", *sorted({g for gaps in PAPER_GAPS.values() for g in gaps})],
                        help="which of target and the paper's gaps to ship (default: all)")
    parser.add_argument("--transitions", type=int, default=20_000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)

    data_root, policy_root = assets_dir(), policies_dir()
    data_root.mkdir(parents=True, exist_ok=True)
    policy_root.mkdir(parents=True, exist_ok=True)
    manifest_path = data_root / MANIFEST_NAME
    manifest = json.loads(manifest_path.read_text()) if manifest_path.exists() else {"datasets": {}, "policies": {}}
    for env in args.envs:
        gaps = [None if name == "target" else name for name in args.domains]
        if args.runs is not None:
            manifest["policies"].update(_ship_policies(env, gaps, args.runs, policy_root))
        jobs = [(None, level) for level in TARGET_LEVELS if None in gaps] + [(gap, "source") for gap in gaps if gap]
        for gap, level in jobs:
            domain = parse_domain(env, gap)
            name = f"{env}-{level}" if gap is None else domain.name
            dest = data_root / f"{name}.npz"
            command = (f"xted data make --env {env}" + (f" --gap {gap}" if gap else "")
                       + f" --level {level} --transitions {args.transitions} --seed {args.seed} --out {name}.npz"
                       + (" --run RUN" if level == "medium-replay" else ""))
            # The replay buffer behind medium-replay (tens of MB) is not shipped: it comes from the run.
            from_run = level == "medium-replay"
            if from_run and args.runs is None:
                raise SystemExit("medium-replay needs the run's replay buffer: pass --runs")
            policies = BehaviourPolicies.from_run(args.runs / domain.name) if from_run else BehaviourPolicies.shipped(domain)
            dataset = build_dataset(domain, level, args.transitions, policies, seed=args.seed)
            dataset = dataset.with_metadata(command=command, name=name)
            save(dataset, dest)
            returns = dataset.episode_returns()
            manifest["datasets"][name] = {
                **file_entry(dest, data_root), "arrays_sha256": dataset.fingerprint(), "env": env, "gap": domain.gap,
                "level": level,
                "transitions": len(dataset), "episodes": dataset.num_episodes,
                "return_mean": float(returns.mean()), "normalized_score": dataset.metadata["normalized_score"],
                "command": command,
            }
            with atomic_path(manifest_path) as tmp:
                tmp.write_text(json.dumps(manifest, indent=2, sort_keys=True))
            print(f"{name}: {len(dataset)} transitions, normalized score {dataset.metadata['normalized_score']:.1f}")


if __name__ == "__main__":
    main()
