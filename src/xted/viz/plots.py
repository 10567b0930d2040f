"""Figures of xted's measures and runs, written as PNGs.

Figures are drawn without pyplot (no global state, no display needed): a ``Figure`` saved to
``.png`` renders with Agg. Each ``*_figure`` function takes what it shows and returns the figure.
"""

from __future__ import annotations

import io
import itertools
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from PIL import Image

from xted.analysis.content import check_same_episodes, mean_spectra
from xted.atomic import atomic_path
from xted.data import Dataset
from xted.envs import Domain, simulator
from xted.envs.dynamics import predict_next_observations
from xted.envs.layout import observed_positions, omitted_positions
from xted.errors import InputError
from xted.viz.episode import episode_observations
from xted.viz.results import RunCurves
from xted.viz.state_names import state_names

COLORS = {"source": "tab:gray", "edited": "tab:blue", "floor": "tab:green", "replay": "tab:orange",
          "target": "tab:purple"}
DPI = 100


def check_png_path(path: str | Path) -> Path:
    path = Path(path)
    if path.suffix.lower() != ".png":
        raise InputError(f"{path}: plots are written as .png, got {path.suffix or 'no extension'!r}")
    if path.is_dir():
        raise InputError(f"{path}: is a folder, expected a file path")
    return path


def save_png(figure: Figure, path: str | Path) -> Path:
    """Write ``figure`` atomically to ``path`` (``.png``) in a 256-colour palette: plots of a few
    lines and bars look the same, at a third of the size of matplotlib's RGBA."""
    path = check_png_path(path)
    drawn = io.BytesIO()
    figure.savefig(drawn, format="png", dpi=DPI)
    with Image.open(drawn) as image:
        palette = image.convert("RGB").quantize(colors=256)
    with atomic_path(path, suffix=".png") as tmp:
        palette.save(tmp, format="PNG", optimize=True)
    return path


def dynamics_figure(rows: list[dict]) -> Figure:
    """Per gap (and kappa): one-step dynamics error of source, edit and floor, by the simulator and,
    where the rows have it, by the learned proxy (rows of ``benchmarks/edit_quality.py``)."""
    several_kappas = len({row["kappa"] for row in rows}) > 1
    groups = [row["gap"] + (f"\nkappa {row['kappa']:g}" if several_kappas else "") for row in rows]
    measures = [("sim", "target simulator (truth)")]
    if all("proxy_source" in row and "proxy" in row["floor"] for row in rows):
        measures.append(("proxy", "learned dynamics proxy (the paper's measure)"))
    figure = Figure(figsize=(1.6 + 1.5 * len(rows) * len(measures), 4.2), layout="constrained")
    axes = figure.subplots(1, len(measures), squeeze=False)[0]
    x, width = np.arange(len(rows)), 0.27
    for axis, (key, title) in zip(axes, measures):
        bars = {"source": [row[f"{key}_source"] for row in rows], "edited": [row[f"{key}_edited"] for row in rows],
                "floor": [row["floor"][key] for row in rows]}
        labels = {"source": "source data", "edited": "edited source",
                  "floor": "floor: the edit of held-out target data"}
        for offset, (name, values) in zip((-width, 0.0, width), bars.items()):
            drawn = axis.bar(x + offset, values, width, label=labels[name], color=COLORS[name])
            axis.bar_label(drawn, fmt="%.2f", fontsize=7)
        axis.set_xticks(x, groups)
        axis.set_xlabel("source domain (gap)")
        axis.set_ylabel("one-step MAE (mean |error| over state dims)")
        axis.set_title(title, fontsize=10)
        axis.grid(axis="y", alpha=0.3)
        axis.margins(y=0.12)
    axes[0].legend(fontsize=8, loc="upper left")
    env = rows[0].get("env", "")
    figure.suptitle(f"{env} edits: one-step dynamics error in the target domain".strip())
    return figure


def spectrum_figure(source: Dataset, edited: Dataset, segment: int = 100, cutoff: float = 0.2,
                    names: tuple[str, ...] = ("source", "edited"), reference: Dataset | None = None) -> Figure:
    """FFT magnitude of source and edited states, averaged over aligned segments and state dims,
    and their ratio per frequency (``xted.analysis.content.mean_spectra``); with ``reference`` (the
    target data; ``names[2]``) its spectrum too, in the source's units."""
    spectra = mean_spectra(source, edited, segment, reference)
    frequency = spectra["frequency"]
    shown = ("source", "edited") + (("reference",) if reference is not None else ())
    magnitude = {name: spectra[name].mean(axis=1) for name in shown}
    figure = Figure(figsize=(10, 4), layout="constrained")
    levels, ratio = figure.subplots(1, 2)
    for axis in (levels, ratio):
        axis.axvspan(0, cutoff, color="tab:green", alpha=0.12, label=f"low frequencies (< {cutoff:g})")
        axis.set_xlabel("frequency (fraction of the Nyquist frequency)")
        axis.grid(alpha=0.3)
        axis.set_xlim(0, 1)
    levels.semilogy(frequency, magnitude["source"], color=COLORS["source"], label=names[0])
    levels.semilogy(frequency, magnitude["edited"], color=COLORS["edited"], label=names[1])
    if reference is not None:
        levels.semilogy(frequency, magnitude["reference"], color=COLORS["target"], label=names[2])
    levels.set_ylabel("|FFT| / segment length\n(source std units, mean over state dims)")
    levels.set_title("magnitude spectrum", fontsize=10)
    levels.legend(fontsize=8)
    # The zero-frequency bin is each segment's mean, a level rather than a motion: its ratio is
    # given in the title so that it does not set the scale of the others.
    ratios = magnitude["edited"] / magnitude["source"]
    ratio.plot(frequency[1:], ratios[1:], color=COLORS["edited"])
    if reference is not None:
        ratio.plot(frequency[1:], magnitude["reference"][1:] / magnitude["source"][1:], color=COLORS["target"],
                   label=f"{names[2]} / {names[0]}")
        ratio.plot([], [], color=COLORS["edited"], label=f"{names[1]} / {names[0]}")
        ratio.legend(fontsize=8)
    ratio.axhline(1.0, color="black", linewidth=0.8)
    ratio.set_ylabel("magnitude / source magnitude")
    ratio.set_title(f"what the edit changed, per frequency (mean level: {ratios[0]:.2f})", fontsize=10)
    figure.suptitle(f"State spectra: {spectra['segments']} aligned segments of {segment} steps")
    return figure


def _default_dims(model) -> list[int]:
    """Root height, the first limb joint's angle and the forward velocity."""
    limb = next(j for j in range(model.njnt) if model.jnt_bodyid[j] != model.jnt_bodyid[0])
    return [0, int(model.jnt_qposadr[limb]) - omitted_positions(model), observed_positions(model)]


def trajectory_figure(domain: Domain, source: Dataset, edited: Dataset, episode: int = 0,
                      dims: list[int] | None = None, steps: int = 200,
                      names: tuple[str, str] = ("source", "edited")) -> Figure:
    """A few state dimensions of one episode: source, edit, and ``domain``'s simulator stepped
    once from each edited state with its action (where an edit obeying that domain would go)."""
    check_same_episodes(source, edited)
    model, frame_skip = simulator(domain)
    dim_names = state_names(model)
    dims = dims if dims is not None else _default_dims(model)
    outside = [d for d in dims if not 0 <= d < len(dim_names)]
    if outside or not dims:
        raise InputError(f"dims {outside or dims} are not state dims of {domain.env} (0 to {len(dim_names) - 1})")
    observed = {"source": episode_observations(source, episode)[:steps],
                "edited": episode_observations(edited, episode)[:steps]}
    start = edited.episode_bounds()[episode][0]
    length = len(observed["source"])
    actions = edited.actions[start : start + length]
    replay = predict_next_observations(domain, observed["edited"][:-1].astype(np.float64), actions[:-1])
    time = np.arange(length) * model.opt.timestep * frame_skip
    figure = Figure(figsize=(9, 1.0 + 1.8 * len(dims)), layout="constrained")
    axes = figure.subplots(len(dims), 1, sharex=True, squeeze=False)[:, 0]
    for axis, dim in zip(axes, dims):
        axis.plot(time, observed["source"][:, dim], color=COLORS["source"], label=names[0])
        axis.plot(time, observed["edited"][:, dim], color=COLORS["edited"], label=names[1])
        axis.plot(time[1:], replay[:, dim], color=COLORS["replay"], linestyle="--", linewidth=1.0,
                  label=f"{domain.name} simulator, one step from the edited state")
        name, unit = dim_names[dim]
        axis.set_ylabel(f"{name}\n({unit})", fontsize=9)
        axis.grid(alpha=0.3)
    axes[-1].set_xlabel("time in the episode (s)")
    figure.legend(*axes[0].get_legend_handles_labels(), loc="outside lower center", ncol=3, fontsize=8,
                  frameon=False)
    figure.suptitle(f"{names[0]} and {names[1]}, episode {episode}: the first {length} steps")
    return figure


_RUN_AXES = {
    "prior": ("training step", "denoising loss (MSE of the noise)", "Diffusion prior training"),
    "online": ("environment steps", "return (greedy evaluation, mean ± std)", "Online training"),
    "offline": ("gradient updates", "normalised score (0 random, 100 expert)", "Offline policy training"),
}


def curves_figure(runs: list[RunCurves]) -> Figure:
    """Training curves of runs of one kind, one colour per run (seeds of an offline run share it)."""
    kinds = {run.kind for run in runs}
    if len(kinds) != 1:
        raise InputError(f"runs of one kind can share a plot, got {', '.join(sorted(kinds))}")
    kind = kinds.pop()
    xlabel, ylabel, title = _RUN_AXES[kind]
    figure = Figure(figsize=(7.5, 4.2), layout="constrained")
    axis = figure.subplots()
    for index, run in enumerate(runs):
        color = f"C{index}"
        style = {"marker": "o", "markersize": 3} if max(len(curve.x) for curve in run.curves) < 30 else {}
        if len(run.curves) == 1:
            curve = run.curves[0]
            axis.plot(curve.x, curve.y, color=color, label=run.name, **style)
            if curve.spread is not None:
                axis.fill_between(curve.x, curve.y - curve.spread, curve.y + curve.spread, color=color, alpha=0.15)
            continue
        for curve in run.curves:
            axis.plot(curve.x, curve.y, color=color, alpha=0.35, linewidth=1.0, **style)
        if all(np.array_equal(curve.x, run.curves[0].x) for curve in run.curves):
            mean = np.mean([curve.y for curve in run.curves], axis=0)
            axis.plot(run.curves[0].x, mean, color=color, linewidth=2.2,
                      label=f"{run.name}: mean of {len(run.curves)} seeds (thin: each seed)", **style)
        else:
            axis.plot([], [], color=color, alpha=0.35, label=f"{run.name}: {len(run.curves)} seeds")
    axis.legend(fontsize=8)
    if kind == "prior":
        axis.set_yscale("log")
    axis.set_xlabel(xlabel)
    axis.set_ylabel(ylabel)
    axis.grid(alpha=0.3)
    axis.set_title(title + (f": {runs[0].name}" if len(runs) == 1 else ""))
    return figure


_ALGO_NAMES = {"iql": "IQL", "td3bc": "TD3+BC", "bc": "BC", "dara": "DARA"}
_COLUMN_COLORS = {"Src": "tab:gray", "Tgt": "tab:purple", "Tgt+Src": "tab:olive", "Tgt+Edited": "tab:blue",
                  "Tgt+Oracle": "tab:green", "Tgt+Src DARA": "tab:orange", "Tgt+Edited DARA": "tab:cyan",
                  "Tgt+Guarded": "tab:red", "Tgt+Src IGDF": "tab:brown", "Tgt+Src OTDF": "tab:pink"}
# For the other columns: tab20's lighter shades, none of them a colour above.
_SPARE_COLORS = ("#aec7e8", "#ffbb78", "#98df8a", "#ff9896", "#c5b0d5", "#c49c94", "#f7b6d2", "#c7c7c7", "#dbdb8d",
                 "#9edae5")


def column_colors(columns: list[str]) -> dict[str, str]:
    """A colour per column, each different (up to 10 columns beyond those named above): a named column
    keeps its own wherever it is drawn; the others take spare ones in order."""
    spare = itertools.cycle(_SPARE_COLORS)
    return {column: _COLUMN_COLORS.get(column) or next(spare) for column in columns}


def table_figure(rows: list[dict]) -> Figure:
    """The paper's Table 1 as grouped bars: a panel per env, target and algorithm, a group per gap,
    a bar per column (mean and std over seeds, each seed a dot where the rows list ``scores``).
    ``rows``: those of ``xted bench report --json``; a row without a mean is left out."""
    rows = [{**row, "gap": row["gap"] or "per target"} for row in rows if row.get("mean") is not None]
    if not rows:
        raise InputError("no row holds a score (every cell is missing)")
    panels = list(dict.fromkeys((row["env"], row["target"], row["algo"]) for row in rows))
    gaps = list(dict.fromkeys(row["gap"] for row in rows))
    columns = list(dict.fromkeys(row["column"] for row in rows))
    scores = {(row["env"], row["target"], row["algo"], row["gap"], row["column"]): row for row in rows}
    figure = Figure(figsize=(1.6 + 0.5 * len(gaps) * len(columns) * len(panels), 4.2), layout="constrained")
    axes = figure.subplots(1, len(panels), sharey=True, squeeze=False)[0]
    x, width = np.arange(len(gaps)), 0.8 / len(columns)
    colors = column_colors(columns)
    for axis, panel in zip(axes, panels):
        for number, column in enumerate(columns):
            offset = (number - (len(columns) - 1) / 2) * width
            found = [scores.get((*panel, gap, column)) for gap in gaps]
            means = [np.nan if row is None else row["mean"] for row in found]
            stds = [np.nan if row is None else row["std"] for row in found]
            axis.bar(x + offset, means, width, yerr=stds, capsize=2, label=column,
                     color=colors[column], alpha=0.85)
            for position, row in zip(x + offset, found):
                seeds = [] if row is None else row.get("scores", [])
                axis.plot([position] * len(seeds), seeds, "k.", markersize=3)
        axis.set_xticks(x, gaps)
        axis.set_xlabel("source domain (gap)")
        env, target, algo = panel
        axis.set_title(f"{env} {target}, {_ALGO_NAMES.get(algo, algo)}", fontsize=10)
        axis.grid(axis="y", alpha=0.3)
        axis.axhline(0, color="black", linewidth=0.8)
    with_seeds = any(row.get("scores") for row in rows)
    axes[0].set_ylabel("normalised score, last evaluation\n(mean ± std over seeds" + ("; dots: seeds)" if with_seeds else ")"))
    axes[0].legend(fontsize=8)
    figure.suptitle("Does editing help the learner? Offline RL in the target domain")
    return figure
