"""Where cells' results live: small JSONs in the store (committed), made datasets in the cache (not).

A result's file name says what the cell is and ends in its key's first 12 hex digits; the file
holds the whole key, which a reader checks, so a file of another run is never taken for this one."""

from __future__ import annotations

import json
from pathlib import Path

from xted.atomic import atomic_path
from xted.jsonfiles import read_json
from xted.pipelines.bench.grid import DataCell, LearnerCell

Cell = LearnerCell | DataCell


def result_path(store: str | Path, cell: Cell) -> Path:
    return Path(store) / cell.env / f"{cell.name}.json"


def data_path(cache: str | Path, cell: DataCell) -> Path:
    return Path(cache) / cell.env / f"{cell.name}.npz"


def read_result(store: str | Path, cell: Cell) -> dict | None:
    """The stored result of ``cell``, or None where there is none for its key."""
    path = result_path(store, cell)
    if not path.is_file():
        return None
    result = read_json(path, "unreadable cell result", "remove it to recompute the cell")
    return result if isinstance(result, dict) and result.get("key") == cell.key else None


def write_result(store: str | Path, cell: Cell, result: dict) -> Path:
    path = result_path(store, cell)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path, ".json") as tmp:
        tmp.write_text(json.dumps({**result, "key": cell.key, "inputs": cell.inputs}, indent=1))
    return path


def makes(record: dict) -> list[str]:
    """The fingerprints of every make a data cell's record holds: the first, then each remake that
    came out in other bytes (the same inputs on another machine: XLA's float reductions differ by CPU)."""
    return [record["data_fingerprint"], *(remade["data_fingerprint"] for remade in record.get("remade", ()))]


def trained_on_other_data(store: str | Path, cell: LearnerCell, result: dict) -> bool:
    """Whether a learner's stored result was trained on data that none of its data cells' recorded
    makes is (a data cell whose record was replaced since): such a result is flagged and recomputed."""
    recorded = result.get("training_data")
    for position, ref in enumerate(cell.training):
        if isinstance(ref, DataCell) and recorded is not None:
            made = read_result(store, ref)
            if made is not None and recorded[position] not in makes(made):
                return True
    return False


def current_result(store: str | Path, cell: LearnerCell) -> dict | None:
    """The learner's stored result where it is current: stored under its key and trained on the data
    its data cells record."""
    result = read_result(store, cell)
    return None if result is None or trained_on_other_data(store, cell, result) else result


def stale_files(store: str | Path, cells: list[Cell]) -> list[Path]:
    """The result files under ``store`` that belong to none of ``cells`` (by name, which ends in the
    key's first 12 hex digits): cells of settings no longer planned, or of inputs since changed."""
    current = {f"{cell.name}.json" for cell in cells}
    return sorted(path for path in Path(store).glob("*/*.json") if path.name not in current)
