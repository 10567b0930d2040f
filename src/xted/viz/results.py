"""The result files ``xted plot`` reads, checked: rows of the benchmarks and training runs.

- ``benchmarks/edit_quality.py --out FILE``: one JSON object per line, per gap and kappa;
- ``xted bench report --json``: ``{"rows": [...]}``, one row per env, target, gap, column and algo;
- a training run, by the files in its folder: ``log.csv`` (a prior: ``xted train``),
  ``evals.csv`` (an online run: ``xted online train``) or ``seed_*.json`` (offline policies:
  ``xted policy --out``); a copy of a ``log.csv`` or ``evals.csv`` is recognised by its columns.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math
from pathlib import Path

import numpy as np

from xted.errors import InputError
from xted.jsonfiles import read_json_rows

EDIT_QUALITY_FIELDS = ("gap", "kappa", "sim_source", "sim_edited", "floor")
BENCH_FIELDS = ("env", "target", "gap", "column", "algo", "mean", "std", "n_seeds")
RUN_KINDS = ("prior", "online", "offline")


def read_edit_quality(path: str | Path) -> list[dict]:
    return read_json_rows(path, EDIT_QUALITY_FIELDS, "benchmarks/edit_quality.py --out")


def read_bench_rows(path: str | Path) -> list[dict]:
    """The rows of a file ``xted bench report --json`` wrote."""
    path = Path(path)
    what = "xted bench report --json"
    if not path.is_file():
        raise InputError(f"{path}: no such file (expected {what})")
    try:
        rows = json.loads(path.read_text())["rows"]
    except (OSError, json.JSONDecodeError, KeyError, TypeError) as err:
        raise InputError(f"{path}: not the output of {what} ({type(err).__name__}: {err})") from None
    if not isinstance(rows, list) or not rows:
        raise InputError(f"{path}: no rows of {what}")
    for number, row in enumerate(rows):
        missing = [field for field in BENCH_FIELDS if not isinstance(row, dict) or field not in row]
        if missing:
            raise InputError(f"{path}: row {number} of {what} needs {', '.join(missing)}")
    return rows


@dataclasses.dataclass(frozen=True)
class Curve:
    label: str
    x: np.ndarray
    y: np.ndarray
    spread: np.ndarray | None = None  # +- band around y (the evaluation episodes' std)


@dataclasses.dataclass(frozen=True)
class RunCurves:
    kind: str  # one of RUN_KINDS
    name: str
    curves: list[Curve]


def read_run(path: str | Path) -> RunCurves:
    """A run folder (or a copy of its ``log.csv`` / ``evals.csv``, or one ``seed_N.json``) as curves."""
    path = Path(path)
    if path.is_dir():
        found = {"prior": (path / "log.csv").is_file(), "online": (path / "evals.csv").is_file(),
                 "offline": any(path.glob("seed_*.json"))}
        kinds = [kind for kind in RUN_KINDS if found[kind]]
        if len(kinds) != 1:
            found_text = " and ".join(kinds) if kinds else "none of them"
            raise InputError(f"{path}: expected one of log.csv (a prior), evals.csv (an online run) or seed_*.json "
                             f"(offline policies), found {found_text}")
        files = {"prior": [path / "log.csv"], "online": [path / "evals.csv"],
                 "offline": sorted(path.glob("seed_*.json"))}[kinds[0]]
        return _read_kind(kinds[0], path.name, files)
    if not path.is_file():
        raise InputError(f"{path}: no such run folder or file")
    if path.suffix == ".json":
        return _read_kind("offline", path.stem, [path])
    if path.suffix == ".csv":
        with path.open() as f:
            header = next(csv.reader(f), [])
        kind = "prior" if "loss" in header else "online" if "return_mean" in header else None
        if kind is None:
            raise InputError(f"{path}: columns {header} are neither a prior's log.csv (step, loss) nor an online "
                             f"run's evals.csv (step, return_mean)")
        return _read_kind(kind, path.stem, [path])
    raise InputError(f"{path}: expected a run folder, a .csv or a seed_N.json")


def _read_kind(kind: str, name: str, files: list[Path]) -> RunCurves:
    try:
        return RunCurves(kind, name, _read_curves(kind, files))
    except InputError:
        raise
    except ValueError as err:  # a value that is not a number
        raise InputError(f"{files[0]}: unreadable {kind} run ({err})") from None


def _read_curves(kind: str, files: list[Path]) -> list[Curve]:
    if kind == "prior":
        from xted.diffusion.checkpoint import read_log

        rows = _checked(files[0], read_log(files[0], math.inf), ("step", "loss"))
        curves = [Curve("loss", _column(rows, "step"), _column(rows, "loss"))]
    elif kind == "online":
        from xted.rl.run_folder import read_evals

        rows = _checked(files[0], read_evals(files[0]), ("step", "return_mean"))
        spread = _column(rows, "return_std") if "return_std" in rows[0] else None
        curves = [Curve("return", _column(rows, "step"), _column(rows, "return_mean"), spread)]
    else:
        curves = [_seed_curve(file) for file in files]
    return curves


def _seed_curve(file: Path) -> Curve:
    try:
        result = json.loads(file.read_text())
        evals = result["evals"]
        label = f"seed {result['seed']}"
    except (OSError, json.JSONDecodeError, KeyError, TypeError) as err:
        raise InputError(f"{file}: not an offline policy result with evals ({type(err).__name__}: {err})") from None
    rows = _checked(file, evals, ("step", "normalized_score"))
    return Curve(label, _column(rows, "step"), _column(rows, "normalized_score"))


def _checked(file: Path, rows: list[dict], fields: tuple[str, ...]) -> list[dict]:
    if not rows:
        raise InputError(f"{file}: no rows")
    missing = [field for field in fields if field not in rows[0]]
    if missing:
        raise InputError(f"{file}: rows need {', '.join(missing)}")
    return rows


def _column(rows: list[dict], field: str) -> np.ndarray:
    return np.array([float(row[field]) for row in rows])
