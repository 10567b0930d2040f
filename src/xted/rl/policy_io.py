"""Saving and loading actor checkpoints (params plus the metadata needed to rebuild them).

Two kinds of actor, named by ``meta["policy"]``: ``tanh_gaussian`` (SAC; the default for files
written before the field existed) and ``deterministic`` (TD3, exploring with Gaussian noise of
std ``meta["exploration_noise"]``).
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
from xted.rl.networks import DeterministicPolicy, TanhGaussianPolicy

POLICY_KINDS = ("tanh_gaussian", "deterministic")


def save_actor(path: str | Path, params, meta: dict) -> None:
    payload = {"params": jax.device_get(params), "meta": json.dumps(meta)}
    with atomic_path(path) as tmp:
        tmp.write_bytes(flax.serialization.msgpack_serialize(payload))


def load_actor(path: str | Path) -> tuple[dict, dict]:
    path = Path(path)
    if not path.exists():
        raise InputError(f"policy checkpoint {path} does not exist")
    try:
        payload = flax.serialization.msgpack_restore(path.read_bytes())
        return payload["params"], json.loads(payload["meta"])
    except Exception as err:
        raise InputError(f"{path} is not an xted policy checkpoint ({err})") from None


@functools.lru_cache(maxsize=None)
def _forward(kind: str, hidden: tuple[int, ...], action_dim: int):
    """One jitted forward per network shape, shared by every actor of that shape."""
    module = (TanhGaussianPolicy if kind == "tanh_gaussian" else DeterministicPolicy)(hidden, action_dim)
    return jax.jit(lambda params, obs: module.apply({"params": params}, obs))


class Actor:
    """A loaded actor: ``act(obs, rng)`` explores as it was trained to; ``act(obs)`` is greedy."""

    def __init__(self, params, meta: dict):
        self.kind = meta.get("policy", "tanh_gaussian")
        if self.kind not in POLICY_KINDS:
            raise InputError(f"unknown policy kind {self.kind!r}; known: {', '.join(POLICY_KINDS)}")
        self.params = params
        self.meta = meta
        self._forward = _forward(self.kind, tuple(meta["hidden"]), meta["action_dim"])

    @classmethod
    def load(cls, path: str | Path) -> "Actor":
        return cls(*load_actor(path))

    def act(self, obs: np.ndarray, rng: np.random.Generator | None = None) -> np.ndarray:
        out = self._forward(self.params, jnp.asarray(obs, jnp.float32))
        if self.kind == "deterministic":
            action = np.asarray(out)
            if rng is None:
                return action
            noise = self.meta["exploration_noise"] * rng.standard_normal(action.shape)
            return np.clip(action + noise, -1.0, 1.0).astype(np.float32)
        mean, log_std = np.asarray(out[0]), np.asarray(out[1])
        if rng is None:
            return np.tanh(mean)
        return np.tanh(mean + np.exp(log_std) * rng.standard_normal(mean.shape)).astype(np.float32)
