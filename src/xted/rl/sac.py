"""Soft Actor-Critic: pure losses composed in one jitted update.

Twin critics with target networks, a tanh-Gaussian actor and a learned temperature
(target entropy -|A|), as in Haarnoja et al. 2018. Bootstraps through time-limit truncations;
stops at true terminals.
"""

from __future__ import annotations

from functools import partial

import flax
import jax
import jax.numpy as jnp
import optax
from flax.training.train_state import TrainState

from xted.rl.config import SACConfig
from xted.rl.networks import Critic, TanhGaussianPolicy, sample_tanh_gaussian


@flax.struct.dataclass
class SACState:
    actor: TrainState
    critic: TrainState
    target_critic_params: dict
    log_alpha: TrainState
    rng: jax.Array


def init_sac(rng, obs_dim: int, action_dim: int, config: SACConfig, steps: int) -> SACState:
    """Fresh networks (``steps``, the run's length, schedules nothing here: the learning rate is constant)."""
    actor_key, critic_key, rng = jax.random.split(rng, 3)
    obs, act = jnp.zeros((1, obs_dim)), jnp.zeros((1, action_dim))
    actor_def = TanhGaussianPolicy(config.hidden, action_dim)
    critic_def = Critic(config.hidden)
    actor = TrainState.create(
        apply_fn=actor_def.apply, params=actor_def.init(actor_key, obs)["params"], tx=optax.adam(config.learning_rate)
    )
    critic_params = critic_def.init(critic_key, obs, act)["params"]
    critic = TrainState.create(apply_fn=critic_def.apply, params=critic_params, tx=optax.adam(config.learning_rate))
    log_alpha = TrainState.create(
        apply_fn=None, params={"log_alpha": jnp.log(jnp.float32(config.init_temperature))}, tx=optax.adam(config.learning_rate)
    )
    return SACState(actor, critic, critic_params, log_alpha, rng)


def critic_loss(critic_params, state: SACState, batch, rng, config: SACConfig):
    mean, log_std = state.actor.apply_fn({"params": state.actor.params}, batch["next_observations"])
    next_action, next_log_prob = sample_tanh_gaussian(rng, mean, log_std)
    next_q = state.critic.apply_fn({"params": state.target_critic_params}, batch["next_observations"], next_action)
    alpha = jnp.exp(state.log_alpha.params["log_alpha"])
    target = batch["rewards"] + config.discount * (1.0 - batch["terminals"]) * (
        next_q.min(axis=0) - alpha * next_log_prob
    )
    q = state.critic.apply_fn({"params": critic_params}, batch["observations"], batch["actions"])
    loss = ((q - jax.lax.stop_gradient(target)) ** 2).mean()
    return loss, {"critic_loss": loss, "q": q.mean()}


def actor_loss(actor_params, state: SACState, batch, rng):
    mean, log_std = state.actor.apply_fn({"params": actor_params}, batch["observations"])
    action, log_prob = sample_tanh_gaussian(rng, mean, log_std)
    q = state.critic.apply_fn({"params": state.critic.params}, batch["observations"], action).min(axis=0)
    alpha = jnp.exp(state.log_alpha.params["log_alpha"])
    loss = (alpha * log_prob - q).mean()
    return loss, {"actor_loss": loss, "entropy": -log_prob.mean()}


def temperature_loss(params, entropy, target_entropy):
    return jnp.exp(params["log_alpha"]) * (entropy - target_entropy)


@partial(jax.jit, static_argnames="config")
def sac_update(state: SACState, batch, config: SACConfig):
    """One SAC step on ``batch``: critic, then actor, then temperature, then target critics."""
    rng, critic_key, actor_key = jax.random.split(state.rng, 3)
    grads, info = jax.grad(critic_loss, has_aux=True)(state.critic.params, state, batch, critic_key, config)
    critic = state.critic.apply_gradients(grads=grads)
    state = state.replace(critic=critic)

    grads, actor_info = jax.grad(actor_loss, has_aux=True)(state.actor.params, state, batch, actor_key)
    actor = state.actor.apply_gradients(grads=grads)

    target_entropy = -batch["actions"].shape[-1]
    alpha_grad = jax.grad(temperature_loss)(state.log_alpha.params, actor_info["entropy"], target_entropy)
    log_alpha = state.log_alpha.apply_gradients(grads=alpha_grad)

    target = optax.incremental_update(critic.params, state.target_critic_params, config.tau)
    new_state = SACState(actor, critic, target, log_alpha, rng)
    return new_state, {**info, **actor_info, "alpha": jnp.exp(log_alpha.params["log_alpha"])}

