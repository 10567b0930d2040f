"""The training objective: epsilon-prediction MSE with the first transition of every window held
clean (inpainting) and excluded, the optimiser, and one jitted train step (a pure function).

Every unmasked scalar counts equally: the squared errors of all streams are summed and divided by
the number of unmasked elements (``unmasked steps * (ds + da + 1)``), so a 17-d state weighs 17
times a reward.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import flax.struct
import jax
import jax.numpy as jnp
import optax

from xted.diffusion.config import PriorConfig
from xted.diffusion.denoiser import Denoiser, apply_inverse, init_params
from xted.diffusion.schedule import Schedule, cosine_schedule, q_sample

# Per-sample loss weight as a function of the signal-to-noise ratio of the sampled timestep.
LOSS_WEIGHTS: dict[str, Callable[[jnp.ndarray], jnp.ndarray]] = {
    "uniform": jnp.ones_like,
    "min_snr": lambda snr: jnp.minimum(snr, 5.0) / snr,  # Min-SNR-5 (Hang et al. 2023), eps-prediction
}

@flax.struct.dataclass
class TrainState:
    params: Any
    ema_params: Any
    opt_state: Any
    step: jnp.ndarray


def learning_rate(config: PriorConfig, step: jnp.ndarray) -> jnp.ndarray:
    step = jnp.asarray(step, jnp.float32)
    lr = jnp.float32(config.learning_rate)
    if config.warmup_steps:
        lr = lr * jnp.minimum(1.0, (step + 1) / config.warmup_steps)
    if config.decay_steps is not None:
        progress = jnp.clip(step / config.decay_steps, 0.0, 1.0)
        lr = lr * (0.1 + 0.45 * (1 + jnp.cos(jnp.pi * progress)))
    return lr


def make_optimizer(config: PriorConfig) -> optax.GradientTransformation:
    """Adam after global-norm clipping, on the flattened parameter vector (one fused update
    instead of one per parameter array: faster to compile and to run on a CPU)."""
    adam = optax.adam(functools.partial(learning_rate, config))
    if config.grad_clip is not None:
        adam = optax.chain(optax.clip_by_global_norm(config.grad_clip), adam)
    return optax.flatten(adam)


@functools.partial(jax.jit, static_argnums=0)
def init_train_state(config: PriorConfig, rng: jax.Array) -> TrainState:
    """Fresh parameters (EMA equal to them), optimiser state and step 0."""
    h = config.horizon
    dummy = lambda d: jnp.zeros((1, h, d), jnp.float32)  # noqa: E731
    params = init_params(
        config.denoiser, rng, dummy(config.state_dim), dummy(config.action_dim),
        dummy(1) if config.use_reward else None, jnp.zeros(1, jnp.int32), jnp.zeros(1, jnp.float32), jnp.zeros(1, bool),
    )
    return TrainState(
        params=params,
        ema_params=jax.tree.map(jnp.copy, params),
        opt_state=make_optimizer(config).init(params),
        step=jnp.zeros((), jnp.int32),
    )


def loss_fn(
    params: Any, batch: dict[str, jnp.ndarray], rng: jax.Array, *, model: Denoiser, schedule: Schedule,
    config: PriorConfig,
) -> tuple[jnp.ndarray, dict[str, jnp.ndarray]]:
    """Masked epsilon MSE. ``batch``: one ``[B, H, d]`` array per stream ("state", "action",
    "reward"), ``loss_mask [B, H]`` and ``returns [B]`` (normalised to [0, 1]).

    Inv adds the MSE of its inverse models on the window's clean transitions (every one of them,
    the held first included); ``mse_action`` / ``mse_reward`` then report those."""
    streams = config.denoiser.diffused_streams
    mask = batch["loss_mask"].astype(jnp.float32)
    b = mask.shape[0]
    t_rng, drop_rng, noise_rng = jax.random.split(rng, 3)
    t = jax.random.randint(t_rng, (b,), 0, config.trained_noise_steps)
    noise = {s: jax.random.normal(jax.random.fold_in(noise_rng, i), batch[s].shape) for i, s in enumerate(streams)}
    x_t = {s: batch[s] for s in config.denoiser.streams}  # streams not diffused are read by no model
    for s in streams:
        noised = q_sample(schedule, batch[s], t, noise[s])
        x_t[s] = noised.at[:, 0].set(batch[s][:, 0])
    drop = jax.random.bernoulli(drop_rng, config.condition_dropout, (b,))
    returns = batch["returns"] if config.return_condition else None
    eps = model.apply(params, x_t["state"], x_t["action"], x_t.get("reward"), t, returns, drop)
    abar = schedule.alphas_cumprod[t]
    weight = LOSS_WEIGHTS[config.loss_weighting](abar / (1 - abar))
    metrics, total = {}, 0.0
    for s, e in zip(streams, eps):
        se = jnp.sum(jnp.square(e - noise[s]), axis=-1) * mask  # xTED Eq. 5 (Eq. 12 with returns); Ho et al. Eq. 14
        metrics[f"mse_{s}"] = jnp.sum(se) / (jnp.sum(mask) * e.shape[-1])
        total = total + jnp.sum(weight[:, None] * se)
    dims = sum(config.denoiser.element_dim(s) for s in streams)
    loss = total / (jnp.sum(mask) * dims)
    if config.architecture == "inverse_dynamics":
        predicted = apply_inverse(config.denoiser, params, batch["state"], batch["action"])
        for s, p in zip(("action", "reward"), predicted):
            if p is not None:
                metrics[f"mse_{s}"] = jnp.mean(jnp.square(p - batch[s][:, :-1]))
                loss = loss + metrics[f"mse_{s}"]
    return loss, {"loss": loss, **metrics}


def ema_decay(decay: float, step: jnp.ndarray) -> jnp.ndarray:
    """The EMA's decay at ``step``, warmed up as ``min(decay, (1 + step) / (10 + step))``: the average
    starts at the random initial weights, which a fixed 0.999 keeps at 67% weight after 400 steps
    (a short run edited with mostly untrained weights); from about 10k steps on it is ``decay``."""
    return jnp.minimum(decay, (1.0 + step) / (10.0 + step))


def train_step(
    state: TrainState, batch: dict[str, jnp.ndarray], rng: jax.Array, *, model: Denoiser,
    optimizer: optax.GradientTransformation, schedule: Schedule, config: PriorConfig,
) -> tuple[TrainState, dict[str, jnp.ndarray]]:
    """One update: gradient of :func:`loss_fn` (noise from ``rng`` folded with the step), optimiser, EMA."""
    step_rng = jax.random.fold_in(rng, state.step)
    grads, metrics = jax.grad(loss_fn, has_aux=True)(
        state.params, batch, step_rng, model=model, schedule=schedule, config=config
    )
    updates, opt_state = optimizer.update(grads, state.opt_state, state.params)
    params = optax.apply_updates(state.params, updates)
    d = ema_decay(config.ema_decay, state.step)
    ema = jax.tree.map(lambda e, p: d * e + (1 - d) * p, state.ema_params, params)
    return TrainState(params, ema, opt_state, state.step + 1), metrics


@functools.lru_cache(maxsize=8)
def make_train_step(config: PriorConfig) -> Callable[..., tuple[TrainState, dict[str, jnp.ndarray]]]:
    """``train_step`` bound to ``config`` and jitted: ``(state, batch, rng) -> (state, metrics)``."""
    return jax.jit(
        functools.partial(
            train_step, model=Denoiser(config.denoiser), optimizer=make_optimizer(config),
            schedule=cosine_schedule(config.num_timesteps), config=config,
        )
    )
