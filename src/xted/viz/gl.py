"""Headless OpenGL for MuJoCo: EGL where the machine offers it, else OSMesa.

``import mujoco`` binds a default context class from ``MUJOCO_GL``, and PyOpenGL fixes its platform
when it is first imported, so one process cannot fall back to OSMesa after a failed EGL attempt.
Each candidate is therefore tried in a child process; the first that makes a context is written
to ``MUJOCO_GL`` (for this process and its children) and its context class is used here. A
``MUJOCO_GL`` set by the user is honoured, and must be one of the two.
"""

from __future__ import annotations

import functools
import importlib
import os
import subprocess
import sys

from xted.errors import InputError

BACKENDS = ("egl", "osmesa")
_PROBE = "from mujoco.{0} import GLContext; c = GLContext(16, 16); c.make_current(); c.free()"


def probe(backend: str) -> str | None:
    """None if ``backend`` makes an OpenGL context in a fresh process, else why not (one line)."""
    env = {**os.environ, "MUJOCO_GL": backend}
    env.pop("PYOPENGL_PLATFORM", None)
    try:
        result = subprocess.run([sys.executable, "-c", _PROBE.format(backend)], env=env, capture_output=True,
                                text=True, timeout=120)
    except subprocess.TimeoutExpired:
        return "timed out making a context"
    if result.returncode == 0:
        return None
    lines = [line for line in result.stderr.strip().splitlines() if line.strip()]
    return lines[-1] if lines else f"exit code {result.returncode}"


@functools.cache
def gl_context_class() -> type:
    """The ``GLContext`` class of the headless backend this machine offers (see the module doc)."""
    requested = os.environ.get("MUJOCO_GL", "").strip().lower()
    if requested and requested not in BACKENDS:
        raise InputError(f"MUJOCO_GL={requested}: rendering is headless, with egl or osmesa; set one of them "
                         f"or unset MUJOCO_GL to choose automatically")
    failures = {}
    for backend in (requested,) if requested else BACKENDS:
        reason = probe(backend)
        if reason is None:
            os.environ["MUJOCO_GL"] = backend
            try:
                return importlib.import_module(f"mujoco.{backend}").GLContext
            except (ImportError, RuntimeError, AttributeError) as err:
                reason = f"{type(err).__name__}: {err}"
        failures[backend] = reason
    tried = "; ".join(f"{backend}: {reason}" for backend, reason in failures.items())
    raise InputError(f"no headless OpenGL for MuJoCo ({tried}). Install EGL (libegl1, with a GPU driver or Mesa) "
                     f"or OSMesa (libosmesa6), or set MUJOCO_GL to a backend that works")
