"""``xted bench run`` and ``xted bench report``: the paper's Table 1 protocol as a resumable grid of cells,
and its report; both name the grid with the same options. ``xted bench refresh`` rewrites the report
blocks of markdown documents from the store."""

from __future__ import annotations

import contextlib
import functools
import inspect
import io
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any, List, Optional

import typer
from typer.core import TyperGroup

from xted.cli.options import fields_epilog, parse_seeds
from xted.errors import InputError
from xted.diffusion.config import EditConfig
from xted.pipelines.bench.columns import COLUMN_SETS, COLUMNS, LEARNER_WRAPPERS, expand_column_sets
from xted.pipelines.bench.config import BenchConfig, RayConfig
from xted.rl.config import OFFLINE_ALGORITHMS

DEFAULTS = BenchConfig()
RAY_DEFAULTS = RayConfig()


def _names(text: str, option: str) -> tuple[str, ...]:
    names = tuple(part.strip() for part in text.split(",") if part.strip())
    if not names:
        raise InputError(f"{option} {text!r}: expected comma-separated names")
    return names


def _joined(values: tuple) -> str:
    return ",".join(str(value) for value in values)


FIELDS = "\n\n".join((
    fields_epilog({"--edit fields (the edit of every Tgt+Edited cell; --kappa sets kappa)": EditConfig}, "--edit"),
    fields_epilog({f"--set fields of --algos {name}": kind for name, kind in OFFLINE_ALGORITHMS.items()
                   if name not in LEARNER_WRAPPERS}),
    *(fields_epilog({f"--set {name}.FIELD: the fields of the columns whose learner is {name} (its backbone is the "
                     "IQL learner above)": OFFLINE_ALGORITHMS[name]}, prefix=f"{name}.", nested=False)
      for name in LEARNER_WRAPPERS),
))


class _BenchCommands(TyperGroup):
    """``run`` and ``report``; the one-command form of before (``xted bench [--report] OPTIONS``) is
    refused with its new spelling."""

    def resolve_command(self, ctx, args):
        if args and args[0] not in self.commands:
            rest = " ".join(arg for arg in args if arg != "--report")
            raise InputError(
                "xted bench is two commands now: `xted bench run` computes the grid's missing cells, `xted bench "
                f"report` prints its stored results (was `xted bench --report`): `xted bench "
                f"{'report' if '--report' in args else 'run'} {rest}`")
        return super().resolve_command(ctx, args)


app = typer.Typer(cls=_BenchCommands, no_args_is_help=True, context_settings={"ignore_unknown_options": True},
                  help="The paper's Table 1 protocol as a resumable grid of cells (env x target x gap x column x algo "
                  "x seed): run computes it, report reads it, prune lists (or removes) stored results of no "
                  "cell of it; all take the same grid options.")


def grid_config(
    envs: str = typer.Option(_joined(DEFAULTS.envs), "--envs", help="Envs, comma-separated."),
    targets: str = typer.Option(_joined(DEFAULTS.targets), "--targets",
                                help="Target levels (shipped ENV-LEVEL data), comma-separated."),
    gaps: str = typer.Option(_joined(DEFAULTS.gaps), "--gaps", help="Source domains, comma-separated."),
    columns: str = typer.Option(_joined(DEFAULTS.columns), "--columns",
                                help=f"Training data per learner, comma-separated: {', '.join(COLUMNS)}; or a set of "
                                f"them: {', '.join(COLUMN_SETS)}."),
    algos: str = typer.Option(_joined(DEFAULTS.algos), "--algos",
                              help="iql, td3bc, bc (comma-separated); the DARA, IGDF and OTDF columns are IQL's."),
    seeds: str = typer.Option(_joined(DEFAULTS.seeds), "--seeds", help="Seeds, trained together per group."),
    steps: int = typer.Option(DEFAULTS.steps, "--steps", min=1, help="Gradient steps per learner."),
    eval_every: int = typer.Option(DEFAULTS.eval_every, "--eval-every", min=1, help="Steps between evaluations."),
    eval_episodes: int = typer.Option(DEFAULTS.eval_episodes, "--eval-episodes", min=1,
                                      help="Episodes per evaluation."),
    kappa: float = typer.Option(DEFAULTS.kappa, "--kappa", min=0.0, max=1.0, help="Edit noise level kappa."),
    edit: List[str] = typer.Option([], "--edit", help="EditConfig override FIELD=VALUE (repeatable)."),
    project_dynamics: bool = typer.Option(
        DEFAULTS.project_dynamics, "--project-dynamics",
        help="Project every edit onto a dynamics model fitted to the row's target data, as xted edit "
        "--project-dynamics does (--edit dynamics_weight=W; opt-in, beyond the paper)."),
    dynamics_proxy_steps: int = typer.Option(DEFAULTS.dynamics_proxy_steps, "--dynamics-proxy-steps", min=1,
                                             help="Training steps of that dynamics model."),
    overrides: List[str] = typer.Option(
        [], "--set", help="Algorithm config override FIELD=VALUE; DARA's, IGDF's and OTDF's own as dara.FIELD=VALUE, "
        "igdf.FIELD=VALUE, otdf.FIELD=VALUE (repeatable)."),
    priors: List[str] = typer.Option(
        [], "--prior", help="Prior folder per env: ENV=PATH or ENV-TARGET=PATH (default: the shipped one, else one the "
        "bench trains; --prior-steps, --prior-preset)."),
    prior_steps: int = typer.Option(DEFAULTS.prior_steps, "--prior-steps", min=1,
                                    help="Training steps of a prior the bench trains (a target with none shipped or given)."),
    prior_preset: str = typer.Option(DEFAULTS.prior_preset, "--prior-preset",
                                     help="Preset of a prior the bench trains: cpu or paper."),
    prior_overrides: List[str] = typer.Option(
        [], "--prior-set", help="PriorConfig override of a prior the bench trains: FIELD=VALUE for every env, "
        "ENV:FIELD=VALUE for one (repeatable; xted train --set's fields). Targets with a shipped or given "
        "prior keep it."),
    ser_steps: int = typer.Option(DEFAULTS.ser_steps, "--ser-steps", min=1,
                                  help="Training steps of the Tgt SER column's transition diffusion model."),
    transitions: Optional[int] = typer.Option(DEFAULTS.transitions, "--transitions", min=1,
                                              help="Use only the first N transitions of every dataset."),
    store: Path = typer.Option(Path(DEFAULTS.store), "--store",
                               help="Folder of the cells' result JSONs, relative to the current folder (the default is "
                               "the store committed in a checkout of xted, when run from its root)."),
    cache: Path = typer.Option(Path(DEFAULTS.cache), "--cache", help="Folder of made datasets (edits, oracles)."),
) -> BenchConfig:
    """The grid both commands name, from its options (checked by BenchConfig)."""
    return BenchConfig(
        envs=_names(envs, "--envs"), targets=_names(targets, "--targets"), gaps=_names(gaps, "--gaps"),
        columns=expand_column_sets(_names(columns, "--columns")), algos=_names(algos, "--algos"), seeds=tuple(parse_seeds(seeds)),
        steps=steps, eval_every=eval_every, eval_episodes=eval_episodes, kappa=kappa, edit=tuple(edit),
        project_dynamics=project_dynamics, dynamics_proxy_steps=dynamics_proxy_steps, overrides=tuple(overrides),
        priors=tuple(priors), prior_steps=prior_steps, prior_preset=prior_preset,
        prior_overrides=tuple(prior_overrides), ser_steps=ser_steps, transitions=transitions, store=str(store),
        cache=str(cache))


GRID_PARAMETERS = list(inspect.signature(grid_config, eval_str=True).parameters.values())


def with_grid(command: Callable) -> Callable:
    """Give ``command`` the grid's options (:func:`grid_config`'s); it receives them as ``config``."""
    own = [p for p in inspect.signature(command, eval_str=True).parameters.values() if p.name != "config"]

    @functools.wraps(command)
    def wrapper(**kwargs: Any) -> Any:
        grid = {p.name: kwargs.pop(p.name) for p in GRID_PARAMETERS}
        return command(config=grid_config(**grid), **kwargs)

    keyword = inspect.Parameter.KEYWORD_ONLY
    wrapper.__signature__ = inspect.Signature([p.replace(kind=keyword) for p in (*GRID_PARAMETERS, *own)])
    wrapper.__annotations__ = {p.name: p.annotation for p in wrapper.__signature__.parameters.values()}
    del wrapper.__wrapped__
    return wrapper


@app.command("run", epilog=FIELDS)
@with_grid
def run_grid(
    config: BenchConfig,
    executor: str = typer.Option("local", "--executor",
                                 help="local: one group of seeds after another here; ray: as Ray tasks."),
    address: Optional[str] = typer.Option(
        None, "--address", help="With --executor ray: a Ray cluster's head, HOST:6379 (default: a local instance)."),
    retries: Optional[int] = typer.Option(
        None, "--retries", min=0, max=100,
        help=f"With --executor ray: reruns of a task whose worker died (default {RAY_DEFAULTS.retries})."),
    cpus_per_task: Optional[int] = typer.Option(
        None, "--cpus-per-task", min=1, max=1024,
        help=f"With --executor ray: CPUs each task reserves (default {RAY_DEFAULTS.cpus_per_task})."),
    gpus_per_task: Optional[float] = typer.Option(
        None, "--gpus-per-task", min=0.0, max=64.0,
        help="With --executor ray: GPUs each edit and learner task reserves (default 1 where the cluster has GPUs)."),
    priors_only: bool = typer.Option(False, "--priors-only",
                                     help="Train only the priors the grid's edits read (here), and stop."),
) -> None:
    """Compute every cell of the grid (env x target x gap x column x algo x seed) whose result is not
    stored under its current key, or was trained on data its data cell no longer records."""
    from xted.pipelines.bench.run import CellsFailed, run_bench

    ray = _ray_config(executor, address=address, retries=retries, cpus_per_task=cpus_per_task,
                      gpus_per_task=gpus_per_task)
    if priors_only and ray is not None:
        raise InputError("--priors-only trains the priors here: leave out --executor ray")
    try:
        computed = run_bench(config, echo=typer.echo, ray=ray, priors_only=priors_only)
    except CellsFailed as err:
        typer.echo(f"bench: {len(err.computed)} cells computed; results in {config.store}")
        for name, why in err.failed:
            typer.echo(f"bench: failed: {name}: {why}", err=True)
        typer.echo(f"xted: error: {len(err.failed)} cells failed (rerun to retry them)", err=True)
        raise typer.Exit(1) from None
    typer.echo(f"bench: {len(computed)} cells computed; results in {config.store}")


@app.command("report", epilog=FIELDS)
@with_grid
def report_grid(
    config: BenchConfig,
    as_json: bool = typer.Option(
        False, "--json", help="Print {\"rows\": [...], \"aggregate\": [...], \"cost\": [...]}."),
    png: Optional[Path] = typer.Option(None, "--png", help="Also draw the table as grouped bars."),
    edit_quality: List[Path] = typer.Option(
        [], "--edit-quality", help="Also the edit-quality table of these JSON-lines files "
        "(benchmarks/edit_quality.py --out), rows of the grid's envs and gaps, checked against the edit targets."),
    curves: bool = typer.Option(False, "--curves", help="Also print each row's learning curve "
                                "(mean ± std over seeds at every evaluation)."),
    paper: bool = typer.Option(False, "--paper", help="Under each line of the table the paper's cells "
                               "(its Tables 1 and 2, IQL), and the paper's totals over the same rows."),
    compact: bool = typer.Option(False, "--compact", help="The table one line per task, each cell "
                                 "mean ± std [95% interval] (the paper's mean), as README and BENCHMARKS.md show it; "
                                 "no gains, totals or paper lines."),
    cost: bool = typer.Option(False, "--cost", help="Also print the wall-clock hours each group of "
                              "seeds, edit, oracle and bench-trained prior took (the JSON always has them)."),
) -> None:
    """Print the grid's table from the stored results (mean ± std [95% interval] per row, the gain
    against Tgt, the aggregates over tasks); computes nothing."""
    from xted.pipelines.bench.edit_quality import checked
    from xted.pipelines.bench.edit_quality import markdown as edit_quality_markdown
    from xted.pipelines.bench.edit_quality import read_rows as edit_quality_rows
    from xted.pipelines.bench.grid import plan
    from xted.pipelines.bench.report import (aggregate, aggregate_markdown, compact_markdown, cost_markdown, cost_rows,
                                             curves_markdown, markdown, table_rows)

    if png is not None:
        from xted.viz.plots import check_png_path

        check_png_path(png)
    grid = plan(config)
    rows = table_rows(grid)
    quality = [row for row in edit_quality_rows(edit_quality) if row["env"] in config.envs and row["gap"] in config.gaps]
    if edit_quality and not quality:
        raise InputError(f"--edit-quality: no rows of envs {_joined(config.envs)} and gaps {_joined(config.gaps)}")
    if as_json:
        typer.echo(json.dumps({"rows": rows, "aggregate": aggregate(rows), "cost": cost_rows(grid),
                               **({"edit_quality": [{**row, "targets": checked(row)} for row in quality]}
                                  if edit_quality else {})}))
    else:
        sections = [compact_markdown(rows) if compact else markdown(rows, paper), aggregate_markdown(rows),
                    curves_markdown(rows) if curves else "",
                    cost_markdown(cost_rows(grid)) if cost else "",
                    edit_quality_markdown(quality) if quality else ""]
        typer.echo("\n\n".join(section for section in sections if section))
    if png is not None:
        from xted.viz.plots import save_png, table_figure

        save_png(table_figure(rows), png)


@app.command("refresh")
def refresh_documents(
    documents: List[Path] = typer.Argument(..., help="Markdown files holding report blocks."),
) -> None:
    """Rewrite every report block of these markdown files from the stored results: the lines between
    `<!-- xted bench report OPTIONS -->` and `<!-- end of the report -->` become what `xted bench report
    OPTIONS` prints (run from where those options' --store is found). Computes nothing; every block is
    rendered before any file is written, and a file whose blocks did not change is left untouched."""
    from xted.atomic import atomic_path
    from xted.pipelines.bench.documents import refreshed

    updates = []
    for document in documents:
        if not document.is_file():
            raise InputError(f"{document}: no such file")
        try:
            text = document.read_text()
        except (OSError, UnicodeDecodeError) as err:
            raise InputError(f"cannot read {document}: {err}") from None
        updates.append((document, text, *refreshed(text, str(document), _report_markdown)))
    for document, text, new_text, count in updates:
        if new_text != text:
            with atomic_path(document) as tmp:
                tmp.write_text(new_text)
        typer.echo(f"{document}: {count} report block{'s' if count != 1 else ''} "
                   f"{'refreshed' if new_text != text else 'unchanged'}")


def _report_markdown(options: tuple[str, ...]) -> str:
    """What ``xted bench report OPTIONS`` prints."""
    report = typer.main.get_command(app).commands["report"]
    printed = io.StringIO()
    try:
        with contextlib.redirect_stdout(printed):
            report.main(list(options), prog_name="xted bench report", standalone_mode=False)
    except typer.TyperException as err:  # a usage error of the block's options
        raise InputError(str(err)) from None
    return printed.getvalue()


@app.command("prune", epilog=FIELDS)
@with_grid
def prune_store(
    config: BenchConfig,
    remove: bool = typer.Option(False, "--remove", help="Delete the files listed (default: list them only)."),
) -> None:
    """List the store's result files that match no cell of the grid these options name (stale: of
    settings no longer planned, or of inputs since changed); --remove deletes them. Name every grid
    whose results you keep, e.g. --targets medium-replay,medium,medium-expert --algos iql,td3bc
    --columns with every column you run."""
    from xted.pipelines.bench.grid import plan
    from xted.pipelines.bench.store import stale_files

    stale = stale_files(config.store, plan(config).cells())
    for path in stale:
        if remove:
            path.unlink()
        typer.echo(f"{'removed' if remove else 'stale'}: {path}")
    typer.echo(f"bench: {len(stale)} stored files match no cell of this grid" + ("; removed" if remove and stale
                                                                                   else ""))


def _ray_config(executor: str, **given) -> RayConfig | None:
    """The Ray settings for ``--executor ray``; None for the local executor, which takes none of them."""
    if executor not in ("local", "ray"):
        raise InputError(f"--executor {executor!r}: expected local or ray")
    options = {name: value for name, value in given.items() if value is not None}
    flags = ", ".join("--" + name.replace("_", "-") for name in options)
    if executor == "local":
        if options:
            raise InputError(f"{flags}: only with --executor ray")
        return None
    return RayConfig(**options)
