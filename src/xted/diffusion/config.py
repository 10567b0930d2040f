"""The diffusion configurations: the denoiser's architecture, the prior's one flat, validating
record (every field a ``--set FIELD=VALUE``) with its named presets, and how to edit. Plain
Python: the CLI takes its defaults from here without loading JAX."""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from xted.fields import known_fields, setting
from xted.errors import InputError

# Per-sample loss weightings by the signal-to-noise ratio of the sampled timestep (xted.diffusion.objective).
LOSS_WEIGHTINGS = ("uniform", "min_snr")

STREAMS = ("state", "action", "reward")

# Cross-attention wiring: (updated stream, streams it attends to), xTED Eq. 7 (states <-> actions) and Eq. 8
# (rewards query states and actions).
# State and action exchange information both ways; the reward stream queries the concatenation
# (along the token axis, 2H keys) of state and action, and nothing attends to the reward stream,
# so rewards never feed back into states or actions. All cross blocks read the self-attended
# representations from *before* any cross block (h'_r draws on h_s and h_a, not h'_s and h'_a),
# so the three updates are simultaneous. (The appendix formula updates x_kv instead of x_q; that
# contradicts the stated intent and is not followed.)
CROSS_WIRING: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("state", ("action",)),
    ("action", ("state",)),
    ("reward", ("state", "action")),
)


# The paper's architecture ablations (its Tables 6-7), all in this module's one code path:
# "xted" the model above; "causal" the same with every attention causal in time (CM);
# "feature_concat" one token per step holding [s, a, r] (FC); "temporal_concat" the 2H or 3H
# element tokens s_0, a_0, r_0, s_1, ... in one sequence at the state stream's width (TC).
# FC and TC run ``state_blocks + 1`` self-attention blocks: the xTED state stream's depth.
# "inverse_dynamics" diffuses states only (one stream, ``state_blocks + 1`` blocks) and fills in
# actions and rewards with inverse models trained beside it (Inv, :class:`InverseDynamics`).
# "temporal_unet" is the paper's non-transformer baseline (its appendix comparison): Diffuser's
# temporal U-Net over the [s, a, r] sequence (see :func:`_temporal_unet`).
ARCHITECTURES = ("xted", "causal", "feature_concat", "temporal_concat", "inverse_dynamics", "temporal_unet")


@dataclass(frozen=True)
class DenoiserConfig:
    """Architecture. Stream width = ``width_override`` if set, else
    ``round(width_multiplier * element_dim)`` bounded to ``[min_width, max_width]`` ("joint", the FC
    token, has the summed dims of the streams)."""

    state_dim: int = setting(dataclasses.MISSING, "Observation dimension (from the data).")
    action_dim: int = setting(dataclasses.MISSING, "Action dimension (from the data).")
    use_reward: bool = setting(True, "Diffuse a reward stream beside states and actions (off for reward-free data).")
    width_multiplier: float = setting(16, "Stream width = this x the element's dimension (the paper: 16).")
    min_width: int = setting(0, "Smallest stream width.")
    max_width: int | None = setting(None, "Largest stream width (none: unbounded).")
    width_override: int | None = setting(None, "One width for every stream, instead of the multiplier.")
    state_blocks: int = setting(2, "Self-attention blocks of the state stream.")
    action_blocks: int = setting(2, "Self-attention blocks of the action stream.")
    reward_blocks: int = setting(1, "Self-attention blocks of the reward stream.")
    cross_blocks: int = setting(1, "Rounds of the cross-attention wiring after the self-attention blocks "
                                   "(xted and causal; the paper: 1).")
    num_heads: int = setting(4, "Attention heads (reduced to a divisor of each stream's width).")
    mlp_ratio: int = setting(4, "Hidden width of each block's MLP, as a multiple of the stream width.")
    cond_dim: int = setting(128, "Width of the noise-step (and return) condition embedding.")
    return_condition: bool = setting(False, "Condition on the window's normalised return (classifier-free "
                                            "guidance, xTED Eq. 12-13).")
    horizon: int = setting(20, "Window length H in steps.")
    dtype: str = setting("float32", "Compute dtype of the denoiser (float32 or bfloat16).")
    architecture: str = setting("xted", "xted, or an ablation: " + ", ".join(ARCHITECTURES[1:]) + ".")

    @property
    def streams(self) -> tuple[str, ...]:
        return STREAMS if self.use_reward else STREAMS[:2]

    @property
    def diffused_streams(self) -> tuple[str, ...]:
        """The streams the denoiser predicts noise for (Inv: states only; its inverse models give the rest)."""
        return ("state",) if self.architecture == "inverse_dynamics" else self.streams

    @property
    def cross_wiring(self) -> tuple[tuple[str, tuple[str, ...]], ...]:
        """:data:`CROSS_WIRING` restricted to this model's streams."""
        present = set(self.streams)
        return tuple((u, kv) for u, kv in CROSS_WIRING if u in present and present.issuperset(kv))

    def element_dim(self, stream: str) -> int:
        if stream == "joint":
            return sum(map(self.element_dim, self.streams))
        return {"state": self.state_dim, "action": self.action_dim, "reward": 1}[stream]

    def width(self, stream: str) -> int:
        if self.width_override is not None:
            return self.width_override
        width = max(self.min_width, round(self.width_multiplier * self.element_dim(stream)))
        return width if self.max_width is None else min(width, self.max_width)

    def heads(self, stream: str) -> int:
        return math.gcd(self.num_heads, self.width(stream))

    def blocks(self, stream: str) -> int:
        return {"state": self.state_blocks, "action": self.action_blocks, "reward": self.reward_blocks}[stream]


_DENOISER_FIELDS = tuple(f.name for f in dataclasses.fields(DenoiserConfig))


@dataclass(frozen=True)
class PriorConfig(DenoiserConfig):
    """The denoiser's architecture (the fields of :class:`DenoiserConfig`), diffusion and
    optimisation, in one flat record so that every field is a ``--set FIELD=VALUE`` override.

    Learning rate: linear warm-up over ``warmup_steps``, then constant, or, with ``decay_steps``,
    multiplied by a cosine from 1 at step 0 to 0.1 at ``decay_steps`` (constant after).
    ``train_kappa_max``: training noise steps are drawn from ``0 .. round(train_kappa_max * K) - 1``
    only, the levels an edit up to that kappa visits (1: every level; a prior trained below 1
    refuses larger kappas).
    """

    num_timesteps: int = setting(200, "Diffusion steps K.")
    batch_size: int = setting(256, "Windows per training step.")
    learning_rate: float = setting(2e-4, "Peak Adam learning rate.")
    warmup_steps: int = setting(0, "Linear warm-up steps of the learning rate.")
    decay_steps: int | None = setting(None, "Cosine decay of the learning rate to 0.1x at this step (none: constant).")
    grad_clip: float | None = setting(1.0, "Global gradient-norm clip (none: off).")
    ema_decay: float = setting(0.999, "Decay of the parameters' exponential moving average (what edits use), "
                                      "reached after a warm-up of min(decay, (1 + step) / (10 + step)).")
    condition_dropout: float = setting(0.25, "Probability of dropping the return condition in training (for "
                                             "classifier-free guidance).")
    loss_weighting: str = setting("uniform", "Per-sample loss weight by noise level: " + " or ".join(LOSS_WEIGHTINGS)
                                  + ".")
    train_kappa_max: float = setting(1.0, "Train only on noise steps below this x K (the levels an edit up to "
                                          "this kappa visits).")
    seed: int = setting(0, "Seed of initialisation and batches.")

    def __post_init__(self) -> None:
        checks = [
            (self.state_dim >= 1 and self.action_dim >= 1, "state_dim and action_dim must be >= 1"),
            (self.horizon >= 2, f"horizon must be >= 2, got {self.horizon}"),
            (self.cross_blocks >= 1, f"cross_blocks must be >= 1, got {self.cross_blocks}"),
            (self.num_timesteps >= 1, f"num_timesteps must be >= 1, got {self.num_timesteps}"),
            (self.seed >= 0, f"seed must be >= 0, got {self.seed}"),
            (self.batch_size >= 1, f"batch_size must be >= 1, got {self.batch_size}"),
            (self.warmup_steps >= 0, f"warmup_steps must be >= 0, got {self.warmup_steps}"),
            (self.decay_steps is None or self.decay_steps >= 1, f"decay_steps must be >= 1, got {self.decay_steps}"),
            (0.0 <= self.ema_decay < 1.0, f"ema_decay must be in [0, 1), got {self.ema_decay}"),
            (0.0 <= self.condition_dropout <= 1.0,
             f"condition_dropout must be in [0, 1], got {self.condition_dropout}"),
            (self.loss_weighting in LOSS_WEIGHTINGS, f"loss_weighting must be one of {list(LOSS_WEIGHTINGS)}"),
            (0.0 < self.train_kappa_max <= 1.0 and self.trained_noise_steps >= 1,
             f"train_kappa_max must be in (0, 1] and cover at least one noise step, got {self.train_kappa_max}"),
            (self.architecture in ARCHITECTURES,
             f"architecture must be one of {list(ARCHITECTURES)}, got {self.architecture!r}"),
            (self.max_width is None or self.max_width >= self.min_width,
             f"max_width must be >= min_width, got {self.max_width} < {self.min_width}"),
            (min(map(self.denoiser.width, self.denoiser.streams)) >= 1, "every stream width must be >= 1"),
        ]
        for ok, message in checks:
            if not ok:
                raise InputError(f"PriorConfig: {message}")

    @property
    def trained_noise_steps(self) -> int:
        """Noise steps the prior is trained on: ``t < round(train_kappa_max * K)``."""
        return int(round(self.train_kappa_max * self.num_timesteps))

    @property
    def denoiser(self) -> DenoiserConfig:
        return DenoiserConfig(**{name: getattr(self, name) for name in _DENOISER_FIELDS})

    def to_dict(self) -> dict[str, Any]:
        return json.loads(json.dumps(dataclasses.asdict(self)))

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> PriorConfig:
        return cls(**known_fields(cls, data))


OUTSIDE_SUPPORT = ("keep", "drop", "edit")
GUARD_FIELDS = ("guard", "guard_margin", "guard_disagreement", "support_z", "outside_support")


@dataclass(frozen=True)
class EditConfig:
    """How to edit. ``guidance`` w: ``eps = eps_u + w (eps_c - eps_u)`` toward normalised return
    ``target_return``, used only with a return-conditioned prior; the default 0 edits
    unconditionally, as the paper's Table 1 does (guidance 1 toward 0.9 made IQL collapse on
    halfcheetah thigh: BENCHMARKS.md, "Which edited stream breaks the learner"). ``sampler_steps``:
    DDIM only (default ``k``). ``temperature``: scale of the fresh noise each reverse step adds
    (1: the model's own posterior; 0, the default: none, each step takes the posterior mean;
    BENCHMARKS.md, "Edit precision"). ``eta``: DDIM only, the share of the DDPM posterior's
    noise its steps add (0: deterministic). ``clip_denoised``: bound for the predicted ``x_0`` (normalised
    units) or None. ``hold_actions``: keep every source action and denoise states (and rewards)
    around them, as the first transition is held (inpainting), so the edit changes what the
    actions lead to, not the actions (an ablation). ``hold_first`` false with ``kappa = 1``
    generates episodes from pure noise (the paper's single-domain ``Tgt (Gen)``, its §5.4)."""

    kappa: float = setting(0.5, "Noise to step k = kappa*K, then denoise k steps.")
    iterations: int = setting(1, "Repeated noise+denoise rounds.")
    hold_first: bool = setting(True, "Hold each episode's first transition (false: generate it too; later "
                                     "windows stay stitched to the one before).")
    hold_actions: bool = setting(False, "Keep every source action; edit states (and rewards) around them.")
    guidance: float = setting(0.0, "Classifier-free return guidance weight (0: unconditional, as the paper's Table 1).")
    target_return: float = setting(0.9, "Normalised return that guidance steers toward.")
    sampler: str = setting("ddpm", "ddpm or ddim.")
    sampler_steps: int | None = setting(None, "DDIM steps (default k).")
    clip_denoised: float | None = setting(None, "Bound on the predicted x_0 in normalised units (none: off).")
    temperature: float = setting(0.0, "Scale of the noise each reverse step adds (0: none; 1: the model's own).")
    eta: float = setting(0.0, "DDIM only: share of the DDPM posterior's noise its steps add (0: deterministic).")
    dynamics_weight: float = setting(0.5, "With a dynamics model (--project-dynamics): each edited next state is "
                                          "this x the model's prediction + the rest x the prior's (1: the model's "
                                          "rollout).")
    batch_size: int = setting(1024, "Episodes edited side by side (windows per denoiser call).")
    seed: int = setting(0, "Seed of the forward noise (and reverse noise with temperature > 0).")
    guard: bool = setting(True, "Keep an edited window only where it is valid in the target and lowers the target "
                                "dynamics model's error by more than guard_margin x its resolution; else the source's "
                                "window (false: the paper's plain edit).")
    guard_margin: float = setting(1.0, "The gain an edited window must show, in units of the target model's "
                                       "resolution.")
    guard_disagreement: float = setting(0.0, "Also ask the gain to exceed this x the window's disagreement of the "
                                             "target model's ensemble (0: off; the ensemble: the prior's, or fitted "
                                             "to the target data given).")
    support_z: float = setting(10.0, "A source window with a state more than this many target standard deviations "
                                     "from the target's mean lies beyond the prior's support.")
    outside_support: str = setting("keep", "Windows beyond the support: keep (the source's, unedited), drop (left "
                                           "out) or edit (judged like the rest).")

    def __post_init__(self) -> None:
        checks = [
            (0.0 <= self.kappa <= 1.0, f"kappa must be in [0, 1], got {self.kappa}"),
            (self.iterations >= 1, f"iterations must be >= 1, got {self.iterations}"),
            (self.seed >= 0, f"seed must be >= 0, got {self.seed}"),
            (self.sampler in ("ddpm", "ddim"), f"sampler must be 'ddpm' or 'ddim', got {self.sampler!r}"),
            (self.sampler_steps is None or self.sampler == "ddim", "sampler_steps is for the ddim sampler only"),
            (self.sampler_steps is None or self.sampler_steps >= 1,
             f"sampler_steps must be >= 1, got {self.sampler_steps}"),
            (self.clip_denoised is None or self.clip_denoised > 0,
             f"clip_denoised must be > 0, got {self.clip_denoised}"),
            (self.batch_size >= 1, f"batch_size must be >= 1, got {self.batch_size}"),
            (self.temperature >= 0, f"temperature must be >= 0, got {self.temperature}"),
            (0.0 <= self.eta <= 1.0, f"eta must be in [0, 1], got {self.eta}"),
            (0.0 <= self.dynamics_weight <= 1.0, f"dynamics_weight must be in [0, 1], got {self.dynamics_weight}"),
            (self.eta == 0.0 or self.sampler == "ddim", "eta is for the ddim sampler only"),
            (self.guard_margin >= 0, f"guard_margin must be >= 0, got {self.guard_margin}"),
            (self.guard_disagreement >= 0, f"guard_disagreement must be >= 0, got {self.guard_disagreement}"),
            (self.support_z > 0, f"support_z must be > 0, got {self.support_z}"),
            (self.outside_support in OUTSIDE_SUPPORT,
             f"outside_support must be one of {list(OUTSIDE_SUPPORT)}, got {self.outside_support!r}"),
        ]
        for ok, message in checks:
            if not ok:
                raise InputError(f"EditConfig: {message}")

    def noise_steps(self, num_timesteps: int) -> int:
        """``k = round(kappa * K)``."""
        return int(round(self.kappa * num_timesteps))


def _paper(state_dim: int, action_dim: int) -> PriorConfig:
    """The paper's setup (appendix hyperparameter table). Optimiser settings are not stated there;
    Adam at 2e-4 with batch 256 follows Diffuser / Decision Diffuser, plus a short warm-up."""
    return PriorConfig(
        state_dim=state_dim, action_dim=action_dim, width_multiplier=16, state_blocks=2, action_blocks=2,
        reward_blocks=1, horizon=20, num_timesteps=200, batch_size=256, learning_rate=2e-4,
        warmup_steps=1000, return_condition=True,
    )


def _cpu(state_dim: int, action_dim: int) -> PriorConfig:
    """Small, fast configuration for a 2-core CPU: stream widths 4x the element's dim (at least 32,
    at most 1024: the paper's 1x for its 1024-d embedding states), one block per stream, batch 128
    (about 3.4 GFLOP per step on halfcheetah; BENCHMARKS.md has the curve that chose it)."""
    return PriorConfig(
        state_dim=state_dim, action_dim=action_dim, width_multiplier=4, min_width=32, max_width=1024,
        state_blocks=1, action_blocks=1, reward_blocks=1, cond_dim=64, horizon=20, num_timesteps=200, batch_size=128,
        learning_rate=1e-3, warmup_steps=500, decay_steps=50_000, return_condition=True,
    )


def _tiny(state_dim: int, action_dim: int) -> PriorConfig:
    """A smoke test of a pipeline, not a model: width 8, one block per stream, windows of 4, 10
    noise steps; trains and edits in seconds (what the examples' tests run)."""
    return PriorConfig(
        state_dim=state_dim, action_dim=action_dim, width_override=8, state_blocks=1, action_blocks=1,
        reward_blocks=1, num_heads=2, cond_dim=16, horizon=4, num_timesteps=10, batch_size=16,
    )


def presets() -> dict[str, Callable[[int, int], PriorConfig]]:
    """Named configurations as functions of ``(state_dim, action_dim)``."""
    return {"paper": _paper, "cpu": _cpu, "tiny": _tiny}


def preset(name: str, state_dim: int, action_dim: int, rewards: bool = True, **overrides: Any) -> PriorConfig:
    """``presets()[name](state_dim, action_dim)`` with fields replaced by ``overrides``; without
    ``rewards`` (reward-free target data) the reward stream and return conditioning are off, as in
    the paper's real-robot setting (its appendix: "the reward modules removed")."""
    table = presets()
    if name not in table:
        raise InputError(f"unknown prior preset {name!r}; expected one of {sorted(table)}")
    config = table[name](state_dim, action_dim)
    if not rewards:
        config = dataclasses.replace(config, use_reward=False, return_condition=False)
    return dataclasses.replace(config, **overrides)
