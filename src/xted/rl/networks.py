"""Policy, critic and value networks of the RL algorithms (Flax linen), built from :class:`xted.nn.MLP`."""

from __future__ import annotations

from typing import Sequence

import flax.linen as nn
import jax
import jax.numpy as jnp

from xted.errors import InputError
from xted.nn import MLP

LOG_STD_MIN, LOG_STD_MAX = -5.0, 2.0


class TanhGaussianPolicy(nn.Module):
    """A Gaussian over pre-tanh actions; ``__call__`` returns (mean, log_std)."""

    hidden: Sequence[int]
    action_dim: int

    @nn.compact
    def __call__(self, obs):
        out = MLP(self.hidden, 2 * self.action_dim)(obs)
        mean, log_std = jnp.split(out, 2, axis=-1)
        return mean, jnp.clip(log_std, LOG_STD_MIN, LOG_STD_MAX)


class GaussianPolicy(nn.Module):
    """IQL's locomotion actor: ``__call__`` returns (tanh-squashed mean, state-independent log-std
    broadcast to the batch)."""

    hidden: Sequence[int]
    action_dim: int

    @nn.compact
    def __call__(self, obs):
        mean = jnp.tanh(MLP(self.hidden, self.action_dim)(obs))
        log_std = self.param("log_std", nn.initializers.zeros, (self.action_dim,))
        return mean, jnp.broadcast_to(jnp.clip(log_std, LOG_STD_MIN, LOG_STD_MAX), mean.shape)


class DeterministicPolicy(nn.Module):
    """tanh-squashed deterministic action (TD3+BC, BC)."""

    hidden: Sequence[int]
    action_dim: int

    @nn.compact
    def __call__(self, obs):
        return jnp.tanh(MLP(self.hidden, self.action_dim)(obs))


class Critic(nn.Module):
    """An ensemble of Q(s, a) heads, evaluated in one vmapped call: output [ensemble, batch]."""

    hidden: Sequence[int]
    ensemble: int = 2

    @nn.compact
    def __call__(self, obs, action):
        ensemble = nn.vmap(
            MLP,
            variable_axes={"params": 0},
            split_rngs={"params": True},
            in_axes=None,
            out_axes=0,
            axis_size=self.ensemble,
        )
        return ensemble(self.hidden, 1)(jnp.concatenate([obs, action], axis=-1))[..., 0]


class ValueNet(nn.Module):
    hidden: Sequence[int]

    @nn.compact
    def __call__(self, obs):
        return MLP(self.hidden, 1)(obs)[..., 0]


def gaussian_log_prob(mean, log_std, x):
    """log N(x; mean, diag(exp(log_std)^2)), summed over the last axis."""
    return jnp.sum(-0.5 * ((x - mean) / jnp.exp(log_std)) ** 2 - log_std - 0.5 * jnp.log(2 * jnp.pi), axis=-1)


def sample_tanh_gaussian(rng, mean, log_std):
    """Reparameterised sample of tanh(N(mean, std)) and its log-probability."""
    pre_tanh = mean + jnp.exp(log_std) * jax.random.normal(rng, mean.shape)
    action = jnp.tanh(pre_tanh)
    log_prob = gaussian_log_prob(mean, log_std, pre_tanh)
    # log|d tanh(u)/du| = 2 (log 2 - u - softplus(-2u)), numerically stable
    log_prob -= jnp.sum(2.0 * (jnp.log(2.0) - pre_tanh - jax.nn.softplus(-2.0 * pre_tanh)), axis=-1)
    return action, log_prob


def require_no_actor_penalty(actor_penalty, learner: str) -> None:
    """Refuse an actor penalty (OTDF's behaviour term) for a learner whose actor loss takes none."""
    if actor_penalty is not None:
        raise InputError(f"{learner} takes no actor penalty (OTDF's behaviour term regularises IQL's actor)")
