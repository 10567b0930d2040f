"""Top-level commands of ``xted``: train a prior, edit source data, the demo."""

from __future__ import annotations

import dataclasses
import json
import types
import typing
from pathlib import Path
from typing import Any, List, Optional

import typer

from xted.cli.main import app
from xted.errors import InputError


def parse_overrides(config_type: type, pairs: list[str]) -> dict[str, Any]:
    """``["field=value", ...]`` -> typed overrides of a config dataclass's fields."""
    hints = typing.get_type_hints(config_type)
    overrides: dict[str, Any] = {}
    for pair in pairs:
        name, sep, text = pair.partition("=")
        if not sep or name not in hints:
            fields = ", ".join(f.name for f in dataclasses.fields(config_type))
            raise InputError(f"--set {pair!r}: expected FIELD=VALUE with FIELD one of {fields}")
        kinds = [k for k in typing.get_args(hints[name]) if k is not type(None)] or [hints[name]]
        if isinstance(hints[name], types.UnionType) and text.lower() == "none":
            overrides[name] = None
            continue
        kind = kinds[0]
        try:
            overrides[name] = (text.lower() in ("1", "true", "yes")) if kind is bool else kind(text)
        except ValueError:
            raise InputError(f"--set {pair!r}: {text!r} is not a {kind.__name__}") from None
    return overrides


@app.command()
def train(
    target: str = typer.Option(..., "--target", help="Target dataset (path or shipped name)."),
    out: Path = typer.Option(..., "--out", help="Prior folder; an existing one is resumed."),
    preset: str = typer.Option("cpu", "--preset", help="cpu (fast, small) or paper (the paper's model)."),
    steps: int = typer.Option(20_000, "--steps", help="Total training steps."),
    seed: int = typer.Option(0, "--seed"),
    checkpoint_every: int = typer.Option(1000, "--checkpoint-every"),
    overrides: List[str] = typer.Option([], "--set", help="Override a config field: FIELD=VALUE (repeatable)."),
) -> None:
    """Train the diffusion prior on target trajectories (resumable; progress, CSV log, checkpoints)."""
    from xted.data import load
    from xted.diffusion.training import PriorConfig, preset as make_preset, train_prior

    data = load(target)
    config = make_preset(preset, data.observation_dim, data.action_dim, seed=seed,
                         **parse_overrides(PriorConfig, overrides))
    train_prior(data, out, config, steps, checkpoint_every=checkpoint_every)
    typer.echo(f"prior trained to step {steps} in {out}")


@app.command()
def edit(
    prior: Path = typer.Option(..., "--prior", help="Prior folder (xted train)."),
    source: str = typer.Option(..., "--source", help="Source dataset (path or shipped name)."),
    out: str = typer.Option(..., "--out", help="Edited dataset; the format follows the path."),
    kappa: float = typer.Option(0.5, "--kappa", help="Noise to step k = kappa*K, then denoise k steps."),
    iterations: int = typer.Option(1, "--iterations", help="Repeated noise+denoise rounds."),
    hold_last: bool = typer.Option(False, "--hold-last", help="Hold the last transition of each window too."),
    guidance: float = typer.Option(1.0, "--guidance", help="Classifier-free return guidance weight."),
    sampler: str = typer.Option("ddpm", "--sampler", help="ddpm or ddim."),
    sampler_steps: Optional[int] = typer.Option(None, "--sampler-steps", help="DDIM steps (default k)."),
    seed: int = typer.Option(0, "--seed"),
    force: bool = typer.Option(False, "--force", help="Replace an existing output."),
) -> None:
    """Edit source trajectories toward the prior's (target) dynamics."""
    from xted.data import formats, load
    from xted.diffusion.editor import EditConfig, edit_dataset
    from xted.diffusion.training import load_prior

    formats.check_writable(formats.target(out), overwrite=force)
    if formats.locate(source).path.resolve() == formats.target(out).path.resolve():
        raise InputError(f"output {out} is the source {source}; choose another output path")
    config = EditConfig(kappa=kappa, iterations=iterations, hold_last=hold_last, guidance=guidance,
                        sampler=sampler, sampler_steps=sampler_steps, seed=seed)
    edited, report = edit_dataset(load_prior(prior), load(source), config)
    formats.save(edited, out, overwrite=force)
    typer.echo(json.dumps({"out": out, **report}))



@app.command()
def demo(
    transitions: int = typer.Option(2000, "--transitions", help="Transitions per dataset."),
) -> None:
    """Show a domain gap: make target and 2x-gravity data, replay both in the target simulator."""
    from xted.data.build import build_dataset
    from xted.envs import parse_domain
    from xted.envs.dynamics import dynamics_error

    target = parse_domain("halfcheetah")
    typer.echo("simulator dynamics MAE in the halfcheetah target domain (random-action data):")
    for gap in (None, "gravity"):
        domain = parse_domain("halfcheetah", gap)
        data = build_dataset(domain, "random", transitions, None, seed=0)
        error = dynamics_error(target, data.observations, data.actions, data.next_observations)
        typer.echo(f"  {domain.name:24s} n={len(data):6d}  MAE={error.mae:.4f}")
