"""Implicit Q-Learning (Kostrikov, Nair & Levine 2022): pure losses composed in one jitted update.

As in the reference implementation (ikostrikov/implicit_q_learning, ``learner.py: _update_jit``):
V is an expectile regression of the target twin-Q minimum, the actor is advantage-weighted regression
with weights ``exp(temperature * (Q - V))`` clipped at 100, Q regresses ``r + discount * mask * V(s')``,
then the target critic moves by ``tau``. The actor is the reference's locomotion actor: a Gaussian with a
tanh-squashed mean and a learned state-independent log-std, its learning rate cosine-decayed to zero over
the run; evaluation acts with the mean. Rewards are used as given unless ``normalize_rewards`` asks for the
reference's locomotion scaling, ``1000 / (max episode return - min episode return)``.

A batch may carry per-transition weights (:mod:`xted.rl.source_weighting`: IGDF's and OTDF's
filters): ``sample_weight`` (0 drops a transition from every loss) and ``q_weight`` (the critic's
weight of each kept one); ``actor_penalty(obs, mean_action)`` adds a per-state term to the actor
loss (OTDF's behaviour regulariser). Without them every transition weighs 1.
"""

from __future__ import annotations

import math

import flax
import jax
import jax.numpy as jnp
import numpy as np
import optax
from flax.training.train_state import TrainState

from xted.rl.config import IQLConfig
from xted.rl.networks import Critic, GaussianPolicy, ValueNet, gaussian_log_prob


@flax.struct.dataclass
class IQLState:
    actor: TrainState
    critic: TrainState
    target_critic_params: dict
    value: TrainState


def init_iql(rng, obs_dim: int, action_dim: int, config: IQLConfig, steps: int) -> IQLState:
    """Fresh networks; ``steps`` is the run's length, over which the actor's learning rate decays."""
    actor_key, critic_key, value_key = jax.random.split(rng, 3)
    obs, act = jnp.zeros((1, obs_dim)), jnp.zeros((1, action_dim))
    actor_def = GaussianPolicy(config.hidden, action_dim)
    critic_def, value_def = Critic(config.hidden), ValueNet(config.hidden)
    actor = TrainState.create(apply_fn=actor_def.apply, params=actor_def.init(actor_key, obs)["params"],
                              tx=optax.adam(optax.cosine_decay_schedule(config.actor_lr, max(steps, 1))))
    critic_params = critic_def.init(critic_key, obs, act)["params"]
    critic = TrainState.create(apply_fn=critic_def.apply, params=critic_params, tx=optax.adam(config.critic_lr))
    value = TrainState.create(apply_fn=value_def.apply, params=value_def.init(value_key, obs)["params"],
                              tx=optax.adam(config.value_lr))
    return IQLState(actor, critic, critic_params, value)


def expectile_loss(diff, expectile: float):
    weight = jnp.where(diff > 0, expectile, 1.0 - expectile)
    return weight * diff**2


def _target_q(state: IQLState, batch):
    q = state.critic.apply_fn({"params": state.target_critic_params}, batch["observations"], batch["actions"])
    return q.min(axis=0)


def batch_mean(values, batch, weight: str = "sample_weight"):
    """The mean over the batch's last axis, weighted by ``batch[weight]`` where the batch has weights
    (normalised by the kept transitions' count, ``sample_weight``'s sum)."""
    if "sample_weight" not in batch:
        return values.mean(axis=-1)
    return (batch[weight] * values).sum(axis=-1) / jnp.maximum(batch["sample_weight"].sum(), 1.0)


def value_loss(value_params, state: IQLState, batch, config: IQLConfig):
    v = state.value.apply_fn({"params": value_params}, batch["observations"])
    loss = batch_mean(expectile_loss(_target_q(state, batch) - v, config.expectile), batch)  # IQL Eq. 5
    return loss, {"value_loss": loss, "v": v.mean()}


def actor_loss(actor_params, state: IQLState, batch, config: IQLConfig, actor_penalty=None):
    advantage = _target_q(state, batch) - state.value.apply_fn({"params": state.value.params}, batch["observations"])
    weights = jnp.minimum(jnp.exp(config.temperature * advantage), config.max_weight)
    mean, log_std = state.actor.apply_fn({"params": actor_params}, batch["observations"])
    per_state = -weights * gaussian_log_prob(mean, log_std, batch["actions"])  # IQL Eq. 7 (AWR)
    if actor_penalty is not None:
        per_state = per_state + actor_penalty(batch["observations"], mean)
    loss = batch_mean(per_state, batch)
    return loss, {"actor_loss": loss, "advantage": advantage.mean()}


def critic_loss(critic_params, state: IQLState, batch, config: IQLConfig):
    next_v = state.value.apply_fn({"params": state.value.params}, batch["next_observations"])
    target = batch["rewards"] + config.discount * (1.0 - batch["terminals"]) * next_v  # IQL Eq. 6
    q = state.critic.apply_fn({"params": critic_params}, batch["observations"], batch["actions"])
    loss = batch_mean((q - target) ** 2, batch, "q_weight").sum()
    return loss, {"critic_loss": loss, "q": q.mean()}


def iql_step(state: IQLState, batch, config: IQLConfig, step=None, actor_penalty=None):
    """One IQL step: value, then actor (on the new value), then critic, then the target critic.
    ``step`` schedules nothing here (the actor's learning-rate decay counts its own steps)."""
    grads, info = jax.grad(value_loss, has_aux=True)(state.value.params, state, batch, config)
    state = state.replace(value=state.value.apply_gradients(grads=grads))
    grads, actor_info = jax.grad(actor_loss, has_aux=True)(state.actor.params, state, batch, config, actor_penalty)
    state = state.replace(actor=state.actor.apply_gradients(grads=grads))
    grads, critic_info = jax.grad(critic_loss, has_aux=True)(state.critic.params, state, batch, config)
    critic = state.critic.apply_gradients(grads=grads)
    target = optax.incremental_update(critic.params, state.target_critic_params, config.tau)
    return state.replace(critic=critic, target_critic_params=target), {**info, **actor_info, **critic_info}


def iql_act(actor: TrainState, obs):
    """The mean action."""
    return actor.apply_fn({"params": actor.params}, obs)[0]


def locomotion_reward_scale(episode_returns: np.ndarray) -> float:
    """The reference's locomotion reward scale, ``1000 / (max return - min return)`` (1 if all equal)."""
    spread = float(np.max(episode_returns) - np.min(episode_returns))
    return 1000.0 / spread if spread > 0 and math.isfinite(spread) else 1.0
