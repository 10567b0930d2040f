"""``xted analyze``: measure datasets against a domain's simulator."""

from __future__ import annotations

import json
from typing import List, Optional

import typer

from xted.envs import parse_domain

app = typer.Typer(help="Measure datasets: simulator dynamics error.", no_args_is_help=True)


@app.command("dynamics")
def dynamics(
    datasets: List[str] = typer.Argument(..., help="Dataset paths or shipped names."),
    env: str = typer.Option(..., "--env", help="halfcheetah or walker2d."),
    gap: Optional[str] = typer.Option(None, "--gap", help="Domain to replay in (default: the target domain)."),
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """Replay every transition (s, a, s') in the domain's simulator; report MAE and MSE."""
    from xted.data import load
    from xted.envs.dynamics import dynamics_error

    domain = parse_domain(env, gap)
    results = []
    for name in datasets:
        data = load(name)
        error = dynamics_error(domain, data.observations, data.actions, data.next_observations_or_derived())
        results.append({"path": name, **error.summary()})
    if as_json:
        print(json.dumps({"env": env, "domain": domain.name, "datasets": results}))
        return
    print(f"simulator dynamics error in {domain.name}")
    print(f"{'dataset':40s} {'n':>7s} {'excluded':>8s} {'MAE':>9s} {'MSE':>9s} {'MAE p50':>9s} {'MAE p90':>9s}")
    for row in results:
        q = row["mae_quantiles"]
        print(f"{row['path'][-40:]:40s} {row['n']:7d} {row['excluded_clipped']:8d} {row['mae']:9.4f} "
              f"{row['mse']:9.4f} {q['p50']:9.4f} {q['p90']:9.4f}")
