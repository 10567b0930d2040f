"""How an observation maps onto a MuJoCo state: ``qpos`` without the root's ground-plane
coordinates, then ``qvel``. A planar body (HalfCheetah, Walker2d, Hopper: a ``rootx`` slide joint
first) omits x; a free-floating one (Ant, its first joint free) omits x and y. Neither affects the
dynamics, so an observation fixes the simulator state with them at 0."""

from __future__ import annotations

import mujoco
import numpy as np


def omitted_positions(model: mujoco.MjModel) -> int:
    """Root coordinates an observation leaves out: 2 (x, y) for a free root joint, else 1 (x)."""
    return 2 if model.njnt and model.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE else 1


def observed_positions(model: mujoco.MjModel) -> int:
    """Position dimensions an observation holds: the index of its first velocity."""
    return model.nq - omitted_positions(model)


def state_dims(model: mujoco.MjModel) -> int:
    """Dimensions of an observation that fixes the state: ``observed_positions + nv``."""
    return observed_positions(model) + model.nv


def full_qpos(model: mujoco.MjModel, positions: np.ndarray, root: np.ndarray | None = None) -> np.ndarray:
    """``qpos`` ``[..., nq]`` from an observation's positions ``[..., observed]``, the omitted root
    coordinates set to ``root`` ``[..., omitted]`` (0 where None)."""
    positions = np.asarray(positions, dtype=np.float64)
    if root is None:
        root = np.zeros((*positions.shape[:-1], omitted_positions(model)))
    return np.concatenate([root, positions], axis=-1)


def observation(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """The observation of ``data``'s state: ``[qpos[omitted:], qvel]``."""
    return np.concatenate([data.qpos[omitted_positions(model):], data.qvel])
