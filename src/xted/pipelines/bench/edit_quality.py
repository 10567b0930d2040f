"""The edit-quality table of ``xted bench report --edit-quality``: rows written by
``benchmarks/edit_quality.py --out`` (one JSON line per env x gap x kappa), each checked against the
bench's edit targets."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from pathlib import Path

from xted.diffusion.config import EditConfig
from xted.jsonfiles import read_json_rows

NEEDED = ("env", "gap", "kappa", "sim_source", "sim_edited", "proxy_source", "proxy_edited", "floor", "content")

# name: (what it asks, whether a row is held to it, whether the row meets it)
TARGETS = {
    "large gap halved": (
        "edited <= 50% of source where the source's simulator error exceeds twice the floor",
        lambda row: row["sim_source"] > 2 * row["floor"]["sim"],
        lambda row: row["sim_edited"] <= 0.5 * row["sim_source"]),
    "lands at the floor": (
        "edited simulator error <= 1.5x the floor (the edit of held-out target data)",
        lambda row: True,
        lambda row: row["sim_edited"] <= 1.5 * row["floor"]["sim"]),
    "proxy": (
        "the paper's proxy: edited <= 55% of source",
        lambda row: True,
        lambda row: row["proxy_edited"] <= 0.55 * row["proxy_source"]),
    "content kept": (
        "forward-velocity correlation with the source >= 0.6 and >= 3x the mismatched pairs'",
        lambda row: True,
        lambda row: (row["content"]["matched"]["forward_velocity_correlation"] >= 0.6
                     and row["content"]["matched"]["forward_velocity_correlation"]
                     >= 3 * row["content"]["mismatched"]["forward_velocity_correlation"])),
}


def read_rows(paths: Sequence[Path]) -> list[dict]:
    """Every row of the given JSON-lines files, in order; a missing file or malformed row is an InputError."""
    return [row for path in paths for row in read_json_rows(path, NEEDED, "benchmarks/edit_quality.py --out")]


def edit_label(row: dict) -> str:
    """The row's edit settings that differ from today's EditConfig defaults (kappa and seed apart),
    or "default"; a row written before ``edit_config`` was recorded shows its ``--edit`` overrides."""
    if "edit_config" not in row:
        return " ".join(row.get("edit") or []) or "default"
    defaults = dataclasses.asdict(EditConfig())
    recorded = {"guard": False, **row["edit_config"]}  # rows from before the guard are plain edits
    changed = [f"{key}={value}" for key, value in recorded.items()
               if key not in ("kappa", "seed", "dynamics_weight") and key in defaults and value != defaults[key]]
    if row.get("project_dynamics"):  # the weight matters only with a dynamics model
        changed.append(f"project-dynamics w={row['edit_config']['dynamics_weight']}")
    return " ".join(changed) or "default"


def checked(row: dict) -> dict[str, bool | None]:
    """Each target's verdict on ``row``: met, not met, or None where it does not apply."""
    return {name: (meets(row) if applies(row) else None) for name, (_, applies, meets) in TARGETS.items()}


def markdown(rows: Sequence[dict]) -> str:
    """One line per row with its ratios and its verdicts; then each target's count and what it asks.
    The floor is the same edit of held-out target data the prior never saw."""
    header = ["env", "gap", "kappa", "edit", "sim source -> edited (ratio)", "edited / floor",
              "floor sim / proxy", "proxy source -> edited (ratio)", "fwd-velocity corr matched / mismatched",
              *TARGETS]
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    verdicts = [checked(row) for row in rows]
    for row, verdict in zip(rows, verdicts):
        correlation = row["content"]["matched"]["forward_velocity_correlation"]
        chance = row["content"]["mismatched"]["forward_velocity_correlation"]
        cells = [
            row["env"], row["gap"], f"{row['kappa']:g}", edit_label(row),
            f"{row['sim_source']:.3f} -> {row['sim_edited']:.3f} ({row['sim_edited'] / row['sim_source']:.2f})",
            f"{row['sim_edited'] / row['floor']['sim']:.2f}",
            f"{row['floor']['sim']:.3f} / {row['floor']['proxy']:.3f}",
            f"{row['proxy_source']:.3f} -> {row['proxy_edited']:.3f} ({row['proxy_edited'] / row['proxy_source']:.2f})",
            f"{correlation:.2f} / {chance:.2f}",
            *("n/a" if met is None else "met" if met else "not met" for met in verdict.values()),
        ]
        out.append("| " + " | ".join(cells) + " |")
    out.append("")
    for name, (asks, _, _) in TARGETS.items():
        held = [verdict[name] for verdict in verdicts if verdict[name] is not None]
        out.append(f"- {name}: {asks}: met by {sum(held)} of {len(held)} rows")
    return "\n".join(out)
