"""Saving and loading actor checkpoints (params plus the metadata needed to rebuild them)."""

from __future__ import annotations

import json
from pathlib import Path

import flax.serialization
import jax
import jax.numpy as jnp
import numpy as np

from xted.atomic import atomic_path
from xted.errors import InputError
from xted.rl.networks import TanhGaussianPolicy


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


class GaussianActor:
    """A loaded tanh-Gaussian actor: ``act(obs, rng=None)`` samples, or is greedy without rng."""

    def __init__(self, params, meta: dict):
        self.params = params
        self.meta = meta
        self.module = TanhGaussianPolicy(tuple(meta["hidden"]), meta["action_dim"])
        self._forward = jax.jit(lambda p, o: self.module.apply({"params": p}, o))

    @classmethod
    def load(cls, path: str | Path) -> "GaussianActor":
        return cls(*load_actor(path))

    def act(self, obs: np.ndarray, rng: np.random.Generator | None = None) -> np.ndarray:
        mean, log_std = self._forward(self.params, jnp.asarray(obs, jnp.float32))
        mean, std = np.asarray(mean), np.exp(np.asarray(log_std))
        if rng is None:
            return np.tanh(mean)
        return np.tanh(mean + std * rng.standard_normal(mean.shape)).astype(np.float32)
