"""IGDF (Wen et al., ICML 2024): source transitions scored by a contrastive dynamics representation.

Two encoders, ``phi(s, a)`` and ``psi(s')``, learn to tell a target transition's own next state from
source next states: for each target ``(s, a)`` of a batch its ``s'`` is the positive and the batch's
source next states the negatives, logits ``phi . psi`` under a binary cross-entropy. Frozen, they
score every source transition by ``cos(phi(s, a), psi(s'))``: how much its next state looks like the
one the target's dynamics would give. The learner then keeps each batch's best-scored source share
and weights its Q loss by ``exp(alpha * score)`` (:mod:`xted.rl.source_weighting`).
States arrive standardised on target + source (the trainer's standardisation), actions raw.
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
from xted.rl.config import IGDFConfig


class DynamicsEncoders(nn.Module):
    """``phi(s, a)`` and ``psi(s')``, each (input) -> hidden -> embedding."""

    hidden: tuple[int, ...]
    embedding_dim: int

    def setup(self):
        self.phi = MLP(self.hidden, self.embedding_dim)
        self.psi = MLP(self.hidden, self.embedding_dim)

    def __call__(self, obs, actions, next_obs):
        return self.phi(jnp.concatenate([obs, actions], axis=-1)), self.psi(next_obs)


def contrastive_loss(params, model: DynamicsEncoders, target: dict, source_next_obs):
    """Binary cross-entropy of ``phi(s, a) . psi(x)`` over the batch: 1 for each target's own ``s'``,
    0 for every source next state."""
    phi, psi_own = model.apply({"params": params}, target["observations"], target["actions"],
                               target["next_observations"])
    psi_source = model.apply({"params": params}, source_next_obs, method=lambda m, x: m.psi(x))
    logits = jnp.concatenate([(phi * psi_own).sum(-1, keepdims=True), phi @ psi_source.T], axis=1)
    labels = jnp.zeros_like(logits).at[:, 0].set(1.0)
    return optax.sigmoid_binary_cross_entropy(logits, labels).mean()


@partial(jax.jit, static_argnames="config")
def train_encoders(key, target: dict, source: dict, config: IGDFConfig):
    """``config.encoder_steps`` Adam steps on batches of ``encoder_batch`` target transitions and
    ``encoder_batch - 1`` source next states; returns (params, per-step losses)."""
    model = DynamicsEncoders(config.encoder_hidden, config.embedding_dim)
    init_key, key = jax.random.split(key)
    params = model.init(init_key, target["observations"][:1], target["actions"][:1],
                        target["next_observations"][:1])["params"]
    state = TrainState.create(apply_fn=model.apply, params=params, tx=optax.adam(config.encoder_lr))

    def step(carry, _):
        state, key = carry
        key, target_key, source_key = jax.random.split(key, 3)
        target_idx = jax.random.randint(target_key, (config.encoder_batch,), 0, len(target["observations"]))
        source_idx = jax.random.randint(source_key, (config.encoder_batch - 1,), 0, len(source["observations"]))
        batch = {k: v[target_idx] for k, v in target.items()}
        loss, grads = jax.value_and_grad(contrastive_loss)(state.params, model, batch,
                                                           source["next_observations"][source_idx])
        return (state.apply_gradients(grads=grads), key), loss

    (state, _), losses = jax.lax.scan(step, (state, key), None, length=config.encoder_steps)
    return state.params, losses


@partial(jax.jit, static_argnames="config")
def dynamics_scores(params, obs, actions, next_obs, config: IGDFConfig):
    """``cos(phi(s, a), psi(s'))`` per transition."""
    phi, psi = DynamicsEncoders(config.encoder_hidden, config.embedding_dim).apply(
        {"params": params}, obs, actions, next_obs)
    return (phi * psi).sum(-1) / (jnp.linalg.norm(phi, axis=-1) * jnp.linalg.norm(psi, axis=-1) + 1e-8)


def source_scores(keys, target: dict, source: dict, config: IGDFConfig,
                  chunk: int = 65_536) -> tuple[np.ndarray, np.ndarray]:
    """Per seed (one key each, stacked): ``[S, N_source]`` scores and ``[S, steps]`` encoder losses."""
    params, losses = jax.vmap(partial(train_encoders, config=config), in_axes=(0, None, None))(keys, target, source)
    score = jax.vmap(partial(dynamics_scores, config=config), in_axes=(0, None, None, None))
    inputs = ("observations", "actions", "next_observations")
    n = len(source["observations"])
    scores = [score(params, *(source[k][i:i + chunk] for k in inputs)) for i in range(0, n, chunk)]
    return np.concatenate([np.asarray(s) for s in scores], axis=1), np.asarray(losses)
