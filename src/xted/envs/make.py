"""Build Gymnasium environments and bare MuJoCo models for a :class:`Domain`.

Gravity and friction are edits of the loaded ``MjModel``; thigh length is a generated XML
in a temporary folder, loaded once and removed. Nothing is written into installed packages.
"""

from __future__ import annotations

import functools
import tempfile
import warnings
from pathlib import Path

import gymnasium as gym
import mujoco
import numpy as np

from xted.envs.domains import ENV_IDS, Domain, parse_domain
from xted.envs.layout import observed_positions
from xted.envs.morphology import scaled_thigh_xml

HEALTHY_Z = {"walker2d": (0.8, 2.0), "hopper": (0.7, float("inf")), "ant": (0.2, 1.0)}  # the v5 envs' defaults
# Ant-v5's default observation appends the bodies' contact forces, an output of the step and not state:
# xted's Ant observes the state alone, ``[qpos[2:], qvel]`` (27 dims).
OBSERVATION_OPTIONS = {"ant": {"include_cfrc_ext_in_observation": False}}


def _forward_mujoco_warning(message: str) -> None:
    # Gymnasium's half_cheetah.xml uses `settotalmass`, which MuJoCo >= 3.3 reports as deprecated
    # (to stderr and a MUJOCO_LOG.TXT in the working folder) every time the model is compiled.
    if "settotalmass" not in message:
        warnings.warn(f"MuJoCo: {message}", RuntimeWarning, stacklevel=2)


mujoco.set_mju_user_warning(_forward_mujoco_warning)


def _asset_xml(env_id: str) -> Path:
    probe = gym.make(env_id)
    try:
        return Path(probe.unwrapped.fullpath)
    finally:
        probe.close()


def apply_physics(model: mujoco.MjModel, domain: Domain) -> None:
    """Scale gravity and every geom's friction (the floor's included) in place."""
    model.opt.gravity[:] = model.opt.gravity * domain.gravity
    model.geom_friction[:] = model.geom_friction * domain.friction


def make(env: str | Domain, gap: str | None = None, **kwargs) -> gym.Env:
    """A Gymnasium env of ``env`` (``halfcheetah``, ``walker2d``, ``hopper``, ``ant``) in the domain ``gap``."""
    domain = env if isinstance(env, Domain) else parse_domain(env, gap)
    kwargs = {**OBSERVATION_OPTIONS.get(domain.env, {}), **kwargs}
    if domain.thigh == 1.0:
        instance = gym.make(domain.env_id, **kwargs)
    else:
        xml, lift = scaled_thigh_xml(domain.env, _asset_xml(domain.env_id), domain.thigh)
        if domain.env in HEALTHY_Z:  # the torso stands higher by the thigh's added length
            low, high = HEALTHY_Z[domain.env]
            kwargs.setdefault("healthy_z_range", (low + lift, high + lift))
        with tempfile.TemporaryDirectory(prefix="xted-morph-") as folder:
            path = Path(folder) / f"{domain.env}_thigh.xml"
            path.write_text(xml)
            instance = gym.make(domain.env_id, xml_file=str(path), **kwargs)
    apply_physics(instance.unwrapped.model, domain)
    return instance


def simulator(domain: Domain) -> tuple[mujoco.MjModel, int]:
    """The domain's compiled ``MjModel`` and its frame skip (simulator steps per env step)."""
    instance = make(domain)
    try:
        return instance.unwrapped.model, instance.unwrapped.frame_skip
    finally:
        instance.close()


def observation_velocity_clip(domain: Domain) -> float:
    """Walker2d-v5 and Hopper-v5 clip velocities in their observations to +-10; HalfCheetah does not."""
    return 10.0 if domain.env in ("walker2d", "hopper") else np.inf


def observation_bounds(env: str | None) -> tuple[np.ndarray, np.ndarray] | None:
    """Per-dimension ``(low, high)`` of what ``env``'s observations can hold where the env clips them
    (Walker2d: velocities within +-10), else None (no bound, or an env xted does not know)."""
    if env not in ENV_IDS:
        return None
    domain = Domain(env)
    clip = observation_velocity_clip(domain)
    if not np.isfinite(clip):
        return None
    model = simulator(domain)[0]
    high = np.concatenate([np.full(observed_positions(model), np.inf), np.full(model.nv, clip)])
    return -high, high


def action_bounds(env: str | None) -> tuple[np.ndarray, np.ndarray] | None:
    """``(low, high)`` of ``env``'s action space, or None for an env xted does not know."""
    if env not in ENV_IDS:
        return None
    space = _action_space(env)
    return space.low.copy(), space.high.copy()


@functools.cache
def _action_space(env: str) -> gym.spaces.Box:
    instance = gym.make(ENV_IDS[env])
    try:
        return instance.action_space
    finally:
        instance.close()


def forward_velocity_index(domain: Domain) -> int:
    """Index of the root's forward (x) velocity in observations: their first velocity."""
    return observed_positions(simulator(domain)[0])
