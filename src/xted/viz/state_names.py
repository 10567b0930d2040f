"""Names and units of observation dimensions: the positions an observation holds, then ``qvel``,
named by the model's joints (:mod:`xted.envs.layout`)."""

from __future__ import annotations

import mujoco

from xted.envs.layout import omitted_positions

_POSITION_UNITS = {mujoco.mjtJoint.mjJNT_SLIDE: "m", mujoco.mjtJoint.mjJNT_HINGE: "rad"}
_VELOCITY_UNITS = {mujoco.mjtJoint.mjJNT_SLIDE: "m/s", mujoco.mjtJoint.mjJNT_HINGE: "rad/s"}


def _free_joint(name: str) -> tuple[list[tuple[str, str]], list[tuple[str, str]]]:
    positions = [(f"{name} {axis} position", "m") for axis in "xyz"]
    positions += [(f"{name} orientation q{part}", "") for part in "wxyz"]
    velocities = [(f"{name} {axis} velocity", "m/s") for axis in "xyz"]
    velocities += [(f"{name} angular velocity {axis}", "rad/s") for axis in "xyz"]
    return positions, velocities


def state_names(model: mujoco.MjModel) -> list[tuple[str, str]]:
    """``(name, unit)`` of every observation dimension, e.g. ``("rootx velocity", "m/s")``."""
    positions, velocities = [], []
    for joint in range(model.njnt):
        kind = mujoco.mjtJoint(model.jnt_type[joint])
        name = model.joint(joint).name
        if kind == mujoco.mjtJoint.mjJNT_FREE:
            joint_positions, joint_velocities = _free_joint(name)
            positions += joint_positions
            velocities += joint_velocities
            continue
        if kind not in _POSITION_UNITS:
            raise ValueError(f"joint {name} is neither free, a hinge nor a slide")
        positions.append((f"{name} position" if kind == mujoco.mjtJoint.mjJNT_SLIDE else f"{name} angle",
                          _POSITION_UNITS[kind]))
        velocities.append((f"{name} velocity", _VELOCITY_UNITS[kind]))
    return positions[omitted_positions(model):] + velocities
