"""DARA (Liu et al. 2022): dynamics-aware reward augmentation of source data, IQL as the backbone.

Two classifiers tell target (label 1) from source (label 0) transitions, one on ``(s, a)`` and one on
``(s, a, s')``; their logits are log-odds of "target". By Bayes' rule
``log p_tgt(s'|s,a) / p_src(s'|s,a) = logit_sas - logit_sa``, and each source reward becomes
``r + eta * clip(logit_sas - logit_sa, -clip, clip)``: source transitions the target dynamics would not
produce are penalised. The classifiers are trained first, on balanced batches (half target, half source)
with Gaussian input noise as a regulariser (as DARC does), then IQL trains on target + corrected source.
Inputs are the trainer's standardised observations and the raw actions. The correction is added to the
rewards the backbone trains on (after IQL's optional reward scaling), in log-probability units.
"""

from __future__ import annotations

from functools import partial
from typing import Sequence

import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np
import optax
from flax.training.train_state import TrainState

from xted.nn import MLP
from xted.rl.config import DARAConfig

CLASSIFIER_INPUTS = ("observations", "actions", "next_observations")


class DomainClassifiers(nn.Module):
    """Target-vs-source logits of ``(s, a)`` and of ``(s, a, s')``."""

    hidden: Sequence[int]

    @nn.compact
    def __call__(self, obs, actions, next_obs):
        sa = MLP(self.hidden, 1, name="sa")(jnp.concatenate([obs, actions], axis=-1))[..., 0]
        sas = MLP(self.hidden, 1, name="sas")(jnp.concatenate([obs, actions, next_obs], axis=-1))[..., 0]
        return sa, sas


def classifier_loss(params, apply_fn, batch, labels):
    sa, sas = apply_fn({"params": params}, *(batch[k] for k in CLASSIFIER_INPUTS))
    loss = (optax.sigmoid_binary_cross_entropy(sa, labels).mean()
            + optax.sigmoid_binary_cross_entropy(sas, labels).mean())
    return loss


@partial(jax.jit, static_argnames="config")
def train_classifiers(key, target: dict, source: dict, config: DARAConfig):
    """Train both classifiers for ``config.classifier_steps``; returns (params, per-step losses)."""
    init_key, key = jax.random.split(key)
    model = DomainClassifiers(config.classifier_hidden)
    params = model.init(init_key, *(target[k][:1] for k in CLASSIFIER_INPUTS))["params"]
    state = TrainState.create(apply_fn=model.apply, params=params, tx=optax.adam(config.classifier_lr))
    half = config.classifier_batch // 2
    labels = jnp.concatenate([jnp.ones(half), jnp.zeros(config.classifier_batch - half)])

    def step(carry, _):
        state, key = carry
        key, target_key, source_key, noise_key = jax.random.split(key, 4)
        target_idx = jax.random.randint(target_key, (half,), 0, len(target["observations"]))
        source_idx = jax.random.randint(source_key, (config.classifier_batch - half,), 0, len(source["observations"]))
        noise_keys = jax.random.split(noise_key, len(CLASSIFIER_INPUTS))
        batch = {}
        for k, noise_k in zip(CLASSIFIER_INPUTS, noise_keys):
            x = jnp.concatenate([target[k][target_idx], source[k][source_idx]])
            batch[k] = x + config.input_noise * jax.random.normal(noise_k, x.shape)
        loss, grads = jax.value_and_grad(classifier_loss)(state.params, state.apply_fn, batch, labels)
        return (state.apply_gradients(grads=grads), key), loss

    (state, _), losses = jax.lax.scan(step, (state, key), None, length=config.classifier_steps)
    return state.params, losses


@partial(jax.jit, static_argnames="config")
def reward_delta(params, obs, actions, next_obs, config: DARAConfig):
    """``log p_tgt(s'|s,a) / p_src(s'|s,a)`` estimated as ``logit_sas - logit_sa`` (unclipped)."""
    sa, sas = DomainClassifiers(config.classifier_hidden).apply({"params": params}, obs, actions, next_obs)
    return sas - sa


def source_reward_deltas(keys, target: dict, source: dict, config: DARAConfig,
                         chunk: int = 65_536) -> tuple[np.ndarray, np.ndarray]:
    """Per seed (one key each, stacked): ``[S, N_source]`` reward deltas and ``[S, steps]`` losses."""
    params, losses = jax.vmap(partial(train_classifiers, config=config), in_axes=(0, None, None))(keys, target, source)
    delta = jax.vmap(partial(reward_delta, config=config), in_axes=(0, None, None, None))
    n = len(source["observations"])
    deltas = [delta(params, *(source[k][i:i + chunk] for k in CLASSIFIER_INPUTS)) for i in range(0, n, chunk)]
    return np.concatenate([np.asarray(d) for d in deltas], axis=1), np.asarray(losses)


def corrected_rewards(rewards: np.ndarray, deltas: np.ndarray, config: DARAConfig) -> np.ndarray:
    """``r + eta * clip(delta, -clip, clip)``: DARA's reward augmentation ``r - eta * delta_r``, whose
    ``delta_r = log p_src(s'|s,a) / p_tgt(s'|s,a)`` is ``-delta`` here (Liu et al. 2022)."""
    return rewards + config.eta * np.clip(deltas, -config.clip, config.clip)
