"""OTDF (Lyu et al., ICLR 2025): source transitions scored by optimal transport to the target's,
and a behaviour regulariser from a conditional VAE of the target's actions.

Each source transition ``x = [s, a, s']`` is matched to the target's transitions by entropic optimal
transport (cosine cost scaled by its maximum, uniform marginals, log-domain Sinkhorn; epsilon relative
to the mean scaled cost), the source taken in chunks; its deviation ``d_i = sum_j P_ij C_ij`` (each
row's transported cost over its row's mass) says how far it lies from anything the target holds, and
``-d_i`` is its score (:mod:`xted.rl.source_weighting` keeps and weights by it). The CVAE gives
``log beta(a | s)`` of the target's behaviour; the actor loss subtracts ``behaviour_weight`` times it
at the policy's action. States arrive standardised (the trainer's standardisation), actions raw.
"""

from __future__ import annotations

from functools import partial

import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np
import optax
from flax.training.train_state import TrainState

from xted.nn import MLP
from xted.rl.config import OTDFConfig

TRANSITION = ("observations", "actions", "next_observations")


def cosine_cost(x, y):
    """``1 - cos(x_i, y_j)``."""
    x = x / (jnp.linalg.norm(x, axis=-1, keepdims=True) + 1e-8)
    y = y / (jnp.linalg.norm(y, axis=-1, keepdims=True) + 1e-8)
    return 1.0 - x @ y.T


# Above this 1 / epsilon the kernel exp(-cost / epsilon) underflows float32: iterate in the log domain.
KERNEL_LIMIT = 80.0


@partial(jax.jit, static_argnames=("iterations",))
def transport_deviation(x, y, epsilon: float, iterations: int, tolerance: float):
    """Per row of ``x``: its transported cost to ``y`` over its row mass, under the entropic plan
    between uniform marginals on the cosine cost scaled by its maximum. Sinkhorn scales the kernel
    (matrix-vector products) while ``1 / epsilon`` allows; in the log domain beyond."""
    raw = cosine_cost(x, y)
    cost = raw / jnp.maximum(raw.max(), 1e-8)
    eps = epsilon * cost.mean()
    a, b = jnp.full(x.shape[0], 1.0 / x.shape[0]), jnp.full(y.shape[0], 1.0 / y.shape[0])

    def iterate(step, start):
        def going(carry):
            return (carry[2] < iterations) & (carry[3] > tolerance)

        return jax.lax.while_loop(going, step, (*start, 0, jnp.inf))[:2]

    def kernel_plan():
        kernel = jnp.exp(-cost / eps)

        def step(carry):
            u, v, i, _ = carry
            rows = kernel @ v
            error = jnp.abs(u * rows - a).sum()  # the current plan's row marginals
            u = a / rows
            return u, b / (kernel.T @ u), i + 1, error

        u, v = iterate(step, (jnp.ones_like(a), jnp.ones_like(b)))
        return u[:, None] * kernel * v[None, :]

    def log_plan():
        def step(carry):
            f, g, i, _ = carry
            rows = jax.nn.logsumexp((g[None, :] - cost) / eps, axis=1)
            error = jnp.abs(jnp.exp(f / eps + rows) - a).sum()
            f = eps * (jnp.log(a) - rows)
            return f, eps * (jnp.log(b) - jax.nn.logsumexp((f[:, None] - cost) / eps, axis=0)), i + 1, error

        f, g = iterate(step, (jnp.zeros_like(a), jnp.zeros_like(b)))
        return jnp.exp((f[:, None] + g[None, :] - cost) / eps)

    plan = jax.lax.cond(1.0 / eps < KERNEL_LIMIT, kernel_plan, log_plan)
    return (plan * raw).sum(axis=1) / plan.sum(axis=1)


def transitions(data: dict) -> jnp.ndarray:
    return jnp.concatenate([jnp.asarray(data[k]) for k in TRANSITION], axis=-1)


def source_deviations(target: dict, source: dict, config: OTDFConfig) -> np.ndarray:
    """``d_i`` of every source transition against all the target's, ``config.chunk`` rows at a time."""
    y = transitions(target)
    x = transitions(source)
    return np.concatenate([np.asarray(transport_deviation(
        x[i:i + config.chunk], y, config.epsilon, config.sinkhorn_iterations, config.sinkhorn_tolerance))
        for i in range(0, x.shape[0], config.chunk)])


class BehaviourVAE(nn.Module):
    """A conditional VAE of actions given states: ``(s, a) -> (mean, log_std)`` of a latent of
    ``2 |A|`` dimensions, ``(s, z) -> tanh`` action."""

    hidden: tuple[int, ...]
    action_dim: int

    def setup(self):
        self.encoder = MLP(self.hidden, 4 * self.action_dim)
        self.decoder = MLP(self.hidden, self.action_dim)

    @property
    def latent_dim(self) -> int:
        return 2 * self.action_dim

    def __call__(self, obs, actions, noise):
        mean, log_std = jnp.split(self.encoder(jnp.concatenate([obs, actions], axis=-1)), 2, axis=-1)
        log_std = jnp.clip(log_std, -4.0, 15.0)
        return self.decode(obs, mean + jnp.exp(log_std) * noise), mean, log_std

    def decode(self, obs, latent):
        return jnp.tanh(self.decoder(jnp.concatenate([obs, latent], axis=-1)))


def vae_loss(params, model: BehaviourVAE, batch, noise, kl_weight: float):
    """Reconstruction MSE plus ``kl_weight`` x KL(q(z | s, a) || N(0, I))."""
    reconstruction, mean, log_std = model.apply({"params": params}, batch["observations"], batch["actions"], noise)
    kl = 0.5 * (mean**2 + jnp.exp(2 * log_std) - 1.0 - 2 * log_std).sum(-1)
    return ((reconstruction - batch["actions"]) ** 2).sum(-1).mean() + kl_weight * kl.mean()


@partial(jax.jit, static_argnames="config")
def train_behaviour(key, target: dict, config: OTDFConfig):
    """The CVAE fitted to the target's ``(s, a)``: (params, per-step losses)."""
    action_dim = target["actions"].shape[-1]
    model = BehaviourVAE(config.vae_hidden, action_dim)
    init_key, key = jax.random.split(key)
    params = model.init(init_key, target["observations"][:1], target["actions"][:1],
                        jnp.zeros((1, 2 * action_dim)))["params"]
    state = TrainState.create(apply_fn=model.apply, params=params, tx=optax.adam(config.vae_lr))

    def step(carry, _):
        state, key = carry
        key, batch_key, noise_key = jax.random.split(key, 3)
        idx = jax.random.randint(batch_key, (config.vae_batch,), 0, len(target["observations"]))
        batch = {k: target[k][idx] for k in ("observations", "actions")}
        noise = jax.random.normal(noise_key, (config.vae_batch, 2 * action_dim))
        loss, grads = jax.value_and_grad(vae_loss)(state.params, model, batch, noise, config.kl_weight)
        return (state.apply_gradients(grads=grads), key), loss

    (state, _), losses = jax.lax.scan(step, (state, key), None, length=config.vae_steps)
    return state.params, losses


DECODE_CHUNK = 2048  # states decoded at once (memory: chunk x behaviour_samples x the CVAE's width)


def decode_behaviour(params, obs, key, config: OTDFConfig, action_dim: int):
    """``[N, K, |A|]``: for every state, the CVAE's decoded actions of ``K = behaviour_samples`` latents
    drawn from its prior N(0, I)."""
    model = BehaviourVAE(config.vae_hidden, action_dim)
    n, k = obs.shape[0], config.behaviour_samples
    chunks = -(-n // DECODE_CHUNK)
    padded = jnp.concatenate([obs, jnp.zeros((chunks * DECODE_CHUNK - n, obs.shape[1]), obs.dtype)])
    latents = jax.random.normal(key, (chunks, DECODE_CHUNK, k, 2 * action_dim))

    def decode(chunk):
        states, z = chunk
        return model.apply({"params": params}, jnp.repeat(states[:, None], k, axis=1), z, method=BehaviourVAE.decode)

    decoded = jax.lax.map(decode, (padded.reshape(chunks, DECODE_CHUNK, -1), latents))
    return decoded.reshape(chunks * DECODE_CHUNK, k, action_dim)[:n]


@partial(jax.jit, static_argnames=("config", "action_dim"))
def decode_behaviours(params, obs, keys, config: OTDFConfig, action_dim: int):
    """:func:`decode_behaviour` of each seed's CVAE (stacked ``params``, one key each): ``[S, N, K, |A|]``."""
    return jax.vmap(decode_behaviour, in_axes=(0, None, 0, None, None))(params, obs, keys, config, action_dim)


def behaviour_log_prob(decoded, actions, config: OTDFConfig):
    """``log beta(a | s)`` from the state's decoded actions ``[B, K, |A|]``: the log-mean-exp over them of
    N(a; dec(s, z), variance I), a Monte Carlo estimate over the CVAE's latent prior."""
    dim = actions.shape[-1]
    log_normal = (-0.5 * ((actions[:, None] - decoded) ** 2).sum(-1) / config.behaviour_variance
                  - 0.5 * dim * jnp.log(2 * jnp.pi * config.behaviour_variance))
    return jax.nn.logsumexp(log_normal, axis=1) - jnp.log(decoded.shape[1])


def behaviour_penalty(decoded, config: OTDFConfig):
    """The actor loss's term per state: ``-behaviour_weight * log beta(pi(s) | s)``, from the batch's
    decoded behaviour actions. The decoded actions do not depend on the actor, so they are drawn ahead
    (every ``behaviour_redraw_every`` updates, for every state) instead of per update as the authors
    do: each update's expected gradient is the same, at a fraction of the decoder's cost."""
    return lambda obs, actions: -config.behaviour_weight * behaviour_log_prob(decoded, actions, config)


def train_behaviours(keys, target: dict, config: OTDFConfig):
    """One CVAE per seed (one key each): stacked params and ``[S, steps]`` losses."""
    params, losses = jax.vmap(partial(train_behaviour, config=config), in_axes=(0, None))(keys, target)
    return params, np.asarray(losses)
