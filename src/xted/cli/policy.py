"""``xted policy``: train offline policies (IQL, TD3+BC, BC, DARA) on target + source data."""

from __future__ import annotations

import json
from pathlib import Path
from typing import List, Optional

import numpy as np
import typer

from xted.cli.main import app
from xted.config import apply_overrides
from xted.errors import InputError
from xted.resume import discard_run


def parse_seeds(text: str) -> list[int]:
    try:
        seeds = [int(part) for part in text.split(",")]
    except ValueError:
        seeds = []
    if not seeds or min(seeds) < 0 or len(set(seeds)) != len(seeds):
        raise InputError(f"--seeds {text!r}: expected distinct non-negative integers such as 0,1,2")
    return seeds


@app.command()
def policy(
    algo: str = typer.Option("iql", "--algo", help="iql, td3bc, bc or dara."),
    target: str = typer.Option(..., "--target", help="Target dataset (path or shipped name)."),
    sources: List[str] = typer.Option([], "--source", help="Source dataset mixed in (repeatable)."),
    env: str = typer.Option(..., "--env", help="halfcheetah or walker2d."),
    gap: Optional[str] = typer.Option(None, "--gap", help="Domain to evaluate in (default: the target domain)."),
    steps: int = typer.Option(100_000, "--steps", min=1, help="Gradient steps per seed."),
    seeds: str = typer.Option("0", "--seeds", help="Comma-separated seeds, trained together."),
    eval_episodes: int = typer.Option(10, "--eval-episodes", min=1, help="Episodes per evaluation and seed."),
    eval_every: int = typer.Option(10_000, "--eval-every", min=1, help="Steps between evaluations (and at the end)."),
    s4rl_noise: float = typer.Option(0.0, "--s4rl-noise", min=0.0,
                                     help="S4RL Gaussian state-noise std in standardised units (S4RL: 3e-4); 0 = off."),
    overrides: List[str] = typer.Option(
        [], "--set", help="Override a config field: FIELD=VALUE, hidden=256,256, iql.FIELD=VALUE (repeatable)."),
    out: Optional[Path] = typer.Option(None, "--out", help="Folder of per-seed results; finished seeds are skipped."),
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object."),
    allow_env_mismatch: bool = typer.Option(False, "--allow-env-mismatch",
                                            help="Train on data whose recorded env differs from --env."),
    force: bool = typer.Option(False, "--force", help="Delete the previous results in --out and train every seed afresh."),
) -> None:
    """Train an offline policy per seed (all seeds at once) and report normalised scores in the target env."""
    from xted.data import load
    from xted.envs import check_same_env, dataset_env, parse_domain
    from xted.rl.offline_train import default_config, train_offline

    config = apply_overrides(default_config(algo), overrides)
    seed_list = parse_seeds(seeds)
    domain = parse_domain(env, gap)
    target_data, source_data = load(target), [load(s) for s in sources]
    for role, name, data in (("--target", target, target_data), *(("--source", n, d) for n, d in zip(sources, source_data))):
        check_same_env(domain.env, dataset_env(data.metadata), f"{role} {name}", allow_env_mismatch)
    if force and out is not None:
        discard_run(out, ("seed_*.json",))
    results = train_offline(config, target_data, source_data, domain, steps, seed_list,
                            eval_every=eval_every, eval_episodes=eval_episodes, out_dir=out, s4rl_noise=s4rl_noise)
    scores = [r["final_score"] for r in results]
    summary = {"algo": algo, "env": env, "domain": domain.name, "seeds": seed_list, "steps": steps,
               "scores": scores, "best_scores": [r["best_score"] for r in results],
               "mean": float(np.mean(scores)), "std": float(np.std(scores))}
    if as_json:
        typer.echo(json.dumps(summary))
        return
    for r in results:
        typer.echo(f"seed {r['seed']}: final {r['final_score']:.1f}  best {r['best_score']:.1f}")
    typer.echo(f"{algo} in {domain.name}: {summary['mean']:.1f} +- {summary['std']:.1f} over {len(scores)} seeds")
