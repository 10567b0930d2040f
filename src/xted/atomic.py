"""Atomic output: write to a temporary sibling, then rename over the target."""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import os
import shutil
import tempfile
from pathlib import Path
from typing import Iterator

from xted.errors import InputError


@contextlib.contextmanager
def atomic_path(target: str | os.PathLike, suffix: str = "") -> Iterator[Path]:
    """Yield a temporary path next to ``target``; rename it to ``target`` on success.

    On an exception the temporary file or folder is removed, so are the folders made for
    ``target``, and ``target`` is untouched. A refusal of the file system (a read-only folder, a
    full disk) becomes an InputError naming ``target``. The temporary name ends with ``suffix``,
    for writers that add or check an extension (``np.savez`` appends ``.npz`` to a name without it).
    """
    target = Path(target)
    missing = _missing_folders(target.parent)
    tmp_path = None
    try:
        for folder in reversed(missing):
            folder.mkdir()
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.tmp-", suffix=suffix, dir=target.parent)
        os.close(fd)
        os.unlink(tmp)
        tmp_path = Path(tmp)
        yield tmp_path
        if target.is_dir() and not target.is_symlink():
            _swap_in_folder(tmp_path, target)
        else:
            os.replace(tmp_path, target)
    except BaseException as err:
        if tmp_path is not None and tmp_path.is_dir():
            shutil.rmtree(tmp_path, ignore_errors=True)
        elif tmp_path is not None and tmp_path.exists():
            tmp_path.unlink()
        for folder in missing:
            with contextlib.suppress(OSError):
                folder.rmdir()
        if isinstance(err, OSError):
            raise InputError(f"cannot write {target}: {err.strerror or err}") from err
        raise


def _missing_folders(folder: Path) -> list[Path]:
    """``folder`` and its ancestors that do not exist yet, innermost first."""
    missing = []
    while not folder.exists() and folder != folder.parent:
        missing.append(folder)
        folder = folder.parent
    return missing


_RENAME_EXCHANGE = 2


def _exchange(a: Path, b: Path) -> bool:
    """Swap two paths in one step (Linux ``renameat2(RENAME_EXCHANGE)``); False where unsupported."""
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c"), use_errno=True)
        renameat2 = libc.renameat2
    except (OSError, AttributeError, TypeError):
        return False
    at_fdcwd = -100
    return renameat2(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), _RENAME_EXCHANGE) == 0


def _swap_in_folder(new: Path, target: Path) -> None:
    """Put folder ``new`` at ``target``, replacing the folder there, so that a crash at any point
    leaves the old or the new folder in place (never neither), then remove the old one."""
    if _exchange(new, target):
        shutil.rmtree(new)
        return
    # Without an atomic exchange the old folder is moved aside first: a crash between the two
    # renames leaves it at the hidden backup name, not deleted.
    backup = new.with_name(new.name + ".old")
    os.replace(target, backup)
    os.replace(new, target)
    shutil.rmtree(backup)
