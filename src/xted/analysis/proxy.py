"""A learned dynamics proxy: the paper's way of measuring editing without a simulator.

An MLP ``(s, a) -> s' - s`` fitted to target transitions (inputs and outputs standardised, MSE,
Adam with cosine decay). Its error on a dataset, ``|proxy(s, a) - s'|``, is the paper's "dynamics
error" (its §5 figure): the measure a user has when the target is a real robot. With a simulator,
:func:`xted.envs.dynamics.dynamics_error` is the ground truth; the proxy's own simulator error on
held-out target data says how much a model learned from this target data can resolve at all.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np
import optax
from tqdm.auto import tqdm

from xted.data import Dataset
from xted.envs.dynamics import DynamicsError
from xted.errors import InputError
from xted.rl.networks import MLP


@dataclass(frozen=True)
class ProxyConfig:
    hidden: tuple[int, ...] = (256, 256, 256)
    steps: int = 20_000
    batch_size: int = 256
    lr: float = 1e-3
    seed: int = 0

    def __post_init__(self) -> None:
        if self.steps < 1 or self.batch_size < 1 or self.lr <= 0 or not self.hidden:
            raise InputError(f"ProxyConfig: steps, batch_size, lr and hidden must be positive, got {self}")


def _inputs(observations: np.ndarray, actions: np.ndarray) -> np.ndarray:
    return np.concatenate([observations, actions], axis=1).astype(np.float32)


@dataclass(frozen=True)
class DynamicsProxy:
    """A fitted proxy: ``predict`` gives next observations, ``error`` the paper's dynamics error."""

    config: ProxyConfig
    params: Any
    input_mean: np.ndarray
    input_std: np.ndarray
    delta_mean: np.ndarray
    delta_std: np.ndarray

    @property
    def observation_dim(self) -> int:
        return len(self.delta_mean)

    def predict(self, observations: np.ndarray, actions: np.ndarray) -> np.ndarray:
        observations = np.asarray(observations, np.float64)
        expected = (self.observation_dim, len(self.input_mean) - self.observation_dim)
        if observations.shape[1:] != expected[:1] or np.shape(actions)[1:] != expected[1:]:
            raise InputError(
                f"the proxy takes {expected[0]}-d observations and {expected[1]}-d actions, "
                f"got {observations.shape[1:]} and {np.shape(actions)[1:]}"
            )
        x = (_inputs(observations, actions) - self.input_mean) / self.input_std
        delta = np.asarray(_apply(self.params, self.config.hidden, jnp.asarray(x), self.observation_dim), np.float64)
        return observations + delta * self.delta_std + self.delta_mean

    def error(self, data: Dataset) -> DynamicsError:
        predicted = self.predict(data.observations, data.actions)
        return DynamicsError.from_differences(predicted - data.next_observations_or_derived())


def _apply(params: Any, hidden: tuple[int, ...], x: jnp.ndarray, out: int) -> jnp.ndarray:
    return MLP(hidden, out, activation=nn.silu).apply(params, x)


def proxy_loss(params: Any, hidden: tuple[int, ...], x: jnp.ndarray, y: jnp.ndarray) -> jnp.ndarray:
    """Mean squared error of the standardised state change."""
    return jnp.mean((_apply(params, hidden, x, y.shape[-1]) - y) ** 2)


def fit_proxy(target: Dataset, config: ProxyConfig = ProxyConfig(), progress: bool = True) -> DynamicsProxy:
    """Fit the proxy to ``target``'s transitions; the same seed gives the same proxy."""
    if len(target) < 2:
        raise InputError(f"the proxy needs at least 2 target transitions, got {len(target)}")
    inputs = _inputs(target.observations, target.actions)
    deltas = (target.next_observations_or_derived() - target.observations).astype(np.float32)
    input_mean, input_std = inputs.mean(0), inputs.std(0) + 1e-6
    delta_mean, delta_std = deltas.mean(0), deltas.std(0) + 1e-6
    x = jnp.asarray((inputs - input_mean) / input_std)
    y = jnp.asarray((deltas - delta_mean) / delta_std)

    init_key, data_key = jax.random.split(jax.random.PRNGKey(config.seed))
    params = MLP(config.hidden, y.shape[1], activation=nn.silu).init(init_key, x[:1])
    optimizer = optax.adam(optax.cosine_decay_schedule(config.lr, config.steps))
    opt_state = optimizer.init(params)

    def update(carry, key):
        params, opt_state = carry
        pick = jax.random.randint(key, (config.batch_size,), 0, x.shape[0])
        loss, grads = jax.value_and_grad(proxy_loss)(params, config.hidden, x[pick], y[pick])
        updates, opt_state = optimizer.update(grads, opt_state, params)
        return (optax.apply_updates(params, updates), opt_state), loss

    @jax.jit
    def chunk(carry, keys):
        return jax.lax.scan(update, carry, keys)

    keys = jax.random.split(data_key, config.steps)
    carry = (params, opt_state)
    bar = tqdm(total=config.steps, disable=not progress, unit="step", desc="proxy")
    for start in range(0, config.steps, 1000):
        carry, losses = chunk(carry, keys[start : start + 1000])
        bar.update(len(losses))
        bar.set_postfix(loss=f"{float(losses[-1]):.4f}")
    bar.close()
    return DynamicsProxy(
        config=config,
        params=jax.device_get(carry[0]),
        input_mean=input_mean,
        input_std=input_std,
        delta_mean=delta_mean,
        delta_std=delta_std,
    )

