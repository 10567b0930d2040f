"""Build the datasets and behaviour policies shipped with xted (maintainers' tool).

    python tools/ship.py [--runs RUNS] [--envs ENV...] [--domains target gravity ...] [--transitions 20000]
                         [--medium-from DOMAIN=RUN:STEP ...]

It lives outside the package: it writes into the package's own assets, which the library never does.

From the online run folders ``RUNS/{domain}`` (``xted online train``) it copies the behaviour policies
into ``xted/assets/policies`` (target: expert and medium; sources: expert), then makes every shipped
dataset with exactly the command a user would run (``xted data make ... --out``) and records each
file in ``assets/datasets/manifest.json``. ``--medium-from`` takes a target's medium policy (and
medium-replay's buffer) from another run's checkpoint. Without ``--runs`` the shipped experts are
kept and only the datasets (and any ``--medium-from`` policy) are made again.
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


def medium_runs(pairs: list[str]) -> dict[str, tuple[Path, int]]:
    """``--medium-from DOMAIN=RUN:STEP`` pairs as ``{domain: (run folder, step)}``."""
    found = {}
    for pair in pairs:
        domain, _, rest = pair.partition("=")
        run, _, step = rest.rpartition(":")
        if not (domain and run and step.isdigit()):
            raise SystemExit(f"--medium-from {pair!r}: expected DOMAIN=RUN:STEP")
        found[domain] = (Path(run), int(step))
    return found


def target_policies(domain, runs: Path | None, mediums: dict[str, tuple[Path, int]]) -> BehaviourPolicies:
    """A target's expert from ``RUNS/DOMAIN``; its medium (and the replay buffer behind medium-replay)
    from there too, or from the run and step ``--medium-from`` names."""
    if domain.name in mediums:
        run, step = mediums[domain.name]
        return BehaviourPolicies.from_run(run, step)
    if runs is None:
        raise SystemExit("medium-replay needs the run's replay buffer: pass --runs (or --medium-from)")
    return BehaviourPolicies.from_run(runs / domain.name)


def _policy_entry(env: str, gap: str | None, role: str, source: Path, run: Path, folder: Path, domain) -> dict:
    evals = {int(row["step"]): row for row in read_evals(run)}
    settings = json.loads((run / "run.json").read_text())["run"]
    init_from, tipping = settings.get("init_from"), settings.get("terminate_above_pitch")
    # The run it started from, as a folder beside it (runs/online/NAME): where it lives here says nothing.
    init = f" --init-from {Path(init_from).name}" if init_from else ""
    init += f" --terminate-above-pitch {tipping}" if tipping is not None else ""
    meta = Policy.load(source).meta
    step, algo = meta["step"], meta.get("algo", "sac")
    dest = folder / f"{domain.name}-{role}.msgpack"
    shutil.copyfile(source, dest)
    return {**file_entry(dest, folder), "domain": domain.name, "role": role, "step": step,
            "eval_return": evals[step]["return_mean"], "eval_normalized_score": evals[step]["normalized_score"],
            "trained_steps": int(max(evals)), "command": f"xted online train --env {env}" + (f" --gap {gap}" if gap else "")
            + f" --algo {algo} --seed {meta['seed']} --steps {int(max(evals))}{init} --out RUN"}


def _ship_policies(env: str, gaps: list[str | None], runs: Path | None, mediums: dict[str, tuple[Path, int]],
                   folder: Path) -> dict:
    entries = {}
    for gap in gaps:
        domain = parse_domain(env, gap)
        if runs is not None:
            run = runs / domain.name
            expert = BehaviourPolicies.from_run(run).expert
            entries[f"{domain.name}-expert"] = _policy_entry(env, gap, "expert", expert, run, folder, domain)
        if domain.is_target and (runs is not None or domain.name in mediums):
            run = mediums[domain.name][0] if domain.name in mediums else runs / domain.name
            medium = target_policies(domain, runs, mediums).medium
            entries[f"{domain.name}-medium"] = _policy_entry(env, gap, "medium", medium, run, folder, domain)
    return entries


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=Path, default=None, help="online run folders; default: keep the shipped policies")
    parser.add_argument("--envs", nargs="+", default=["halfcheetah", "walker2d"])
    parser.add_argument("--domains", nargs="+", default=["target", *sorted({g for gaps in PAPER_GAPS.values() for g in gaps})],
                        help="which of target and the paper's gaps to ship (default: all)")
    parser.add_argument("--medium-from", nargs="+", default=[], metavar="DOMAIN=RUN:STEP",
                        help="a target's medium policy (and medium-replay's buffer) from this run's checkpoint at STEP "
                        "instead of RUNS/DOMAIN's (walker2d: a second run, its medium at D4RL's level)")
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
        mediums = medium_runs(args.medium_from)
        manifest["policies"].update(_ship_policies(env, gaps, args.runs, mediums, policy_root))
        jobs = [(None, level) for level in TARGET_LEVELS if None in gaps] + [(gap, "source") for gap in gaps if gap]
        for gap, level in jobs:
            domain = parse_domain(env, gap)
            name = f"{env}-{level}" if gap is None else domain.name
            dest = data_root / f"{name}.npz"
            # The replay buffer behind medium-replay (tens of MB) is not shipped: it comes from the run.
            from_run = level == "medium-replay"
            chosen_step = f" --medium-step {mediums[domain.name][1]}" if from_run and domain.name in mediums else ""
            command = (f"xted data make --env {env}" + (f" --gap {gap}" if gap else "")
                       + f" --level {level} --transitions {args.transitions} --seed {args.seed} --out {name}.npz"
                       + (f" --run RUN{chosen_step}" if from_run else ""))
            policies = target_policies(domain, args.runs, mediums) if from_run else BehaviourPolicies.shipped(domain)
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
