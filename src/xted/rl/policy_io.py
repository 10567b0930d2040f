"""Saving and loading policies: actor parameters plus the metadata needed to rebuild and use them.

Three kinds of actor, named by ``meta["policy"]``: ``tanh_gaussian`` (SAC; the default for files
written before the field existed), ``deterministic`` (TD3, TD3+BC and BC; TD3 explores with Gaussian
noise of std ``meta["exploration_noise"]``) and ``gaussian`` (IQL: a tanh-squashed mean and a
state-independent std). An offline policy also stores ``obs_mean`` and ``obs_std``, the
standardisation of its training data, which it applies to every observation before acting.

A policy saved with :meth:`Policy.save` is a folder: ``policy.msgpack`` (parameters and metadata,
all that loading needs) and ``policy.json`` (the same metadata, for reading).
"""

from __future__ import annotations

import functools
import json
from pathlib import Path

import flax.serialization
import jax
import jax.numpy as jnp
import numpy as np

from xted.atomic import atomic_path
from xted.errors import InputError
from xted.rl.networks import DeterministicPolicy, GaussianPolicy, TanhGaussianPolicy

POLICY_KINDS = ("tanh_gaussian", "deterministic", "gaussian")
POLICY_FILE, POLICY_META_FILE = "policy.msgpack", "policy.json"


def save_actor(path: str | Path, params, meta: dict) -> None:
    payload = {"params": jax.device_get(params), "meta": json.dumps(meta)}
    with atomic_path(path) as tmp:
        tmp.write_bytes(flax.serialization.msgpack_serialize(payload))


def load_actor(path: str | Path) -> tuple[dict, dict]:
    """Parameters and metadata of a checkpoint file, or of a saved policy's folder."""
    path = Path(path)
    if path.is_dir():
        path = path / POLICY_FILE
    if not path.exists():
        raise InputError(f"policy checkpoint {path} does not exist")
    try:
        payload = flax.serialization.msgpack_restore(path.read_bytes())
        return payload["params"], json.loads(payload["meta"])
    except Exception as err:
        raise InputError(f"{path} is not an xted policy checkpoint ({err})") from None


def to_action_range(action: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """An action in [-1, 1] mapped affinely into [low, high] per dimension."""
    return (low + (np.asarray(action) + 1) * (high - low) / 2).astype(np.float32)


@functools.lru_cache(maxsize=None)
def _forward(kind: str, hidden: tuple[int, ...], action_dim: int):
    """One jitted forward per network shape, shared by every actor of that shape."""
    module = {"tanh_gaussian": TanhGaussianPolicy, "deterministic": DeterministicPolicy,
              "gaussian": GaussianPolicy}[kind](hidden, action_dim)
    return jax.jit(lambda params, obs: module.apply({"params": params}, obs))


class Policy:
    """A loaded policy: ``act(obs, rng)`` explores as it was trained to; ``act(obs)`` is greedy.

    ``obs`` is one observation ``[obs_dim]`` or a batch ``[N, obs_dim]``; actions come back in the
    same layout, in [-1, 1], or in ``[action_low, action_high]`` where the policy learnt a wider
    range from its data."""

    def __init__(self, params, meta: dict):
        self.kind = meta.get("policy", "tanh_gaussian")
        if self.kind not in POLICY_KINDS:
            raise InputError(f"unknown policy kind {self.kind!r}; known: {', '.join(POLICY_KINDS)}")
        self.params = params
        self.meta = meta
        self._forward = _forward(self.kind, tuple(meta["hidden"]), meta["action_dim"])
        standardised = "obs_mean" in meta
        self._obs_mean = np.asarray(meta["obs_mean"], np.float32) if standardised else None
        self._obs_std = np.asarray(meta["obs_std"], np.float32) if standardised else None
        ranged = "action_low" in meta
        self.action_range = (np.asarray(meta["action_low"], np.float32),
                             np.asarray(meta["action_high"], np.float32)) if ranged else None

    @classmethod
    def load(cls, path: str | Path) -> "Policy":
        """A policy from a checkpoint file or a folder written by :meth:`save`."""
        return cls(*load_actor(path))

    def save(self, folder: str | Path) -> Path:
        """Write the policy to ``folder`` (``policy.msgpack`` and ``policy.json``); returns the folder."""
        folder = Path(folder)
        if folder.exists() and not folder.is_dir():
            raise InputError(f"{folder} exists and is not a folder: cannot save a policy there")
        folder.mkdir(parents=True, exist_ok=True)
        save_actor(folder / POLICY_FILE, self.params, self.meta)
        with atomic_path(folder / POLICY_META_FILE) as tmp:
            tmp.write_text(json.dumps(self.meta, indent=2))
        return folder

    @property
    def scores(self) -> dict | None:
        """An offline policy's evaluation in training (``final_score``, ``best_score``, ``evals``;
        scores None when it trained without a simulator); None for other checkpoints."""
        return self.meta.get("scores")

    def act(self, obs: np.ndarray, rng: np.random.Generator | None = None) -> np.ndarray:
        action = self._act_unit(obs, rng)
        return action if self.action_range is None else to_action_range(action, *self.action_range)

    def _act_unit(self, obs: np.ndarray, rng: np.random.Generator | None) -> np.ndarray:
        """The actor's action in [-1, 1]."""
        obs = np.asarray(obs, np.float32)
        if self._obs_mean is not None:
            if obs.shape[-1:] != self._obs_mean.shape:
                raise InputError(f"observation of shape {obs.shape}: this policy takes {len(self._obs_mean)} "
                                 f"features (one observation, or a batch of them)")
            obs = (obs - self._obs_mean) / self._obs_std
        out = self._forward(self.params, jnp.asarray(obs))
        if self.kind == "deterministic":
            action = np.asarray(out)
            if rng is None or "exploration_noise" not in self.meta:
                return action
            noise = self.meta["exploration_noise"] * rng.standard_normal(action.shape)
            return np.clip(action + noise, -1.0, 1.0).astype(np.float32)
        mean, log_std = np.asarray(out[0]), np.asarray(out[1])
        if self.kind == "gaussian":
            if rng is None:
                return mean
            return np.clip(mean + np.exp(log_std) * rng.standard_normal(mean.shape), -1.0, 1.0).astype(np.float32)
        if rng is None:
            return np.tanh(mean)
        return np.tanh(mean + np.exp(log_std) * rng.standard_normal(mean.shape)).astype(np.float32)
