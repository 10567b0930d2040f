"""A user's own dynamics: a step function ``f(observations [N, obs_dim], actions [N, act_dim]) ->
next observations [N, obs_dim]`` (their simulator, a model of their robot), for envs xted does not
simulate. It measures data as a simulator replay does (:func:`step_function_error`) and projects
edits (``Prior.edit(dynamics=f)``). On the command line it is named ``module:function`` (a module on
the Python path) or ``path/to/file.py:function``."""

from __future__ import annotations

import importlib
import re
import types
from collections.abc import Callable
from pathlib import Path

import numpy as np

from xted.data import Dataset
from xted.envs.dynamics import DynamicsError
from xted.errors import InputError

StepFunction = Callable[[np.ndarray, np.ndarray], np.ndarray]

_SPEC = re.compile(r"^(?P<module>[A-Za-z_][\w.]*|.+\.py):(?P<function>[A-Za-z_]\w*)$")
_NOT_MODULES = ("minari",)  # ``minari:ID`` names a dataset


def is_step_function_spec(text: str) -> bool:
    """Whether ``text`` reads ``module:function`` or ``file.py:function`` (not ``minari:ID``)."""
    match = _SPEC.match(text)
    return match is not None and match["module"] not in _NOT_MODULES


def load_step_function(spec: str) -> StepFunction:
    """The function ``spec`` names; InputError where the module or file, or the function in it, is
    missing or is not callable."""
    match = _SPEC.match(spec)
    if match is None:
        raise InputError(f"step function {spec!r}: name it module:function or path/to/file.py:function")
    module_name, function_name = match["module"], match["function"]
    if module_name.endswith(".py"):
        path = Path(module_name)
        if not path.is_file():
            raise InputError(f"step function {spec!r}: no file {path}")
        module = types.ModuleType(path.stem)  # run as is: no bytecode cache written beside the user's file
        module.__file__ = str(path)
        exec(compile(path.read_text(), str(path), "exec"), module.__dict__)
    else:
        try:
            module = importlib.import_module(module_name)
        except ImportError as err:
            raise InputError(f"step function {spec!r}: cannot import {module_name} ({err})") from None
    function = getattr(module, function_name, None)
    if not callable(function):
        raise InputError(f"step function {spec!r}: {module_name} has no function {function_name}")
    return function


def predicted_next_observations(step: StepFunction, observations: np.ndarray, actions: np.ndarray) -> np.ndarray:
    """``step`` applied to a batch, checked to return one next observation per row."""
    predicted = np.asarray(step(observations, actions), dtype=np.float64)
    if predicted.shape != observations.shape:
        raise InputError(f"the step function returned shape {predicted.shape} for {len(observations)} observations "
                         f"of {observations.shape[1]} features: it must return next observations {observations.shape}")
    return predicted


def step_function_error(step: StepFunction, data: Dataset) -> DynamicsError:
    """One-step error of ``data``'s next observations against ``step``'s, as a simulator replay's."""
    observations = np.asarray(data.observations, np.float64)
    predicted = predicted_next_observations(step, observations, np.asarray(data.actions, np.float64))
    return DynamicsError.from_differences(predicted - data.require_next_observations())
