"""Behaviour cloning: a deterministic tanh actor regressed on the dataset's actions (MSE).

The learning rate defaults to 3e-4 (TD3+BC's BC baseline on MuJoCo); the xTED paper's robot
setting uses 1e-4, available through ``learning_rate``.
"""

from __future__ import annotations

from functools import partial

import flax
import jax
import jax.numpy as jnp
import optax
from flax.training.train_state import TrainState

from xted.rl.config import BCConfig
from xted.rl.networks import DeterministicPolicy, require_no_actor_penalty


@flax.struct.dataclass
class BCState:
    actor: TrainState


def init_bc(rng, obs_dim: int, action_dim: int, config: BCConfig, steps: int) -> BCState:
    """Fresh networks (``steps``, the run's length, schedules nothing here: the learning rate is constant)."""
    actor_def = DeterministicPolicy(config.hidden, action_dim)
    params = actor_def.init(rng, jnp.zeros((1, obs_dim)))["params"]
    return BCState(TrainState.create(apply_fn=actor_def.apply, params=params, tx=optax.adam(config.learning_rate)))


def bc_loss(actor_params, actor: TrainState, batch):
    loss = ((actor.apply_fn({"params": actor_params}, batch["observations"]) - batch["actions"]) ** 2).mean()
    return loss, {"bc_loss": loss}


@partial(jax.jit, static_argnames="config")
def bc_update(state: BCState, batch, config: BCConfig, step, actor_penalty=None):
    """One regression step (``config`` and ``step`` schedule nothing here)."""
    require_no_actor_penalty(actor_penalty, "BC")
    grads, info = jax.grad(bc_loss, has_aux=True)(state.actor.params, state.actor, batch)
    return BCState(state.actor.apply_gradients(grads=grads)), info


def deterministic_act(actor: TrainState, obs):
    """The actor's action (BC and TD3+BC)."""
    return actor.apply_fn({"params": actor.params}, obs)
