"""Where a target env ends an episode, read off the observation it steps into: what an edited
transition's terminal flag must say. Gymnasium's v5 rules with their default ranges; observations
begin with the torso height (column 0; :mod:`xted.envs.layout`), then for the planar bodies its angle."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from xted.envs.make import HEALTHY_Z

Termination = Callable[[np.ndarray], np.ndarray]  # next observations [N, d] -> terminal [N] (bool)

WALKER_HEALTHY_ANGLE = (-1.0, 1.0)
HOPPER_HEALTHY_ANGLE, HOPPER_HEALTHY_STATE = (-0.2, 0.2), 100.0


def _never(next_observations: np.ndarray) -> np.ndarray:
    return np.zeros(len(next_observations), bool)


def _walker2d(next_observations: np.ndarray) -> np.ndarray:
    z, angle = next_observations[:, 0], next_observations[:, 1]
    healthy = (HEALTHY_Z["walker2d"][0] < z) & (z < HEALTHY_Z["walker2d"][1])
    healthy &= (WALKER_HEALTHY_ANGLE[0] < angle) & (angle < WALKER_HEALTHY_ANGLE[1])
    return ~healthy


def _hopper(next_observations: np.ndarray) -> np.ndarray:
    z, angle = next_observations[:, 0], next_observations[:, 1]
    healthy = np.all(np.abs(next_observations[:, 1:]) < HOPPER_HEALTHY_STATE, axis=1) & (z > HEALTHY_Z["hopper"][0])
    healthy &= (HOPPER_HEALTHY_ANGLE[0] < angle) & (angle < HOPPER_HEALTHY_ANGLE[1])
    return ~healthy


def _ant(next_observations: np.ndarray) -> np.ndarray:
    z = next_observations[:, 0]
    healthy = np.all(np.isfinite(next_observations), axis=1) & (HEALTHY_Z["ant"][0] <= z) & (z <= HEALTHY_Z["ant"][1])
    return ~healthy


_RULES: dict[str, Termination] = {"halfcheetah": _never, "walker2d": _walker2d, "hopper": _hopper, "ant": _ant}


def termination(env: str | None) -> Termination | None:
    """``env``'s termination rule (``halfcheetah``, ``walker2d``, ``hopper``, ``ant``; Gymnasium ids too), or None."""
    if env is None:
        return None
    name = env.lower().split("-")[0].replace("_", "")
    return _RULES.get(name)
