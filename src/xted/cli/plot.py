"""``xted plot``: pictures of edits, gaps and runs, each written as a PNG."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import numpy as np
import typer

from xted.envs.domains import KNOWN_ENVS
from xted.errors import InputError
from xted.viz.config import PlotDefaults

app = typer.Typer(help="Pictures of edits, gaps and runs, each written as a PNG (replaced if it exists).",
                  no_args_is_help=True)

OUT_HELP = "PNG file to write."


def _parse_dims(text: str) -> list[int]:
    try:
        return [int(part) for part in text.split(",") if part.strip()]
    except ValueError:
        raise InputError(f"--dims takes state dims as integers, e.g. 0,2,8; got {text!r}") from None


@app.command("dynamics")
def dynamics(
    results: Path = typer.Argument(..., help="The rows benchmarks/edit_quality.py --out FILE writes (JSON lines)."),
    out: Path = typer.Option(..., "--out", help=OUT_HELP),
) -> None:
    """One-step dynamics error per gap: source, edited source and the floor (the same edit of
    held-out target data), replayed in the target simulator and, beside it, by the learned proxy.

    Input: the file "python benchmarks/edit_quality.py ... --out FILE" appends to, one JSON
    object per gap and kappa (keys gap, kappa, sim_source, sim_edited, floor.sim; proxy_source,
    proxy_edited, floor.proxy for the proxy's panel)."""
    from xted.viz.plots import check_png_path, dynamics_figure, save_png
    from xted.viz.results import read_edit_quality

    check_png_path(out)
    typer.echo(save_png(dynamics_figure(read_edit_quality(results)), out))


@app.command("spectrum")
def spectrum(
    source: str = typer.Argument(..., help="Source dataset (path or shipped name)."),
    edited: str = typer.Argument(..., help="Its edit (same episodes)."),
    out: Path = typer.Option(..., "--out", help=OUT_HELP),
    segment: int = typer.Option(PlotDefaults.segment, "--segment", min=2, help="Steps per FFT segment."),
    cutoff: float = typer.Option(PlotDefaults.cutoff, "--cutoff", min=0.01, max=1.0,
                                 help="Low-frequency band to shade, as a fraction of the Nyquist frequency."),
    target: Optional[str] = typer.Option(None, "--target",
                                         help="Target data (path or shipped name) whose spectrum to draw beside."),
) -> None:
    """FFT magnitude of source against edited states (the paper's frequency analysis): every
    episode cut into aligned segments, each state dim in the source's standard deviations, the
    magnitudes averaged over segments and dims; and their ratio per frequency. With --target, the
    target data's spectrum in the same units too: whether what the edit changed moves toward the
    target's motion (printed for the upper half of the band)."""
    from xted.data import load
    from xted.viz.plots import check_png_path, save_png, spectrum_figure

    check_png_path(out)
    names = (Path(source).stem, Path(edited).stem) + (() if target is None else (Path(target).stem,))
    source_data, edited_data = load(source), load(edited)
    reference = None if target is None else load(target)
    figure = spectrum_figure(source_data, edited_data, segment, cutoff, names, reference)
    typer.echo(save_png(figure, out))
    if reference is not None:
        from xted.analysis.content import mean_spectra

        spectra = mean_spectra(source_data, edited_data, segment, reference)
        upper = spectra["frequency"] > 0.5
        levels = {name: spectra[name][upper].mean(axis=0) for name in ("source", "edited", "reference")}
        closer = np.abs(levels["edited"] - levels["reference"]) < np.abs(levels["source"] - levels["reference"])
        typer.echo(f"above half the Nyquist frequency, mean magnitude: source {levels['source'].mean():.4f}, "
                   f"edited {levels['edited'].mean():.4f}, target {levels['reference'].mean():.4f}; "
                   f"the edit is closer to the target in {int(closer.sum())} of {len(closer)} state dims")


@app.command("trajectory")
def trajectory(
    source: str = typer.Argument(..., help="Source dataset (path or shipped name)."),
    edited: str = typer.Argument(..., help="Its edit (same episodes)."),
    env: str = typer.Option(..., "--env", help=f"{KNOWN_ENVS}."),
    gap: Optional[str] = typer.Option(None, "--gap", help="Domain whose simulator replays the edit (default: target)."),
    episode: int = typer.Option(0, "--episode", help="Episode index (negative counts from the end)."),
    dims: Optional[str] = typer.Option(None, "--dims",
                                       help="State dims, comma-separated (default: root height, a thigh angle and "
                                            "the forward velocity)."),
    steps: int = typer.Option(PlotDefaults.trajectory_steps, "--steps", min=2, help="First N steps of the episode."),
    out: Path = typer.Option(..., "--out", help=OUT_HELP),
) -> None:
    """A few state dims of one episode over time: source, edit, and the domain's simulator stepped
    once from each edited state with its action (where an edit that obeyed those dynamics goes)."""
    from xted.data import load
    from xted.envs import parse_domain
    from xted.viz.plots import check_png_path, save_png, trajectory_figure

    check_png_path(out)
    figure = trajectory_figure(parse_domain(env, gap), load(source), load(edited), episode,
                               None if dims is None else _parse_dims(dims), steps, (Path(source).stem, Path(edited).stem))
    typer.echo(save_png(figure, out))


@app.command("curves")
def curves(
    runs: List[Path] = typer.Argument(..., help="Run folders of one kind (or copies of their log.csv / evals.csv)."),
    out: Path = typer.Option(..., "--out", help=OUT_HELP),
) -> None:
    """Training curves, the kind read from each folder's files: a prior's log.csv (xted train:
    loss against step), an online run's evals.csv (xted online train: return against env steps) or
    offline policies' seed_*.json (xted policy --out: normalised score against updates, per seed)."""
    from xted.viz.plots import check_png_path, curves_figure, save_png
    from xted.viz.results import read_run

    check_png_path(out)
    typer.echo(save_png(curves_figure([read_run(run) for run in runs]), out))


@app.command("table")
def table(
    results: Path = typer.Argument(..., help="What xted bench report --json printed ({\"rows\": [...]})."),
    out: Path = typer.Option(..., "--out", help=OUT_HELP),
) -> None:
    """The paper's Table 1 as grouped bars: per env, target and algorithm, a group per gap and a
    bar per column (Src, Tgt, Tgt+Src, Tgt+Edited, Tgt+Oracle, Tgt+Src DARA, Tgt+Edited DARA): mean and std over
    seeds, each seed a dot. "xted bench report --png FILE" draws the same figure."""
    from xted.viz.plots import check_png_path, save_png, table_figure
    from xted.viz.results import read_bench_rows

    check_png_path(out)
    typer.echo(save_png(table_figure(read_bench_rows(results)), out))
