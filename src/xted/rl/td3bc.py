"""TD3+BC (Fujimoto & Gu 2021): pure losses composed in one jitted update.

TD3's twin critics with target policy smoothing (noise 0.2 clipped at 0.5) and a delayed actor
(every 2nd critic step) whose loss is ``-lambda * Q1(s, pi(s)) + (pi(s) - a)^2`` with
``lambda = alpha / mean|Q1|`` (alpha 2.5); both targets move by ``tau`` on actor steps only.
Offline, the learning rates default to the xTED paper's (actor 1e-5, critic 1e-3): on 20k
transitions they beat the TD3+BC paper's 3e-4 for both (BENCHMARKS.md, "TD3+BC"); online TD3 keeps 3e-4.

``behaviour_cloning=False`` is TD3 itself (Fujimoto et al. 2018, actor loss ``-Q1(s, pi(s))``), the
online learner of :mod:`xted.rl.online`.
"""

from __future__ import annotations

from functools import partial

import flax
import jax
import jax.numpy as jnp
import optax
from flax.training.train_state import TrainState

from xted.rl.config import TD3BCConfig
from xted.rl.networks import Critic, DeterministicPolicy, require_no_actor_penalty


@flax.struct.dataclass
class TD3BCState:
    actor: TrainState
    critic: TrainState
    target_actor_params: dict
    target_critic_params: dict
    rng: jax.Array


def init_td3bc(rng, obs_dim: int, action_dim: int, config: TD3BCConfig, steps: int) -> TD3BCState:
    """Fresh networks (``steps``, the run's length, schedules nothing here: the learning rates are constant)."""
    actor_key, critic_key, rng = jax.random.split(rng, 3)
    obs, act = jnp.zeros((1, obs_dim)), jnp.zeros((1, action_dim))
    actor_def, critic_def = DeterministicPolicy(config.hidden, action_dim), Critic(config.hidden)
    actor_params = actor_def.init(actor_key, obs)["params"]
    critic_params = critic_def.init(critic_key, obs, act)["params"]
    actor = TrainState.create(apply_fn=actor_def.apply, params=actor_params, tx=optax.adam(config.actor_lr))
    critic = TrainState.create(apply_fn=critic_def.apply, params=critic_params, tx=optax.adam(config.critic_lr))
    return TD3BCState(actor, critic, actor_params, critic_params, rng)


def critic_loss(critic_params, state: TD3BCState, batch, rng, config: TD3BCConfig):
    noise = jnp.clip(config.policy_noise * jax.random.normal(rng, batch["actions"].shape),
                     -config.noise_clip, config.noise_clip)
    next_action = state.actor.apply_fn({"params": state.target_actor_params}, batch["next_observations"])
    next_action = jnp.clip(next_action + noise, -1.0, 1.0)
    next_q = state.critic.apply_fn({"params": state.target_critic_params}, batch["next_observations"], next_action)
    target = batch["rewards"] + config.discount * (1.0 - batch["terminals"]) * next_q.min(axis=0)
    q = state.critic.apply_fn({"params": critic_params}, batch["observations"], batch["actions"])
    loss = ((q - target) ** 2).mean(axis=-1).sum()
    return loss, {"critic_loss": loss, "q": q.mean()}


def actor_loss(actor_params, state: TD3BCState, batch, config: TD3BCConfig):
    pi = state.actor.apply_fn({"params": actor_params}, batch["observations"])
    q = state.critic.apply_fn({"params": state.critic.params}, batch["observations"], pi)[0]
    if not config.behaviour_cloning:
        return -q.mean(), {"actor_loss": -q.mean(), "bc_loss": jnp.zeros(())}
    lmbda = config.alpha / jax.lax.stop_gradient(jnp.abs(q).mean())  # TD3+BC (Fujimoto & Gu) Eq. 5
    bc = ((pi - batch["actions"]) ** 2).mean()
    loss = -lmbda * q.mean() + bc  # TD3+BC Eq. 3
    return loss, {"actor_loss": loss, "bc_loss": bc}


@partial(jax.jit, static_argnames="config")
def td3bc_update(state: TD3BCState, batch, config: TD3BCConfig, step=None, actor_penalty=None):
    """One critic step; every ``policy_delay``-th also an actor step and the target updates.

    ``step`` (default: the critic's own step count) is the index that schedules the actor step.

    On critic-only steps the actor entries of the returned info are NaN (not computed).
    """
    require_no_actor_penalty(actor_penalty, "TD3+BC")
    rng, noise_key = jax.random.split(state.rng)
    grads, info = jax.grad(critic_loss, has_aux=True)(state.critic.params, state, batch, noise_key, config)
    state = state.replace(critic=state.critic.apply_gradients(grads=grads), rng=rng)

    def actor_step(state: TD3BCState):
        grads, actor_info = jax.grad(actor_loss, has_aux=True)(state.actor.params, state, batch, config)
        actor = state.actor.apply_gradients(grads=grads)
        return state.replace(
            actor=actor,
            target_actor_params=optax.incremental_update(actor.params, state.target_actor_params, config.tau),
            target_critic_params=optax.incremental_update(state.critic.params, state.target_critic_params, config.tau),
        ), actor_info

    def critic_only(state: TD3BCState):
        nan = jnp.full((), jnp.nan, jnp.float32)
        return state, {"actor_loss": nan, "bc_loss": nan}

    step = state.critic.step if step is None else step
    state, actor_info = jax.lax.cond(step % config.policy_delay == 0, actor_step, critic_only, state)
    return state, {**info, **actor_info}
