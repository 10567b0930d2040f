"""An episode's observations as full MuJoCo states.

Observations are ``qpos`` without the root's ground-plane position (x; x and y for Ant), then
``qvel`` (:mod:`xted.envs.layout`). Integrating the root's velocities ``qvel[0]`` (and ``qvel[1]``)
over the env's time step puts them back, so the body travels through the scene. The trapezoid rule is close, not exact: the
simulator integrates ``frame_skip`` substeps whose velocities an observation does not hold (about
2 cm over 100 steps of random halfcheetah actions, against 1-1.5 m travelled).
"""

from __future__ import annotations

import mujoco
import numpy as np

from xted.data import Dataset
from xted.envs.layout import full_qpos, observed_positions, omitted_positions, state_dims
from xted.errors import InputError


def episode_observations(data: Dataset, episode: int) -> np.ndarray:
    """The observations of episode ``episode`` (negative counts from the end) of ``data``."""
    count = data.num_episodes
    if not -count <= episode < count:
        raise InputError(f"episode {episode} is out of range: the dataset has {count} episodes (0 to {count - 1})")
    start, end = data.episode_bounds()[episode]
    return data.observations[start:end]


def root_positions(velocity: np.ndarray, dt: float) -> np.ndarray:
    """The root's position at every step (``[T]``, or ``[T, k]`` for k coordinates), from 0 at the
    first: ``x[t+1] = x[t] + dt (v[t] + v[t+1]) / 2``."""
    velocity = np.asarray(velocity, dtype=np.float64)
    steps = dt * (velocity[1:] + velocity[:-1]) / 2.0
    return np.concatenate([np.zeros((1, *velocity.shape[1:])), np.cumsum(steps, axis=0)])


def episode_states(model: mujoco.MjModel, observations: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """``(qpos, qvel)`` of every observation, the omitted root coordinates integrated from their velocities."""
    if observations.ndim != 2 or observations.shape[1] != state_dims(model):
        raise InputError(f"observations have {observations.shape[-1]} dims; this model's states have "
                         f"{state_dims(model)} (qpos without the root's ground-plane position, then qvel)")
    observations = np.asarray(observations, dtype=np.float64)
    positions, omitted = observed_positions(model), omitted_positions(model)
    qvel = observations[:, positions:]
    return full_qpos(model, observations[:, :positions], root_positions(qvel[:, :omitted], dt)), qvel


def set_state(model: mujoco.MjModel, data: mujoco.MjData, qpos: np.ndarray, qvel: np.ndarray) -> None:
    """Put ``data`` in the state ``(qpos, qvel)`` with every derived quantity (positions of bodies) computed."""
    data.qpos[:] = qpos
    data.qvel[:] = qvel
    mujoco.mj_forward(model, data)
