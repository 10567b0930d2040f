"""A diffusion model of single transitions, in the manner of SynthER (Lu et al. 2023, "Synthetic
Experience Replay"): the paper's SER baseline (its §5.4), beside the trajectory prior.

Each transition is one vector ``(s, a, r, s', terminal)``, standardised per dimension with the
training data's mean and std; a residual-MLP denoiser predicts the noise (epsilon-prediction
MSE, Ho et al. 2020) on the cosine schedule of :mod:`xted.diffusion.schedule`, and sampling runs
the full ancestral chain from pure noise. Unlike the trajectory prior it sees no window: every
sample is one transition of its own, which is the contrast the paper draws. The default size is
for a CPU (SynthER's own is 6 blocks of width 1024 trained for 100k steps).
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Any

import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np
import optax
from tqdm.auto import tqdm

from xted.data import Dataset
from xted.diffusion.denoiser import timestep_embedding
from xted.diffusion.schedule import Schedule, cosine_schedule, ddpm_step, q_sample
from xted.errors import InputError
from xted.fields import setting


@dataclasses.dataclass(frozen=True)
class TransitionModelConfig:
    """The SER baseline's model and training."""

    width: int = setting(256, "Width of the residual MLP.")
    blocks: int = setting(3, "Residual blocks.")
    time_dim: int = setting(64, "Width of the timestep embedding.")
    num_timesteps: int = setting(100, "Diffusion steps K (training and sampling).")
    batch_size: int = setting(256, "Transitions per training step.")
    learning_rate: float = setting(3e-4, "Adam's learning rate (cosine-decayed to a tenth).")
    steps: int = setting(20_000, "Training steps.")
    seed: int = setting(0, "Seed of the initialisation, the batches and the samples.")

    def __post_init__(self) -> None:
        for name in ("width", "blocks", "time_dim", "num_timesteps", "batch_size", "steps"):
            if getattr(self, name) < 1:
                raise InputError(f"TransitionModelConfig: {name} must be >= 1, got {getattr(self, name)}")
        if self.time_dim % 2:
            raise InputError(f"TransitionModelConfig: time_dim must be even, got {self.time_dim}")
        if not self.learning_rate > 0:
            raise InputError(f"TransitionModelConfig: learning_rate must be > 0, got {self.learning_rate}")
        if self.seed < 0:
            raise InputError(f"TransitionModelConfig: seed must be >= 0, got {self.seed}")


class ResidualMLP(nn.Module):
    """``eps(x_t, t)``: blocks of ``h + Dense(silu(Dense(LayerNorm(h) + time)))``, SynthER's denoiser shape."""

    width: int
    blocks: int
    time_dim: int

    @nn.compact
    def __call__(self, x: jnp.ndarray, t: jnp.ndarray) -> jnp.ndarray:
        time = nn.Dense(self.width)(nn.silu(nn.Dense(self.width)(timestep_embedding(t, self.time_dim))))
        h = nn.Dense(self.width)(x)
        for _ in range(self.blocks):
            y = nn.silu(nn.Dense(2 * self.width)(nn.LayerNorm()(h) + time))
            h = h + nn.Dense(self.width)(y)
        return nn.Dense(x.shape[-1], kernel_init=nn.initializers.zeros)(nn.LayerNorm()(h))


@dataclasses.dataclass(frozen=True, eq=False)
class TransitionModel:
    """A trained SER model: parameters, the standardisation and layout of its vectors, and where its
    actions lie (sampled actions are clipped into the training data's range)."""

    config: TransitionModelConfig
    params: Any
    mean: np.ndarray
    std: np.ndarray
    observation_dim: int
    action_dim: int
    action_low: np.ndarray
    action_high: np.ndarray
    bound: np.ndarray  # the largest |standardised value| of each dimension in the training data
    metadata: dict


def transition_vectors(data: Dataset) -> np.ndarray:
    """``[N, 2 ds + da + 2]``: s, a, r, s', terminal."""
    return np.concatenate([data.observations, data.actions, data.rewards[:, None], data.require_next_observations(),
                           data.terminals[:, None].astype(np.float32)], axis=1).astype(np.float32)


def _network(config: TransitionModelConfig) -> ResidualMLP:
    return ResidualMLP(config.width, config.blocks, config.time_dim)


def _learning_rate(config: TransitionModelConfig) -> optax.Schedule:
    return optax.cosine_decay_schedule(config.learning_rate, config.steps, alpha=0.1)


@functools.partial(jax.jit, static_argnames=("config",))
def _train_step(config: TransitionModelConfig, schedule: Schedule, params, opt_state, vectors: jnp.ndarray,
                key: jax.Array):
    """One Adam step of the epsilon-prediction MSE on a batch drawn from ``vectors``."""
    pick, noise_key, time_key = jax.random.split(key, 3)
    x0 = vectors[jax.random.randint(pick, (config.batch_size,), 0, vectors.shape[0])]
    t = jax.random.randint(time_key, (config.batch_size,), 0, config.num_timesteps)
    noise = jax.random.normal(noise_key, x0.shape)

    def loss(p):
        return jnp.mean((_network(config).apply(p, q_sample(schedule, x0, t, noise), t) - noise) ** 2)

    value, grads = jax.value_and_grad(loss)(params)
    updates, opt_state = optax.adam(_learning_rate(config)).update(grads, opt_state, params)
    return optax.apply_updates(params, updates), opt_state, value


def train_transition_model(data: Dataset, config: TransitionModelConfig = TransitionModelConfig(),
                           progress: bool = False) -> TransitionModel:
    """Fit the SER model to ``data``'s transitions (which must store next observations)."""
    raw = transition_vectors(data)
    mean, std = raw.mean(0), np.maximum(raw.std(0), 1e-6)
    standardised = (raw - mean) / std
    vectors = jnp.asarray(standardised)
    schedule = cosine_schedule(config.num_timesteps)
    key = jax.random.key(config.seed)
    init_key, key = jax.random.split(key)
    params = _network(config).init(init_key, vectors[:1], jnp.zeros((1,), jnp.int32))
    opt_state = optax.adam(_learning_rate(config)).init(params)
    bar = tqdm(range(config.steps), desc="ser", unit="step", disable=not progress, leave=False)
    for step in bar:
        params, opt_state, value = _train_step(config, schedule, params, opt_state, vectors, jax.random.fold_in(key, step))
        if progress and step % 500 == 0:
            bar.set_postfix(loss=f"{float(value):.4f}")
    return TransitionModel(config, params, mean, std, data.observation_dim, data.action_dim,
                           data.actions.min(0), data.actions.max(0),
                           np.maximum(np.abs(standardised).max(0), 1.0).astype(np.float32), dict(data.metadata))


@functools.partial(jax.jit, static_argnames=("config", "n"))
def _sample(config: TransitionModelConfig, schedule: Schedule, params, key: jax.Array, n: int,
            bound: jnp.ndarray) -> jnp.ndarray:
    """``n`` standardised vectors: the ancestral chain (Ho et al. 2020, Eq. 6-7) from pure noise, each
    step's predicted ``x_0`` clipped to ``+-bound`` per dimension (at the chain's noisiest steps
    ``sqrt(abar)`` is 5e-4 (K = 100), and an unclipped ``x_0`` multiplies the noise prediction's error by 2,000)."""
    start, key = jax.random.split(key)
    x = jax.random.normal(start, (n, bound.shape[0]))

    def step(i, x):
        t = jnp.full((n,), config.num_timesteps - 1 - i)
        eps = _network(config).apply(params, x, t)
        return ddpm_step(schedule, x, t, eps, jax.random.normal(jax.random.fold_in(key, i), x.shape), bound)

    return jax.lax.fori_loop(0, config.num_timesteps, step, x)


def sample_transitions(model: TransitionModel, n: int, seed: int | None = None, batch_size: int = 4096) -> Dataset:
    """``n`` generated transitions as a dataset of one-step episodes (each ends in its sampled
    terminal, else a timeout); actions clipped into the training data's range."""
    if n < 1:
        raise InputError(f"sample_transitions: n must be >= 1, got {n}")
    schedule = cosine_schedule(model.config.num_timesteps)
    key = jax.random.key(model.config.seed if seed is None else seed)
    chunks = [np.asarray(_sample(model.config, schedule, model.params, jax.random.fold_in(key, i),
                                 min(batch_size, n - start), jnp.asarray(model.bound)))
              for i, start in enumerate(range(0, n, batch_size))]
    raw = np.concatenate(chunks) * model.std + model.mean
    ds, da = model.observation_dim, model.action_dim
    terminals = raw[:, -1] > 0.5
    return Dataset(observations=raw[:, :ds], actions=np.clip(raw[:, ds:ds + da], model.action_low, model.action_high),
                   rewards=raw[:, ds + da], next_observations=raw[:, ds + da + 1:2 * ds + da + 1],
                   terminals=terminals, timeouts=~terminals,
                   metadata={**model.metadata, "generated": {"method": "transition diffusion (SER)",
                                                             "config": dataclasses.asdict(model.config)}})
