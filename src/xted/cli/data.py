"""``xted data``: inspect, convert and list datasets."""

from __future__ import annotations

import json
from typing import Annotated, Any

import typer

from xted.data import formats, shipped
from xted.envs.domains import KNOWN_ENVS
from xted.errors import InputError

app = typer.Typer(
    help="Inspect, convert and list datasets (.npz, D4RL-style .hdf5/.h5, Minari).",
    no_args_is_help=True,
    add_completion=False,
)

SOURCE_HELP = "A .npz/.hdf5/.h5 file, a Minari dataset folder, minari:ID, or a shipped dataset name."
DEST_HELP = "Output: .npz, .hdf5/.h5, a Minari dataset folder, or minari:ID."


@app.command()
def info(
    path: Annotated[str, typer.Argument(help=SOURCE_HELP, show_default=False)],
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
) -> None:
    """Summarise a dataset: episodes, transitions, dimensions, returns, episode ends, metadata."""
    report = dataset_info(path)
    if as_json:
        typer.echo(json.dumps(report, indent=2))
    else:
        typer.echo(_readable(report))


@app.command()
def convert(
    src: Annotated[str, typer.Argument(help=SOURCE_HELP, show_default=False)],
    dst: Annotated[str, typer.Argument(help=DEST_HELP, show_default=False)],
    force: Annotated[bool, typer.Option("--force", help="Replace an existing output.")] = False,
) -> None:
    """Convert a dataset between formats; the output appears whole or not at all."""
    source, destination = formats.locate(src), formats.target(dst)
    formats.check_apart(destination, {"source": src})
    formats.check_writable(destination, overwrite=force)
    dataset = formats.load(source.path)
    formats.save(dataset, dst, overwrite=force)
    typer.echo(
        f"wrote {len(dataset)} transitions ({dataset.num_episodes} episodes) "
        f"to {destination.path} ({destination.format})"
    )


@app.command()
def make(
    env: Annotated[str, typer.Option("--env", help=f"{KNOWN_ENVS}.")],
    level: Annotated[str, typer.Option("--level", help="random, medium, medium-replay, expert, medium-expert, source.")],
    out: Annotated[str, typer.Option("--out", help=DEST_HELP)],
    gap: Annotated[str | None, typer.Option("--gap", help="Domain gap (source data), e.g. gravity or thigh=3.")] = None,
    transitions: Annotated[int, typer.Option("--transitions", min=1, help="Number of transitions.")] = 20_000,
    run: Annotated[str | None, typer.Option(
        "--run", help="online run folder (xted online train); default: shipped policies.")] = None,
    medium_step: Annotated[int | None, typer.Option(
        "--medium-step", min=0, help="With --run: the evaluated checkpoint that is the medium policy (medium, "
        "medium-replay's buffer cut, medium-expert); default: the one nearest half the best return.")] = None,
    seed: Annotated[int, typer.Option("--seed", min=0)] = 0,
    force: Annotated[bool, typer.Option("--force", help="Replace an existing output.")] = False,
) -> None:
    """Make a D4RL-style dataset by running behaviour policies in a domain."""
    from xted.pipelines.behaviour_data import BehaviourPolicies, build_dataset
    from xted.envs import parse_domain

    if medium_step is not None and run is None:
        raise InputError("--medium-step goes with --run (the shipped policies' medium is fixed)")
    domain = parse_domain(env, gap)
    formats.check_writable(formats.target(out), overwrite=force)
    policies = None
    if level != "random":
        policies = BehaviourPolicies.from_run(run, medium_step) if run else BehaviourPolicies.shipped(domain)
    dataset = build_dataset(domain, level, transitions, policies, seed=seed)
    formats.save(dataset, out, overwrite=force)
    typer.echo(f"wrote {len(dataset)} transitions ({dataset.num_episodes} episodes) of {domain.name} {level} "
               f"to {out}; normalized_score={dataset.metadata['normalized_score']}")


@app.command("list")
def list_shipped(
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object {name: entry}.")] = False,
) -> None:
    """List the datasets shipped with xted."""
    entries = {name: shipped.manifest()["datasets"][name] for name in shipped.names()}
    d4rl = {name: shipped.d4rl_behaviour_score(name) for name in entries}
    if as_json:
        typer.echo(json.dumps({name: {**entry, **({"d4rl_normalized_score": d4rl[name]} if d4rl[name] else {})}
                               for name, entry in entries.items()}, indent=2))
        return
    if not entries:
        typer.echo("no shipped datasets")
    for name, entry in entries.items():
        score = entry.get("normalized_score")
        beside = f" (D4RL's: {d4rl[name]:g})" if d4rl[name] else ""
        typer.echo(
            f"{name}: transitions={entry.get('transitions', '?')} "
            f"normalized_score={'?' if score is None else f'{score:.1f}'}{beside} file={entry.get('file', '?')}"
        )


def dataset_info(path: str) -> dict[str, Any]:
    """The ``data info --json`` object for ``path``."""
    location = formats.locate(path)
    dataset = formats.load(location.path)
    report = {"format": location.format, "path": str(location.path), **dataset.summary()}
    if "normalized_score" in dataset.metadata:
        report["normalized_score"] = dataset.metadata["normalized_score"]
    return report


def _readable(report: dict[str, Any]) -> str:
    lines = [
        f"path:              {report['path']} ({report['format']})",
        f"episodes:          {report['episodes']}",
        f"transitions:       {report['transitions']}",
        f"observation_dim:   {report['observation_dim']}",
        f"action_dim:        {report['action_dim']}",
        (f"return:            mean {report['return_mean']:.3f}, std {report['return_std']:.3f}, "
         f"min {report['return_min']:.3f}, max {report['return_max']:.3f}" if report["rewards"]
         else "return:            none (reward-free data)"),
        f"episode length:    mean {report['episode_length_mean']:.1f}, "
        f"min {report['episode_length_min']}, max {report['episode_length_max']}",
        f"episode ends:      {report['terminals']} terminals, {report['timeouts']} timeouts",
        f"next_observations: {'stored' if report['next_observations'] else 'not stored'}",
        f"extras:            {', '.join(report['extras']) or 'none'}",
    ]
    if "normalized_score" in report:
        lines.append(f"normalized_score:  {report['normalized_score']}")
    lines.append(f"metadata:          {json.dumps(report['metadata'], sort_keys=True)}")
    return "\n".join(lines)
