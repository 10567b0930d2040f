"""``xted online``: train behaviour policies online in a domain (SAC or TD3, resumable)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import typer

from xted.envs import parse_domain
from xted.resume import discard_run
from xted.rl.configs import ONLINE_ALGORITHM_NAMES, OnlineRunConfig

app = typer.Typer(help="Online RL (SAC, TD3) for behaviour policies and domain-gap measurements.",
                  no_args_is_help=True)


@app.command("train")
def train(
    env: str = typer.Option(..., "--env", help="halfcheetah or walker2d."),
    gap: Optional[str] = typer.Option(None, "--gap", help="Domain gap to train in (default: target)."),
    out: Path = typer.Option(..., "--out", help="Run folder; an existing one is resumed (same settings)."),
    algo: str = typer.Option(OnlineRunConfig.algo, "--algo", help=" or ".join(ONLINE_ALGORITHM_NAMES) + "."),
    steps: int = typer.Option(OnlineRunConfig.total_steps, "--steps", min=1,
                              help="Total environment steps (one update each)."),
    checkpoint_every: int = typer.Option(OnlineRunConfig.checkpoint_every, "--checkpoint-every", min=1,
                                         help="Steps between checkpoints with a greedy evaluation."),
    start_steps: int = typer.Option(OnlineRunConfig.start_steps, "--start-steps", min=0,
                                    help="Uniform-random steps before learning."),
    eval_episodes: int = typer.Option(OnlineRunConfig.eval_episodes, "--eval-episodes", min=1),
    seed: int = typer.Option(OnlineRunConfig.seed, "--seed", min=0),
    stop_at_return: Optional[float] = typer.Option(
        OnlineRunConfig.stop_at_return, "--stop-at-return",
        help="End the run at the first greedy evaluation whose mean return reaches this."),
    stop_above_pitch: Optional[float] = typer.Option(
        OnlineRunConfig.stop_above_pitch, "--stop-above-pitch",
        help="End the run at the first greedy evaluation whose mean |root pitch| (radians) exceeds this: "
        "drop a cheetah that has flipped onto its back (about 3; upright runs stay under 0.5)."),
    terminate_above_pitch: Optional[float] = typer.Option(
        OnlineRunConfig.terminate_above_pitch, "--terminate-above-pitch",
        help="While training, end an episode (as a terminal) when |root pitch| exceeds this many radians "
        "and add --upright-bonus to the reward of every step before, so a halfcheetah learns to run upright; "
        "evaluations and datasets use the plain domain and its rewards."),
    upright_bonus: float = typer.Option(OnlineRunConfig.upright_bonus, "--upright-bonus", min=0.0,
                                        help="Reward per upright training step with --terminate-above-pitch."),
    init_from: Optional[Path] = typer.Option(
        None, "--init-from", help="Start from the networks of this finished run (same algo): fine-tune a "
        "policy trained in another domain. It acts from the first step; updates begin after --start-steps."),
    force: bool = typer.Option(False, "--force", help="Delete a previous run in --out and start afresh."),
) -> None:
    """Train in a domain; checkpoints, evaluations (evals.csv) and the replay buffer go to --out.

    An interrupted run continues from its last checkpoint when started again with the same
    settings (a larger --steps extends it)."""
    from xted.rl.online import train_online
    from xted.rl.run_folder import read_evals

    config = OnlineRunConfig(algo=algo, total_steps=steps, start_steps=start_steps,
                             checkpoint_every=checkpoint_every, eval_episodes=eval_episodes, seed=seed,
                             stop_at_return=stop_at_return, stop_above_pitch=stop_above_pitch,
                             terminate_above_pitch=terminate_above_pitch, upright_bonus=upright_bonus,
                             init_from=None if init_from is None else str(init_from))
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
