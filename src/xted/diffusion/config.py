"""The prior's configuration: one flat, validating record (every field a ``--set FIELD=VALUE``) and
the named presets."""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import jax.numpy as jnp

from xted.diffusion.denoiser import ARCHITECTURES, DenoiserConfig
from xted.errors import InputError

# Per-sample loss weight as a function of the signal-to-noise ratio of the sampled timestep.
LOSS_WEIGHTS: dict[str, Callable[[jnp.ndarray], jnp.ndarray]] = {
    "uniform": jnp.ones_like,
    "min_snr": lambda snr: jnp.minimum(snr, 5.0) / snr,  # Min-SNR-5 (Hang et al. 2023), eps-prediction
}

_DENOISER_FIELDS = tuple(f.name for f in dataclasses.fields(DenoiserConfig))


@dataclass(frozen=True)
class PriorConfig(DenoiserConfig):
    """The denoiser's architecture (the fields of :class:`DenoiserConfig`), diffusion and
    optimisation, in one flat record so that every field is a ``--set FIELD=VALUE`` override.

    Learning rate: linear warm-up over ``warmup_steps``, then constant, or, with ``decay_steps``,
    multiplied by a cosine from 1 at step 0 to 0.1 at ``decay_steps`` (constant after).
    """

    num_timesteps: int = 200
    batch_size: int = 256
    learning_rate: float = 2e-4
    warmup_steps: int = 0
    decay_steps: int | None = None
    grad_clip: float | None = 1.0
    ema_decay: float = 0.999
    condition_dropout: float = 0.25
    loss_weighting: str = "uniform"
    seed: int = 0

    def __post_init__(self) -> None:
        checks = [
            (self.state_dim >= 1 and self.action_dim >= 1, "state_dim and action_dim must be >= 1"),
            (self.horizon >= 2, f"horizon must be >= 2, got {self.horizon}"),
            (self.num_timesteps >= 1, f"num_timesteps must be >= 1, got {self.num_timesteps}"),
            (self.batch_size >= 1, f"batch_size must be >= 1, got {self.batch_size}"),
            (self.warmup_steps >= 0, f"warmup_steps must be >= 0, got {self.warmup_steps}"),
            (self.decay_steps is None or self.decay_steps >= 1, f"decay_steps must be >= 1, got {self.decay_steps}"),
            (0.0 <= self.ema_decay < 1.0, f"ema_decay must be in [0, 1), got {self.ema_decay}"),
            (0.0 <= self.condition_dropout <= 1.0,
             f"condition_dropout must be in [0, 1], got {self.condition_dropout}"),
            (self.loss_weighting in LOSS_WEIGHTS, f"loss_weighting must be one of {sorted(LOSS_WEIGHTS)}"),
            (self.architecture in ARCHITECTURES,
             f"architecture must be one of {list(ARCHITECTURES)}, got {self.architecture!r}"),
            (min(map(self.denoiser.width, self.denoiser.streams)) >= 1, "every stream width must be >= 1"),
        ]
        for ok, message in checks:
            if not ok:
                raise InputError(f"PriorConfig: {message}")

    @property
    def denoiser(self) -> DenoiserConfig:
        return DenoiserConfig(**{name: getattr(self, name) for name in _DENOISER_FIELDS})

    def to_dict(self) -> dict[str, Any]:
        return json.loads(json.dumps(dataclasses.asdict(self)))

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> PriorConfig:
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = set(data) - names
        if unknown:
            raise InputError(f"PriorConfig: unknown fields {sorted(unknown)}")
        return cls(**data)


def _paper(state_dim: int, action_dim: int) -> PriorConfig:
    """The paper's setup (appendix hyperparameter table). Optimiser settings are not stated there;
    Adam at 2e-4 with batch 256 follows Diffuser / Decision Diffuser, plus a short warm-up."""
    return PriorConfig(
        state_dim=state_dim, action_dim=action_dim, width_multiplier=16, state_blocks=2, action_blocks=2,
        reward_blocks=1, horizon=20, num_timesteps=200, batch_size=256, learning_rate=2e-4,
        warmup_steps=1000, return_condition=True,
    )


def _cpu(state_dim: int, action_dim: int) -> PriorConfig:
    """Small, fast configuration for a 2-core CPU: stream widths 4x the element's dim (at least 32),
    one block per stream, batch 128 (about 3.4 GFLOP per step; BENCHMARKS.md has the curve that chose it)."""
    return PriorConfig(
        state_dim=state_dim, action_dim=action_dim, width_multiplier=4, min_width=32, state_blocks=1,
        action_blocks=1, reward_blocks=1, cond_dim=64, horizon=20, num_timesteps=200, batch_size=128, learning_rate=1e-3,
        warmup_steps=500, decay_steps=50_000, return_condition=True,
    )


def presets() -> dict[str, Callable[[int, int], PriorConfig]]:
    """Named configurations as functions of ``(state_dim, action_dim)``."""
    return {"paper": _paper, "cpu": _cpu}


def preset(name: str, state_dim: int, action_dim: int, **overrides: Any) -> PriorConfig:
    """``presets()[name](state_dim, action_dim)`` with fields replaced by ``overrides``."""
    table = presets()
    if name not in table:
        raise InputError(f"unknown prior preset {name!r}; expected one of {sorted(table)}")
    return dataclasses.replace(table[name](state_dim, action_dim), **overrides)
