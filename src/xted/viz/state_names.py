"""Names and units of observation dimensions: ``qpos[1:]`` then ``qvel``, named by the model's joints."""

from __future__ import annotations

import mujoco

_POSITION_UNITS = {mujoco.mjtJoint.mjJNT_SLIDE: "m", mujoco.mjtJoint.mjJNT_HINGE: "rad"}
_VELOCITY_UNITS = {mujoco.mjtJoint.mjJNT_SLIDE: "m/s", mujoco.mjtJoint.mjJNT_HINGE: "rad/s"}


def state_names(model: mujoco.MjModel) -> list[tuple[str, str]]:
    """``(name, unit)`` of every observation dimension, e.g. ``("rootx velocity", "m/s")``."""
    positions, velocities = [], []
    for joint in range(model.njnt):
        kind = mujoco.mjtJoint(model.jnt_type[joint])
        if kind not in _POSITION_UNITS:
            raise ValueError(f"joint {model.joint(joint).name} is neither a hinge nor a slide")
        name = model.joint(joint).name
        positions.append((f"{name} position" if kind == mujoco.mjtJoint.mjJNT_SLIDE else f"{name} angle",
                          _POSITION_UNITS[kind]))
        velocities.append((f"{name} velocity", _VELOCITY_UNITS[kind]))
    return positions[1:] + velocities
