"""Reading JSON files (the records xted writes, the results it is given), with one kind of error:
it names the file, what the file should hold, and where there is one, the remedy."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from xted.errors import InputError


def read_json(path: str | Path, unreadable: str, remedy: str | None = None) -> Any:
    """The JSON value in ``path``; an unreadable file is an InputError ``PATH: UNREADABLE (why)[; REMEDY]``."""
    try:
        return json.loads(Path(path).read_text())
    except (OSError, json.JSONDecodeError) as err:
        raise InputError(f"{path}: {unreadable} ({err})" + (f"; {remedy}" if remedy else "")) from None


def read_json_rows(path: str | Path, fields: tuple[str, ...], what: str) -> list[dict]:
    """The JSON-object lines of ``path`` that ``what`` wrote (other lines are skipped), each holding
    ``fields``; a missing file, a malformed or incomplete row, or no row at all is an InputError."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such file (expected {what})")
    rows = []
    for number, line in enumerate(path.read_text().splitlines(), start=1):
        if not line.lstrip().startswith("{"):
            continue
        try:
            row = json.loads(line)
        except json.JSONDecodeError as err:
            raise InputError(f"{path}:{number}: not a JSON object ({err.msg})") from None
        missing = [field for field in fields if field not in row]
        if missing:
            raise InputError(f"{path}:{number}: a row of {what} needs {', '.join(missing)}")
        rows.append(row)
    if not rows:
        raise InputError(f"{path}: no rows of {what} (JSON objects, one per line)")
    return rows
