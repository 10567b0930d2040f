"""An episode's observations as full MuJoCo states.

Observations of HalfCheetah-v5 and Walker2d-v5 are ``qpos[1:]`` then ``qvel``: everything but the
root's x position. Integrating the forward velocity ``qvel[0]`` over the env's time step puts x
back, so the body travels through the scene. The trapezoid rule is close, not exact: the
simulator integrates ``frame_skip`` substeps whose velocities an observation does not hold (about
2 cm over 100 steps of random halfcheetah actions, against 1-1.5 m travelled).
"""

from __future__ import annotations

import mujoco
import numpy as np

from xted.data import Dataset
from xted.errors import InputError


def episode_observations(data: Dataset, episode: int) -> np.ndarray:
    """The observations of episode ``episode`` (negative counts from the end) of ``data``."""
    count = data.num_episodes
    if not -count <= episode < count:
        raise InputError(f"episode {episode} is out of range: the dataset has {count} episodes (0 to {count - 1})")
    start, end = data.episode_bounds()[episode]
    return data.observations[start:end]


def root_positions(forward_velocity: np.ndarray, dt: float) -> np.ndarray:
    """The root's x at every step, from x = 0 at the first: ``x[t+1] = x[t] + dt (v[t] + v[t+1]) / 2``."""
    velocity = np.asarray(forward_velocity, dtype=np.float64)
    steps = dt * (velocity[1:] + velocity[:-1]) / 2.0
    return np.concatenate([[0.0], np.cumsum(steps)])


def episode_states(model: mujoco.MjModel, observations: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """``(qpos, qvel)`` of every observation ``[T, nq - 1 + nv]``, root x integrated from the velocity."""
    nq, nv = model.nq, model.nv
    if observations.ndim != 2 or observations.shape[1] != nq - 1 + nv:
        raise InputError(f"observations have {observations.shape[-1]} dims; this model's states have {nq - 1 + nv} "
                         f"(qpos without the root x, then qvel)")
    observations = np.asarray(observations, dtype=np.float64)
    qvel = observations[:, nq - 1 :]
    qpos = np.concatenate([root_positions(qvel[:, 0], dt)[:, None], observations[:, : nq - 1]], axis=1)
    return qpos, qvel


def set_state(model: mujoco.MjModel, data: mujoco.MjData, qpos: np.ndarray, qvel: np.ndarray) -> None:
    """Put ``data`` in the state ``(qpos, qvel)`` with every derived quantity (positions of bodies) computed."""
    data.qpos[:] = qpos
    data.qvel[:] = qvel
    mujoco.mj_forward(model, data)
