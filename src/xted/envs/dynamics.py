"""Simulator dynamics error: replay each transition (s, a, s') in a domain's simulator.

Observations of HalfCheetah and Walker2d omit only the root x position, which does not affect
the dynamics, so ``s`` fixes the full simulator state (with x = 0) and one env step from it
under ``a`` gives the true next observation. Walker2d-v5 clips observed velocities to +-10:
a transition whose s or s' has a component at the clip bound does not fix the state exactly
and is excluded (and counted).
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from xted.envs.domains import Domain
from xted.envs.make import observation_velocity_clip, simulator
from xted.errors import InputError

if TYPE_CHECKING:
    from xted.data import Dataset


@dataclasses.dataclass(frozen=True)
class DynamicsError:
    """Per-transition absolute errors (mean over state dims) of replayed transitions."""

    n: int
    excluded_clipped: int
    mae: float
    mse: float
    mae_per_transition: np.ndarray
    mse_per_transition: np.ndarray

    @classmethod
    def from_differences(cls, diff: np.ndarray, excluded_clipped: int = 0) -> DynamicsError:
        """From predicted minus recorded next states ``[N, obs_dim]``."""
        mae_t = np.mean(np.abs(diff), axis=1)
        mse_t = np.mean(diff**2, axis=1)
        n = len(diff)
        return cls(
            n=n,
            excluded_clipped=excluded_clipped,
            mae=float(mae_t.mean()) if n else float("nan"),
            mse=float(mse_t.mean()) if n else float("nan"),
            mae_per_transition=mae_t,
            mse_per_transition=mse_t,
        )

    def summary(self) -> dict:
        quantiles = np.quantile(self.mae_per_transition, [0.1, 0.25, 0.5, 0.75, 0.9]) if self.n else [np.nan] * 5
        return {
            "n": self.n,
            "excluded_clipped": self.excluded_clipped,
            "mae": self.mae,
            "mse": self.mse,
            "mae_quantiles": dict(zip(["p10", "p25", "p50", "p75", "p90"], map(float, quantiles))),
            "mse_median": float(np.median(self.mse_per_transition)) if self.n else float("nan"),
        }


def predict_next_observations(domain: Domain, observations: np.ndarray, actions: np.ndarray) -> np.ndarray:
    """The simulator's next observation for every (s, a), unclipped."""
    return _replay(*simulator(domain), domain, observations, actions)


def _replay(model: mujoco.MjModel, frame_skip: int, domain: Domain, observations: np.ndarray,
            actions: np.ndarray) -> np.ndarray:
    data = mujoco.MjData(model)
    nq, nv = model.nq, model.nv
    if observations.shape[1] != nq - 1 + nv:
        raise InputError(
            f"observations have {observations.shape[1]} dims but {domain.env} states have {nq - 1 + nv}"
        )
    if actions.shape[1] != model.nu:
        raise InputError(f"actions have {actions.shape[1]} dims but {domain.env} has {model.nu} actuators")
    low, high = model.actuator_ctrlrange[:, 0], model.actuator_ctrlrange[:, 1]
    predicted = np.empty_like(observations, dtype=np.float64)
    for i in range(len(observations)):
        mujoco.mj_resetData(model, data)
        data.qpos[0] = 0.0
        data.qpos[1:] = observations[i, : nq - 1]
        data.qvel[:] = observations[i, nq - 1 :]
        data.ctrl[:] = np.clip(actions[i], low, high)
        mujoco.mj_step(model, data, nstep=frame_skip)
        predicted[i, : nq - 1] = data.qpos[1:]
        predicted[i, nq - 1 :] = data.qvel
    return predicted


def dynamics_error(
    domain: Domain, observations: np.ndarray, actions: np.ndarray, next_observations: np.ndarray
) -> DynamicsError:
    """Replay (s, a, s') in ``domain`` and compare s' with the simulator's next state."""
    observations = np.asarray(observations, dtype=np.float64)
    next_observations = np.asarray(next_observations, dtype=np.float64)
    model, frame_skip = simulator(domain)
    clip = observation_velocity_clip(domain)
    keep = np.ones(len(observations), dtype=bool)
    if np.isfinite(clip):
        nq = model.nq
        velocities = np.concatenate([observations[:, nq - 1 :], next_observations[:, nq - 1 :]], axis=1)
        keep = np.all(np.abs(velocities) < clip - 1e-6, axis=1)
    predicted = _replay(model, frame_skip, domain, observations[keep], np.asarray(actions)[keep])
    return DynamicsError.from_differences(predicted - next_observations[keep], excluded_clipped=int((~keep).sum()))


def dataset_dynamics_error(domain: Domain, data: Dataset) -> DynamicsError:
    """:func:`dynamics_error` of every transition of ``data`` (next observations stored or derived)."""
    return dynamics_error(domain, data.observations, data.actions, data.next_observations_or_derived())
