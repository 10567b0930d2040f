"""Claims on cells, so that two ``xted bench`` processes on one store never compute the same cell.

A process claims a group of seeds (or a data cell) by creating ``STORE/.claims/NAME.claim``
exclusively (``O_EXCL``: of two processes exactly one succeeds), holding its host, pid and start
time, and deletes it when the work ends, however it ends. A claim of a process that is gone (same
host, pid not running) is stale and taken over; a claim from another host is honoured until it is
deleted by hand (its file names the host and pid).
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
import time
from collections.abc import Iterator
from pathlib import Path

CLAIMS = ".claims"


def claim_path(store: str | Path, name: str) -> Path:
    return Path(store) / CLAIMS / f"{name}.claim"


def holder(path: Path) -> dict | None:
    """Who holds the claim at ``path``: ``{"host", "pid", "since"}``; None where nobody (or the
    holder is gone, in which case the stale claim is removed)."""
    try:
        record = json.loads(path.read_text())
    except FileNotFoundError:
        return None
    except (OSError, json.JSONDecodeError):
        record = {}  # a claim being written this instant, or a torn one: treat as held
    if record.get("host") == socket.gethostname() and not _running(record.get("pid")):
        with contextlib.suppress(FileNotFoundError):
            path.unlink()
        return None
    return record


def _running(pid) -> bool:
    if not isinstance(pid, int):
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


@contextlib.contextmanager
def claim(store: str | Path, name: str) -> Iterator[bool]:
    """Claim ``name`` for this process: yields True where it holds the claim (released on exit),
    False where another live process holds it."""
    path = claim_path(store, name)
    path.parent.mkdir(parents=True, exist_ok=True)
    record = {"host": socket.gethostname(), "pid": os.getpid(), "since": time.time()}
    for _ in range(2):  # a second try after removing a stale claim
        try:
            descriptor = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            if holder(path) is not None:
                yield False
                return
            continue
        with os.fdopen(descriptor, "w") as handle:
            json.dump(record, handle)
        try:
            yield True
        finally:
            with contextlib.suppress(FileNotFoundError):
                path.unlink()
        return
    yield False


def wait_for_release(store: str | Path, name: str, poll_seconds: float = 5.0) -> None:
    """Block until nobody holds the claim ``name`` (its holder finished, or is gone)."""
    path = claim_path(store, name)
    while holder(path) is not None:
        time.sleep(poll_seconds)
