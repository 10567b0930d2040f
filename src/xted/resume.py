"""One rule for every resumable command: a run folder records a fingerprint of what the run is
(its inputs' hashes and its settings); resuming with the same fingerprint continues, with another
one is refused, naming each difference. A recorded fingerprint is never overwritten on resume."""

from __future__ import annotations

import json
import shutil
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from xted.atomic import atomic_path
from xted.errors import InputError
from xted.jsonfiles import read_json


def as_json(value: Any) -> Any:
    """``value`` as it reads back from JSON (tuples become lists), so fingerprints compare equal."""
    return json.loads(json.dumps(value))


def differences(old: Any, new: Any, prefix: str = "") -> list[tuple[str, Any, Any]]:
    """``(dotted key, old, new)`` for every leaf that differs between two JSON-like values."""
    if isinstance(old, Mapping) and isinstance(new, Mapping):
        found = []
        for key in sorted(set(old) | set(new), key=str):
            found += differences(old.get(key), new.get(key), f"{prefix}{key}.")
        return found
    return [] if old == new else [(prefix.rstrip("."), old, new)]


def check_same_run(where: str | Path, recorded: Mapping | None, fingerprint: Mapping) -> None:
    """Refuse to resume ``where`` when its ``recorded`` fingerprint is not ``fingerprint``."""
    if recorded is None:
        return
    found = differences(as_json(recorded), as_json(fingerprint))
    if found:
        detail = "; ".join(f"{key}: {_short(old)} -> {_short(new)}" for key, old, new in found)
        raise InputError(f"{where} holds another run ({detail}); resume with the same inputs and settings, "
                         f"use another output folder, or pass --force to start afresh")


def resume_or_record(path: str | Path, fingerprint: Mapping) -> None:
    """Check ``fingerprint`` against the JSON file ``path`` if it exists, else write it there."""
    path = Path(path)
    if path.exists():
        check_same_run(path.parent, read_json(path, "unreadable run record"), fingerprint)
        return
    with atomic_path(path, ".json") as tmp:
        tmp.write_text(json.dumps(as_json(fingerprint), indent=1))


def discard_run(run_dir: str | Path, markers: tuple[str, ...]) -> None:
    """Delete a previous run's folder so that a run starts afresh (``--force``). Only a folder that
    holds one of the run's marker files (glob patterns) or nothing at all is deleted; any other is
    refused, so that a mistyped ``--out`` never deletes unrelated files."""
    run_dir = Path(run_dir)
    if not run_dir.exists():
        return
    if not run_dir.is_dir():
        raise InputError(f"--force: {run_dir} is a file, not a run folder")
    contents = list(run_dir.iterdir())
    if contents and not any(next(run_dir.glob(marker), None) for marker in markers):
        raise InputError(f"--force: {run_dir} holds no run of this command (none of {', '.join(markers)}); "
                         f"refusing to delete it")
    shutil.rmtree(run_dir)


def _short(value: Any) -> str:
    text = json.dumps(value)
    return text if len(text) <= 24 else text[:10] + "..." + text[-8:]
