"""``xted policy``: train offline policies (IQL, TD3+BC, BC, DARA, IGDF, OTDF) on target + source data."""

from __future__ import annotations

import json
from pathlib import Path
from typing import List, Optional

import numpy as np
import typer

from xted.cli.main import app
from xted.cli.options import fields_epilog, parse_seeds
from xted.envs.domains import KNOWN_ENVS
from xted.fields import apply_overrides
from xted.errors import InputError
from xted.rl.config import OFFLINE_STEPS
from xted.resume import discard_run
from xted.rl.config import OFFLINE_ALGORITHMS


ALGORITHM_FIELDS = fields_epilog({f"--set fields of --algo {name}": kind for name, kind in OFFLINE_ALGORITHMS.items()})


@app.command(epilog=ALGORITHM_FIELDS)
def policy(
    algo: str = typer.Option("iql", "--algo", help=", ".join(OFFLINE_ALGORITHMS) + " (their fields: below)."),
    target: str = typer.Option(..., "--target", help="Target dataset (path or shipped name)."),
    sources: List[str] = typer.Option([], "--source", help="Source dataset mixed in (repeatable)."),
    env: Optional[str] = typer.Option(
        None, "--env", help=f"{KNOWN_ENVS}, to evaluate in (default: the target data's recorded env); "
        "none: train without a simulator (needs --save)."),
    gap: Optional[str] = typer.Option(None, "--gap", help="Domain to evaluate in (default: the target domain)."),
    steps: int = typer.Option(OFFLINE_STEPS, "--steps", min=1, help="Gradient steps per seed."),
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
    force: bool = typer.Option(False, "--force",
                               help="Delete the previous results in --out and --save and train every seed afresh."),
    save: Optional[Path] = typer.Option(
        None, "--save", help="Folder to save each seed's trained policy in (DIR/seed_N: actor, config, observation "
        "standardisation, data fingerprints); finished seeds are skipped."),
) -> None:
    """Train an offline policy per seed (all seeds at once); report normalised scores in the target
    env, and with --save keep the policies (xted.load_policy, then Policy.act)."""
    from xted.data import load
    from xted.envs import check_same_env, dataset_env, parse_domain
    from xted.rl.offline_train import default_config, train_offline

    config = apply_overrides(default_config(algo), overrides)
    seed_list = parse_seeds(seeds)
    target_data, source_data = load(target), [load(s) for s in sources]
    env_name = _evaluation_env(env, dataset_env(target_data.metadata), gap, save)
    domain = None if env_name is None else parse_domain(env_name, gap)
    for role, name, data in (("--target", target, target_data), *(("--source", n, d) for n, d in zip(sources, source_data))):
        check_same_env(env_name, dataset_env(data.metadata), f"{role} {name}", allow_env_mismatch)
    if force:
        for folder, markers in ((out, ("seed_*.json",)), (save, ("seed_*/policy.msgpack",))):
            if folder is not None:
                discard_run(folder, markers)
    results = train_offline(config, target_data, source_data, domain, steps, seed_list, eval_every=eval_every,
                            eval_episodes=eval_episodes, out_dir=out, s4rl_noise=s4rl_noise, save_dir=save)
    scores = [r["final_score"] for r in results]
    evaluated = domain is not None
    summary = {"algo": algo, "env": env_name, "domain": domain.name if evaluated else None, "seeds": seed_list,
               "steps": steps, "scores": scores, "best_scores": [r["best_score"] for r in results],
               "mean": float(np.mean(scores)) if evaluated else None,
               "std": float(np.std(scores)) if evaluated else None,
               "saved": None if save is None else [str(save / f"seed_{seed}") for seed in seed_list]}
    if as_json:
        typer.echo(json.dumps(summary))
        return
    for r in results:
        where = "" if save is None else f"  saved in {save / ('seed_' + str(r['seed']))}"
        if evaluated:
            typer.echo(f"seed {r['seed']}: final {r['final_score']:.1f}  best {r['best_score']:.1f}{where}")
        else:
            last = {name: value for name, value in (r.get("losses") or [{}])[-1].items() if name != "step"}
            shown = ", ".join(f"{name} {value:.4g}" for name, value in last.items())
            typer.echo(f"seed {r['seed']}: trained {steps} steps, not evaluated (no env); last losses: {shown}{where}")
    if evaluated:
        typer.echo(f"{algo} in {domain.name}: {summary['mean']:.1f} +- {summary['std']:.1f} over {len(scores)} seeds")


def _evaluation_env(env: str | None, recorded: str | None, gap: str | None, save: Path | None) -> str | None:
    """The env to evaluate in: ``--env``, else the target data's recorded one; None for ``--env
    none`` or data of no known env, which needs ``--save`` (else nothing would come of the run)."""
    from xted.envs import ENV_IDS

    if env is not None and env.strip().lower() == "none":
        name = None
    elif env is not None:
        name = env
    else:
        name = recorded if recorded in ENV_IDS else None
    if name is None and gap is not None:
        raise InputError("--gap names a domain to evaluate in: give --env too")
    if name is None and save is None:
        known = ", ".join(ENV_IDS)
        why = ("--env none" if env is not None
               else f"the target data records env {recorded!r}, which xted does not simulate (known: {known})"
               if recorded else f"the target data records no env (known: {known}; or give --env)")
        raise InputError(f"{why}: the policy cannot be evaluated, so give --save DIR to keep it")
    return name
