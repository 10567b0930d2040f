"""Noise schedule and samplers (DDPM; DDIM, deterministic or with eta > 0) for epsilon-prediction models.

Index convention (as in diffusers): timesteps are ``t = 0 .. K-1``; ``x_t`` carries the noise of
``t + 1`` forward steps. "Noise to step k" (``k`` in ``1..K``) samples ``x`` at ``t = k - 1`` and
the reverse chain then runs ``t = k-1, ..., 0``: exactly ``k`` model calls. ``k = 0`` is no noise.

``clip`` (samplers): bound for the predicted ``x_0`` in normalised units, or None (no clipping).
``temperature`` (samplers): scale of the fresh noise a step adds (1: the model's posterior; 0: its
mean only), as Diffuser's and the original xTED code's ``sample_temperature`` (0.5 there).
"""

from __future__ import annotations

import flax.struct
import jax.numpy as jnp
import numpy as np

from xted.errors import InputError


@flax.struct.dataclass
class Schedule:
    """Per-timestep coefficients, each an array of length ``K``."""

    betas: jnp.ndarray
    alphas_cumprod: jnp.ndarray
    alphas_cumprod_prev: jnp.ndarray
    posterior_mean_coef1: jnp.ndarray
    posterior_mean_coef2: jnp.ndarray
    posterior_log_variance: jnp.ndarray

    @property
    def num_timesteps(self) -> int:
        return self.betas.shape[0]


def cosine_schedule(num_timesteps: int = 200, s: float = 0.008, max_beta: float = 0.999) -> Schedule:
    """Cosine schedule of Nichol & Dhariwal (2021), computed in float64, stored in float32."""
    steps = np.arange(num_timesteps + 1, dtype=np.float64) / num_timesteps
    f = np.cos((steps + s) / (1 + s) * np.pi / 2) ** 2
    betas = np.minimum(1 - f[1:] / f[:-1], max_beta)
    alphas = 1 - betas
    alphas_cumprod = np.cumprod(alphas)
    alphas_cumprod_prev = np.concatenate([[1.0], alphas_cumprod[:-1]])
    posterior_variance = betas * (1 - alphas_cumprod_prev) / (1 - alphas_cumprod)
    # At t = 0 the posterior variance is 0; its log is taken from t = 1 (never used: no noise at t = 0).
    posterior_log_variance = np.log(np.concatenate([posterior_variance[1:2], posterior_variance[1:]]))
    f32 = lambda a: jnp.asarray(a, dtype=jnp.float32)  # noqa: E731
    return Schedule(
        betas=f32(betas),
        alphas_cumprod=f32(alphas_cumprod),
        alphas_cumprod_prev=f32(alphas_cumprod_prev),
        posterior_mean_coef1=f32(betas * np.sqrt(alphas_cumprod_prev) / (1 - alphas_cumprod)),
        posterior_mean_coef2=f32((1 - alphas_cumprod_prev) * np.sqrt(alphas) / (1 - alphas_cumprod)),
        posterior_log_variance=f32(posterior_log_variance),
    )


def _per_sample(values: jnp.ndarray, t: jnp.ndarray, like: jnp.ndarray) -> jnp.ndarray:
    """``values[t]`` for a ``[B]`` (or scalar) ``t``, shaped to broadcast against ``like`` ``[B, ...]``."""
    v = values[t]
    return jnp.reshape(v, jnp.shape(v) + (1,) * (like.ndim - jnp.ndim(v)))


def q_sample(schedule: Schedule, x0: jnp.ndarray, t: jnp.ndarray, noise: jnp.ndarray) -> jnp.ndarray:
    """Sample ``x_t ~ q(x_t | x_0)`` (xTED Eq. 2; Ho et al. 2020, Eq. 4)."""
    abar = _per_sample(schedule.alphas_cumprod, t, x0)
    return jnp.sqrt(abar) * x0 + jnp.sqrt(1 - abar) * noise


def predict_x0(
    schedule: Schedule, x_t: jnp.ndarray, t: jnp.ndarray, eps: jnp.ndarray, clip: float | None = None
) -> jnp.ndarray:
    """``x_0`` implied by the predicted noise (Ho et al. 2020, Eq. 15), optionally clipped to ``[-clip, clip]``."""
    abar = _per_sample(schedule.alphas_cumprod, t, x_t)
    x0 = (x_t - jnp.sqrt(1 - abar) * eps) / jnp.sqrt(abar)
    return x0 if clip is None else jnp.clip(x0, -clip, clip)


def ddpm_step(
    schedule: Schedule,
    x_t: jnp.ndarray,
    t: jnp.ndarray,
    eps: jnp.ndarray,
    noise: jnp.ndarray,
    clip: float | None = None,
    temperature: float = 1.0,
) -> jnp.ndarray:
    """One ancestral step ``x_t -> x_{t-1}`` (Ho et al. 2020, Eq. 6-7): posterior mean plus
    ``temperature * sigma_t * noise`` (none at t = 0)."""
    x0 = predict_x0(schedule, x_t, t, eps, clip)
    mean = (
        _per_sample(schedule.posterior_mean_coef1, t, x_t) * x0
        + _per_sample(schedule.posterior_mean_coef2, t, x_t) * x_t
    )
    sigma = jnp.exp(0.5 * _per_sample(schedule.posterior_log_variance, t, x_t))
    nonzero = _per_sample(jnp.arange(schedule.num_timesteps) > 0, t, x_t)
    return mean + jnp.where(nonzero, temperature * sigma * noise, 0.0)


def ddim_step(
    schedule: Schedule,
    x_t: jnp.ndarray,
    t: jnp.ndarray,
    t_prev: jnp.ndarray,
    eps: jnp.ndarray,
    clip: float | None = None,
    eta: float = 0.0,
    noise: jnp.ndarray | None = None,
    temperature: float = 1.0,
) -> jnp.ndarray:
    """DDIM step from ``t`` to ``t_prev`` (Song et al. 2021, Eq. 12 and 16); ``t_prev = -1`` gives
    ``x_0``. ``eta = 0`` is deterministic; ``eta = 1`` adds the DDPM posterior's variance, drawn
    from ``noise`` scaled by ``temperature``."""
    x0 = predict_x0(schedule, x_t, t, eps, clip)
    abar = _per_sample(schedule.alphas_cumprod, t, x_t)
    abar_prev = jnp.where(t_prev >= 0, schedule.alphas_cumprod[jnp.maximum(t_prev, 0)], 1.0)
    abar_prev = jnp.reshape(abar_prev, jnp.shape(abar_prev) + (1,) * (x_t.ndim - jnp.ndim(abar_prev)))
    if eta == 0.0 or noise is None:
        return jnp.sqrt(abar_prev) * x0 + jnp.sqrt(1 - abar_prev) * eps
    sigma = eta * jnp.sqrt((1 - abar_prev) / (1 - abar) * (1 - abar / abar_prev))
    direction = jnp.sqrt(jnp.maximum(1 - abar_prev - sigma**2, 0.0)) * eps
    return jnp.sqrt(abar_prev) * x0 + direction + temperature * sigma * noise


def ddim_timesteps(k: int, n_steps: int) -> np.ndarray:
    """``n_steps`` distinct timesteps decreasing from ``k - 1`` to 0 (just ``[k - 1]`` when ``n_steps == 1``)."""
    if not 1 <= n_steps <= k:
        raise InputError(f"ddim_timesteps: need 1 <= n_steps <= k, got n_steps={n_steps}, k={k}")
    if n_steps == 1:
        return np.array([k - 1], dtype=np.int32)
    return np.round(np.linspace(k - 1, 0, n_steps)).astype(np.int32)
