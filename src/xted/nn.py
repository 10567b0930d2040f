"""Network building blocks shared across xted (RL learners, the learned dynamics and reward proxies,
the prior's target dynamics model), and an MLP regression fitted to standardised data."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import partial
from typing import Any, Callable, Protocol, Sequence

import flax.linen as nn
import flax.serialization
import jax
import jax.numpy as jnp
import numpy as np

from xted.errors import InputError


def dense(width: int, fan_in: int) -> nn.Dense:
    """A Dense layer initialised as PyTorch's ``nn.Linear`` (kernel and bias U(+-1/sqrt(fan_in))), the
    init of the reference SAC/TD3/TD3+BC code. Flax's default (LeCun-normal kernels, zero biases)
    made online halfcheetah runs flip onto their backs early and stall near 1,000 (BENCHMARKS.md)."""
    bound = 1.0 / math.sqrt(fan_in)

    def uniform(key, shape, dtype=jnp.float32):
        return jax.random.uniform(key, shape, dtype, -bound, bound)

    return nn.Dense(width, kernel_init=uniform, bias_init=uniform)


class MLP(nn.Module):
    hidden: Sequence[int]
    out: int
    activate_final: bool = False
    activation: Callable[[jax.Array], jax.Array] = nn.relu

    @nn.compact
    def __call__(self, x):
        for width in self.hidden:
            x = self.activation(dense(width, x.shape[-1])(x))
        x = dense(self.out, x.shape[-1])(x)
        return self.activation(x) if self.activate_final else x


class FitSettings(Protocol):
    """What :func:`fit_mlp` reads of a config (``xted.analysis.ProxyConfig`` is one)."""

    hidden: tuple[int, ...]
    steps: int
    batch_size: int
    learning_rate: float
    seed: int


@dataclass(frozen=True)
class FittedMLP:
    """An MLP fitted to standardised inputs and outputs; called on raw inputs, gives raw outputs."""

    hidden: tuple[int, ...]
    params: Any
    input_mean: np.ndarray
    input_std: np.ndarray
    output_mean: np.ndarray
    output_std: np.ndarray

    @property
    def input_dim(self) -> int:
        return len(self.input_mean)

    def __call__(self, inputs: np.ndarray) -> np.ndarray:
        x = (np.asarray(inputs, np.float32) - self.input_mean) / self.input_std
        y = np.asarray(_apply(self.params, self.hidden, jnp.asarray(x), len(self.output_mean)), np.float64)
        return y * self.output_std + self.output_mean

    def to_bytes(self) -> bytes:
        stats = {name: getattr(self, name) for name in ("input_mean", "input_std", "output_mean", "output_std")}
        return flax.serialization.msgpack_serialize({"hidden": list(self.hidden), "params": jax.device_get(self.params),
                                                     **stats})

    @classmethod
    def from_bytes(cls, payload: bytes, name: str) -> FittedMLP:
        try:
            data = flax.serialization.msgpack_restore(payload)
            return cls(hidden=tuple(int(h) for h in data["hidden"]), params=data["params"],
                       **{k: np.asarray(data[k], np.float32) for k in ("input_mean", "input_std", "output_mean",
                                                                     "output_std")})
        except (ValueError, KeyError, TypeError) as err:
            raise InputError(f"{name}: unreadable model ({err})") from None


@partial(jax.jit, static_argnums=(1, 3))
def _apply(params: Any, hidden: tuple[int, ...], x: jnp.ndarray, out: int) -> jnp.ndarray:
    return MLP(hidden, out, activation=nn.silu).apply(params, x)


def regression_loss(params: Any, hidden: tuple[int, ...], x: jnp.ndarray, y: jnp.ndarray) -> jnp.ndarray:
    """Mean squared error of the standardised outputs."""
    return jnp.mean((_apply(params, hidden, x, y.shape[-1]) - y) ** 2)


def fit_mlp(inputs: np.ndarray, outputs: np.ndarray, config: FitSettings, progress: bool = True,
            desc: str = "proxy") -> FittedMLP:
    """Fit ``outputs [N, k]`` from ``inputs [N, d]`` (Adam, cosine decay); the same seed gives the same model."""
    import optax  # training only: editing loads this module without the optimiser
    from tqdm.auto import tqdm

    if len(inputs) < 2:
        raise InputError(f"a proxy needs at least 2 target transitions, got {len(inputs)}")
    inputs, outputs = np.asarray(inputs, np.float32), np.asarray(outputs, np.float32)
    input_mean, input_std = inputs.mean(0), inputs.std(0) + 1e-6
    output_mean, output_std = outputs.mean(0), outputs.std(0) + 1e-6
    x = jnp.asarray((inputs - input_mean) / input_std)
    y = jnp.asarray((outputs - output_mean) / output_std)
    hidden = tuple(config.hidden)

    init_key, data_key = jax.random.split(jax.random.PRNGKey(config.seed))
    params = MLP(hidden, y.shape[1], activation=nn.silu).init(init_key, x[:1])
    optimizer = optax.adam(optax.cosine_decay_schedule(config.learning_rate, config.steps))
    opt_state = optimizer.init(params)

    def update(carry, key):
        params, opt_state = carry
        pick = jax.random.randint(key, (config.batch_size,), 0, x.shape[0])
        loss, grads = jax.value_and_grad(regression_loss)(params, hidden, x[pick], y[pick])
        updates, opt_state = optimizer.update(grads, opt_state, params)
        return (optax.apply_updates(params, updates), opt_state), loss

    @jax.jit
    def chunk(carry, keys):
        return jax.lax.scan(update, carry, keys)

    keys = jax.random.split(data_key, config.steps)
    carry = (params, opt_state)
    bar = tqdm(total=config.steps, disable=not progress, unit="step", desc=desc)
    for start in range(0, config.steps, 1000):
        carry, losses = chunk(carry, keys[start : start + 1000])
        bar.update(len(losses))
        bar.set_postfix(loss=f"{float(losses[-1]):.4f}")
    bar.close()
    return FittedMLP(hidden=hidden, params=jax.device_get(carry[0]), input_mean=input_mean, input_std=input_std,
                     output_mean=output_mean, output_std=output_std)
