"""``xted sac``: train behaviour policies online in a domain (resumable)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import typer

from xted.envs import parse_domain

app = typer.Typer(help="Online SAC for behaviour policies and domain-gap measurements.", no_args_is_help=True)


@app.command("train")
def train(
    env: str = typer.Option(..., "--env", help="halfcheetah or walker2d."),
    gap: Optional[str] = typer.Option(None, "--gap", help="Domain gap to train in (default: target)."),
    out: Path = typer.Option(..., "--out", help="Run folder; an existing one is resumed."),
    steps: int = typer.Option(300_000, "--steps", help="Total environment steps."),
    checkpoint_every: int = typer.Option(10_000, "--checkpoint-every", help="Steps between checkpoints."),
    start_steps: int = typer.Option(5_000, "--start-steps", help="Uniform-random steps before learning."),
    seed: int = typer.Option(0, "--seed"),
) -> None:
    """Train SAC in a domain; checkpoints, evaluations and the replay buffer go to --out."""
    from xted.rl.sac_train import SACRunConfig, read_evals, train_sac

    config = SACRunConfig(total_steps=steps, start_steps=start_steps, checkpoint_every=checkpoint_every, seed=seed)
    train_sac(parse_domain(env, gap), out, config)
    last = read_evals(out)[-1]
    print(json.dumps({"run": str(out), **{k: last[k] for k in ("step", "return_mean", "normalized_score")}}))


@app.command("evaluate")
def evaluate_policy(
    policy: Path = typer.Argument(..., help="Actor checkpoint (.msgpack)."),
    env: str = typer.Option(..., "--env"),
    gap: Optional[str] = typer.Option(None, "--gap", help="Domain to evaluate in (default: target)."),
    episodes: int = typer.Option(10, "--episodes"),
    seed: int = typer.Option(0, "--seed"),
    as_json: bool = typer.Option(False, "--json"),
) -> None:
    """Greedy return of a policy checkpoint in a domain."""
    from xted.rl.evaluation import evaluate
    from xted.rl.policy_io import GaussianActor

    actor = GaussianActor.load(policy)
    domain = parse_domain(env, gap)
    result = evaluate(actor.act, domain, episodes, seed)
    summary = {"policy": str(policy), "domain": domain.name, "trained_in": actor.meta.get("domain"),
               **{k: result[k] for k in ("return_mean", "return_std", "normalized_score")}}
    print(json.dumps(summary) if as_json else "\n".join(f"{k}: {v}" for k, v in summary.items()))
