"""Top-level commands of ``xted`` (registered on the main app)."""

from __future__ import annotations

import tempfile
from pathlib import Path

import typer

from xted.cli.main import app


@app.command()
def demo(
    transitions: int = typer.Option(2000, "--transitions", help="Transitions per dataset."),
) -> None:
    """Show a domain gap: make target and 2x-gravity data, replay both in the target simulator."""
    from xted.data import save
    from xted.data.build import build_dataset
    from xted.envs import parse_domain
    from xted.envs.dynamics import dynamics_error

    target = parse_domain("halfcheetah")
    rows = []
    with tempfile.TemporaryDirectory(prefix="xted-demo-") as folder:
        for gap in (None, "gravity"):
            domain = parse_domain("halfcheetah", gap)
            data = build_dataset(domain, "random", transitions, None, seed=0)
            save(data, Path(folder) / f"{domain.name}.npz")
            error = dynamics_error(target, data.observations, data.actions, data.next_observations)
            rows.append((domain.name, len(data), error.mae))
    typer.echo("simulator dynamics MAE in the halfcheetah target domain (random-action data):")
    for name, n, mae in rows:
        typer.echo(f"  {name:24s} n={n:6d}  MAE={mae:.4f}")
