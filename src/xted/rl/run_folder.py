"""The files of an online run folder (``xted online train``) that readers need without JAX: the
evaluation log and the actor checkpoints' names."""

from __future__ import annotations

import csv
from pathlib import Path

from xted.atomic import atomic_path


def read_evals(run: str | Path) -> list[dict]:
    """The evaluation rows of a run folder (or of an ``evals.csv`` copied out of one)."""
    path = Path(run) if Path(run).suffix == ".csv" else Path(run) / "evals.csv"
    if not path.exists():
        return []
    with path.open() as f:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]


def write_evals(run_dir: Path, rows: list[dict]) -> None:
    with atomic_path(run_dir / "evals.csv") as tmp, tmp.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


def actor_checkpoint(run_dir: str | Path, step: int) -> Path:
    return Path(run_dir) / "checkpoints" / f"actor_{int(step):07d}.msgpack"
