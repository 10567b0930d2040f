"""``xted online``: train behaviour policies online in a domain (SAC or TD3, resumable)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import List, Optional

import typer

from xted.cli.options import config_options, fields_epilog
from xted.envs import parse_domain
from xted.envs.domains import KNOWN_ENVS
from xted.fields import apply_overrides, field_help
from xted.resume import discard_run
from xted.rl.config import ONLINE_ALGORITHM_NAMES, OnlineRunConfig

app = typer.Typer(help="Online RL (SAC, TD3) for behaviour policies and domain-gap measurements.",
                  no_args_is_help=True)


RUN_FIELDS = "\n\n".join(fields_epilog({f"--set {name}.FIELD (with --algo {name})": getattr(OnlineRunConfig(), name)},
                                        prefix=f"{name}.") for name in ONLINE_ALGORITHM_NAMES)


@app.command("train", epilog=RUN_FIELDS)
@config_options(OnlineRunConfig, into="run_fields", skip=("total_steps", "init_from", "sac", "td3"),
                panel="Run settings")
def train(
    env: str = typer.Option(..., "--env", help=f"{KNOWN_ENVS}."),
    gap: Optional[str] = typer.Option(None, "--gap", help="Domain gap to train in (default: target)."),
    out: Path = typer.Option(..., "--out", help="Run folder; an existing one is resumed (same settings)."),
    steps: int = typer.Option(OnlineRunConfig.total_steps, "--steps", min=1,
                              help=field_help(OnlineRunConfig)["total_steps"]),
    init_from: Optional[Path] = typer.Option(
        None, "--init-from", help="Start from the networks of this finished run (same algo): fine-tune a "
        "policy trained in another domain. It acts from the first step; updates begin after --start-steps."),
    overrides: List[str] = typer.Option([], "--set", help="A learner field: sac.FIELD=VALUE or td3.FIELD=VALUE "
                                        "(repeatable; the fields: below)."),
    force: bool = typer.Option(False, "--force", help="Delete a previous run in --out and start afresh."),
    run_fields: List[str] = (),
) -> None:
    """Train in a domain; checkpoints, evaluations (evals.csv) and the replay buffer go to --out.

    An interrupted run continues from its last checkpoint when started again with the same settings (a larger
    --steps extends it)."""
    from xted.rl.online import train_online
    from xted.rl.run_folder import read_evals

    config = apply_overrides(OnlineRunConfig(total_steps=steps, init_from=None if init_from is None else str(init_from)),
                             [*run_fields, *overrides])
    if force:
        discard_run(out, ("run.json",))
    train_online(parse_domain(env, gap), out, config)
    last = read_evals(out)[-1]
    shown = ("step", "return_mean", "normalized_score", "root_pitch_mean")
    print(json.dumps({"run": str(out), **{k: last[k] for k in shown}}))


@app.command("evaluate")
def evaluate_policy(
    policy: Path = typer.Argument(..., help="Actor checkpoint (.msgpack), or a saved policy's folder "
                                  "(xted policy --save DIR: DIR/seed_N)."),
    env: str = typer.Option(..., "--env"),
    gap: Optional[str] = typer.Option(None, "--gap", help="Domain to evaluate in (default: target)."),
    episodes: int = typer.Option(10, "--episodes", min=1),
    seed: int = typer.Option(0, "--seed", min=0),
    as_json: bool = typer.Option(False, "--json"),
) -> None:
    """Greedy return of a policy checkpoint in a domain."""
    from xted.rl.evaluation import evaluate
    from xted.rl.policy_io import Policy

    actor = Policy.load(policy)
    domain = parse_domain(env, gap)
    result = evaluate(actor.act, domain, episodes, seed)
    summary = {"policy": str(policy), "domain": domain.name, "trained_in": actor.meta.get("domain"),
               **{k: result[k] for k in ("return_mean", "return_std", "normalized_score")}}
    print(json.dumps(summary) if as_json else "\n".join(f"{k}: {v}" for k, v in summary.items()))
