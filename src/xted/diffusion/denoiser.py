"""The xTED denoiser (paper §4.1 and appendix): one stream per trajectory element.

Each stream (state, action, reward) is encoded separately (2-layer MLP + learned positional
embedding), runs its own adaLN-conditioned self-attention blocks over the horizon, is updated
once by a cross-attention block following :data:`CROSS_WIRING` (``cross_blocks`` rounds of it,
each reading the round before, where the paper has one), and is decoded separately into its
predicted noise. The condition embedding ``e = f_c(k, R)`` is one global vector per sample.

Heads: a stream of width ``w`` uses ``gcd(num_heads, w)`` heads, the largest divisor of
``num_heads`` that divides ``w`` (4 of 4 for the paper's widths 16·17, 16·6 and 16·1).

Initialisation is adaLN-Zero (DiT): all modulation layers and every decoder's last layer start at
zero, so each block starts as the identity and the untrained model predicts zero noise.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence

import flax.linen as nn
import jax
import jax.numpy as jnp

from xted.diffusion.config import STREAMS, DenoiserConfig


def _layer_norm(x: jnp.ndarray, dtype: jnp.dtype) -> jnp.ndarray:
    return nn.LayerNorm(use_bias=False, use_scale=False, epsilon=1e-6, dtype=dtype)(x)


def _modulate(x: jnp.ndarray, shift: jnp.ndarray, scale: jnp.ndarray) -> jnp.ndarray:
    return x * (1 + scale[:, None]) + shift[:, None]


class Modulation(nn.Module):
    """``chunks`` per-sample vectors of size ``features`` from the condition (zero-initialised)."""

    features: int
    chunks: int
    dtype: jnp.dtype = jnp.float32

    @nn.compact
    def __call__(self, e: jnp.ndarray) -> list[jnp.ndarray]:
        z = nn.Dense(self.features * self.chunks, kernel_init=nn.initializers.zeros, dtype=self.dtype)(nn.silu(e))
        return jnp.split(z, self.chunks, axis=-1)


class Mlp(nn.Module):
    """Dense-GELU-Dense; the last layer optionally zero-initialised."""

    hidden: int
    out: int
    zero_out: bool = False
    dtype: jnp.dtype = jnp.float32

    @nn.compact
    def __call__(self, x: jnp.ndarray) -> jnp.ndarray:
        x = nn.gelu(nn.Dense(self.hidden, dtype=self.dtype)(x))
        init = nn.initializers.zeros if self.zero_out else nn.initializers.lecun_normal()
        return nn.Dense(self.out, kernel_init=init, dtype=self.dtype)(x)


class SelfAttentionBlock(nn.Module):
    """adaLN block: gated residual self-attention, then gated residual MLP."""

    width: int
    heads: int
    mlp_ratio: int
    dtype: jnp.dtype = jnp.float32

    @nn.compact
    def __call__(self, x: jnp.ndarray, e: jnp.ndarray, mask: jnp.ndarray | None = None) -> jnp.ndarray:
        shift, scale, gate, shift2, scale2, gate2 = Modulation(self.width, 6, self.dtype)(e)
        h = _modulate(_layer_norm(x, self.dtype), shift, scale)
        attention = nn.MultiHeadDotProductAttention(
            self.heads, qkv_features=self.width, out_features=self.width, dtype=self.dtype
        )
        x = x + gate[:, None] * attention(h, mask=mask)
        h = _modulate(_layer_norm(x, self.dtype), shift2, scale2)
        return x + gate2[:, None] * Mlp(self.width * self.mlp_ratio, self.width, dtype=self.dtype)(h)


class CrossAttentionBlock(nn.Module):
    """Updates ``x`` with queries from ``x`` and keys/values from ``others``.

    Each attended stream gets its own adaLN shift/scale and a projection to ``x``'s width; several
    attended streams are concatenated along the token axis. ``x`` gets a gated residual attention
    and a gated residual MLP, as in :class:`SelfAttentionBlock`.
    """

    width: int
    heads: int
    mlp_ratio: int
    dtype: jnp.dtype = jnp.float32

    @nn.compact
    def __call__(self, x: jnp.ndarray, others: Sequence[jnp.ndarray], e: jnp.ndarray,
                 mask: jnp.ndarray | None = None) -> jnp.ndarray:
        shift, scale, gate, shift2, scale2, gate2 = Modulation(self.width, 6, self.dtype)(e)
        q = _modulate(_layer_norm(x, self.dtype), shift, scale)
        kv = []
        for i, other in enumerate(others):
            kv_shift, kv_scale = Modulation(other.shape[-1], 2, self.dtype, name=f"kv_modulation_{i}")(e)
            h = _modulate(_layer_norm(other, self.dtype), kv_shift, kv_scale)
            kv.append(nn.Dense(self.width, dtype=self.dtype, name=f"kv_projection_{i}")(h))
        kv = jnp.concatenate(kv, axis=1)
        attention = nn.MultiHeadDotProductAttention(
            self.heads, qkv_features=self.width, out_features=self.width, dtype=self.dtype
        )
        x = x + gate[:, None] * attention(q, kv, mask=mask)
        h = _modulate(_layer_norm(x, self.dtype), shift2, scale2)
        return x + gate2[:, None] * Mlp(self.width * self.mlp_ratio, self.width, dtype=self.dtype)(h)


class Encoder(nn.Module):
    """Element sequence ``[B, H, d]`` -> ``[B, H, width]``: 2-layer MLP plus positional embedding."""

    width: int
    horizon: int
    dtype: jnp.dtype = jnp.float32

    @nn.compact
    def __call__(self, x: jnp.ndarray) -> jnp.ndarray:
        position = self.param("position", nn.initializers.normal(0.02), (self.horizon, self.width))
        h = Mlp(self.width, self.width, dtype=self.dtype)(x)
        return h + position[: x.shape[1]].astype(self.dtype)


class Decoder(nn.Module):
    """``[B, H, width]`` -> predicted noise ``[B, H, d]``: LayerNorm + 2-layer MLP (last layer zero)."""

    width: int
    out: int
    dtype: jnp.dtype = jnp.float32

    @nn.compact
    def __call__(self, h: jnp.ndarray) -> jnp.ndarray:
        h = nn.LayerNorm(dtype=self.dtype)(h)
        return Mlp(self.width, self.out, zero_out=True, dtype=self.dtype)(h)


def timestep_embedding(t: jnp.ndarray, dim: int, max_period: float = 10_000.0) -> jnp.ndarray:
    """Sinusoidal embedding ``[B, dim]`` of integer timesteps ``[B]``."""
    half = dim // 2
    freqs = jnp.exp(-math.log(max_period) * jnp.arange(half, dtype=jnp.float32) / half)
    angles = t.astype(jnp.float32)[:, None] * freqs[None]
    return jnp.concatenate([jnp.sin(angles), jnp.cos(angles)], axis=-1)


class ConditionEmbedding(nn.Module):
    """``e = MLP(sinusoid(t)) [+ MLP(R) * (1 - drop)]``: one ``cond_dim`` vector per sample.

    Without a return (``returns`` None) or with ``drop_condition`` set, the return term is zero:
    the "null" condition of classifier-free guidance.
    """

    cond_dim: int
    return_condition: bool
    dtype: jnp.dtype = jnp.float32

    @nn.compact
    def __call__(self, t: jnp.ndarray, returns: jnp.ndarray | None, drop: jnp.ndarray | None) -> jnp.ndarray:
        e = Mlp(self.cond_dim, self.cond_dim, dtype=self.dtype, name="timestep_mlp")(
            timestep_embedding(t, self.cond_dim)
        )
        if self.return_condition:
            r = returns if returns is not None else jnp.zeros(t.shape, jnp.float32)
            r_emb = Mlp(self.cond_dim, self.cond_dim, dtype=self.dtype, name="return_mlp")(r[:, None])
            keep = jnp.ones(t.shape, bool) if returns is not None else jnp.zeros(t.shape, bool)
            if drop is not None:
                keep = keep & ~drop
            e = e + r_emb * keep[:, None].astype(r_emb.dtype)
        return e


class Denoiser(nn.Module):
    """``(states [B,H,ds], actions [B,H,da], rewards [B,H,1] | None, t [B], returns [B] | None,
    drop_condition [B] bool | None) -> (eps_s, eps_a, eps_r | None)``; the noise of a stream not
    in ``config.diffused_streams`` is None (its input is ignored).

    ``rewards`` must be given exactly when ``config.use_reward``. ``returns`` (normalised to
    [0, 1]) is used only when ``config.return_condition``; None means the null condition.
    """

    config: DenoiserConfig

    @nn.compact
    def __call__(
        self,
        states: jnp.ndarray,
        actions: jnp.ndarray,
        rewards: jnp.ndarray | None,
        t: jnp.ndarray,
        returns: jnp.ndarray | None = None,
        drop_condition: jnp.ndarray | None = None,
    ) -> tuple[jnp.ndarray, jnp.ndarray, jnp.ndarray | None]:
        cfg = self.config
        dtype = jnp.dtype(cfg.dtype)
        if (rewards is not None) != cfg.use_reward:
            expected = "given" if cfg.use_reward else "None"
            raise ValueError(f"rewards must be {expected} when use_reward={cfg.use_reward}")
        inputs = {s: x.astype(dtype) for s, x in zip(STREAMS, (states, actions, rewards)) if s in cfg.streams}
        e = ConditionEmbedding(cfg.cond_dim, cfg.return_condition, dtype, name="condition")(t, returns, drop_condition)
        build = {"xted": _streams, "causal": _streams, "feature_concat": _feature_concat,
                 "temporal_concat": _temporal_concat, "inverse_dynamics": _states_only,
                 "temporal_unet": _temporal_unet}[cfg.architecture]
        eps = {s: x.astype(jnp.float32) for s, x in build(cfg, inputs, e, dtype).items()}
        return eps["state"], eps.get("action"), eps.get("reward")


def _causal_mask(query_times: jnp.ndarray, key_times: jnp.ndarray) -> jnp.ndarray:
    """``[1, 1, Q, K]``: a query at time ``t`` sees keys at times ``<= t``."""
    return (key_times[None, :] <= query_times[:, None])[None, None]


def _self_blocks(cfg: DenoiserConfig, name: str, x: jnp.ndarray, e: jnp.ndarray, count: int,
                 mask: jnp.ndarray | None, dtype: jnp.dtype) -> jnp.ndarray:
    width = x.shape[-1]
    for i in range(count):
        x = SelfAttentionBlock(width, math.gcd(cfg.num_heads, width), cfg.mlp_ratio, dtype, name=f"{name}_self_{i}")(
            x, e, mask
        )
    return x


def _streams(cfg: DenoiserConfig, inputs: dict[str, jnp.ndarray], e: jnp.ndarray, dtype: jnp.dtype) -> dict:
    """xTED (and its causal variant): per-stream self-attention, then the cross-attention wiring."""
    times = jnp.arange(inputs["state"].shape[1])
    causal = cfg.architecture == "causal"
    h = {}
    for s in cfg.streams:
        x = Encoder(cfg.width(s), cfg.horizon, dtype, name=f"{s}_encoder")(inputs[s])
        h[s] = _self_blocks(cfg, s, x, e, cfg.blocks(s), _causal_mask(times, times) if causal else None, dtype)
    for round_ in range(cfg.cross_blocks):
        crossed = dict(h)
        for s, attended in cfg.cross_wiring:
            mask = _causal_mask(times, jnp.tile(times, len(attended))) if causal else None
            name = f"{s}_cross" if round_ == 0 else f"{s}_cross_{round_}"
            block = CrossAttentionBlock(cfg.width(s), cfg.heads(s), cfg.mlp_ratio, dtype, name=name)
            crossed[s] = block(h[s], [h[a] for a in attended], e, mask)
        h = crossed
    return {s: Decoder(cfg.width(s), cfg.element_dim(s), dtype, name=f"{s}_decoder")(h[s]) for s in cfg.streams}


def _split_joint(cfg: DenoiserConfig, joint: jnp.ndarray) -> dict:
    """``[..., ds + da (+ 1)]`` -> one array per stream."""
    splits = list(itertools.accumulate(cfg.element_dim(s) for s in cfg.streams))[:-1]
    return dict(zip(cfg.streams, jnp.split(joint, splits, axis=-1)))


def _feature_concat(cfg: DenoiserConfig, inputs: dict[str, jnp.ndarray], e: jnp.ndarray, dtype: jnp.dtype) -> dict:
    """FC: one token per step, ``[s_t, a_t, r_t]``, one stream."""
    joint = jnp.concatenate([inputs[s] for s in cfg.streams], axis=-1)
    x = Encoder(cfg.width("joint"), cfg.horizon, dtype, name="joint_encoder")(joint)
    x = _self_blocks(cfg, "joint", x, e, cfg.state_blocks + 1, None, dtype)
    return _split_joint(cfg, Decoder(cfg.width("joint"), cfg.element_dim("joint"), dtype, name="joint_decoder")(x))


def _states_only(cfg: DenoiserConfig, inputs: dict[str, jnp.ndarray], e: jnp.ndarray, dtype: jnp.dtype) -> dict:
    """Inv's denoiser: the state stream alone, without cross-attention."""
    x = Encoder(cfg.width("state"), cfg.horizon, dtype, name="state_encoder")(inputs["state"])
    x = _self_blocks(cfg, "state", x, e, cfg.state_blocks + 1, None, dtype)
    return {"state": Decoder(cfg.width("state"), cfg.state_dim, dtype, name="state_decoder")(x)}


INVERSE_PARAMS = "inverse_dynamics"  # Inv's inverse models, a subtree of the prior's "params" collection


class InverseDynamics(nn.Module):
    """Inv's inverse models on normalised windows: ``a_t = f(s_t, s_{t+1})`` and, with rewards,
    ``r_t = g(s_t, a_t, s_{t+1})``, each an MLP of two hidden layers at ``width("joint")``.

    ``(states [B, H, ds], actions [B, H, da] | None) -> (actions [B, H-1, da], rewards [B, H-1, 1] | None)``
    for the ``H - 1`` transitions of a window. ``g`` reads the given actions (training) or, with
    None, the predicted ones (editing).
    """

    config: DenoiserConfig

    @nn.compact
    def __call__(self, states: jnp.ndarray, actions: jnp.ndarray | None = None):
        cfg = self.config
        width = cfg.width("joint")

        def mlp(x: jnp.ndarray, out: int, name: str) -> jnp.ndarray:
            x = nn.gelu(nn.Dense(width, name=f"{name}_0")(x))
            return Mlp(width, out, name=f"{name}_1")(x)

        pairs = jnp.concatenate([states[:, :-1], states[:, 1:]], axis=-1)
        predicted = mlp(pairs, cfg.action_dim, "action")
        if not cfg.use_reward:
            return predicted, None
        used = predicted if actions is None else actions[:, :-1]
        return predicted, mlp(jnp.concatenate([pairs, used], axis=-1), 1, "reward")


def init_params(cfg: DenoiserConfig, rng, states: jnp.ndarray, actions: jnp.ndarray, rewards: jnp.ndarray | None,
                t: jnp.ndarray, returns: jnp.ndarray | None, drop: jnp.ndarray | None) -> dict:
    """The denoiser's parameters; for Inv with its inverse models under ``params[INVERSE_PARAMS]``."""
    params = Denoiser(cfg).init(rng, states, actions, rewards, t, returns, drop)
    if cfg.architecture != "inverse_dynamics":
        return params
    inverse = InverseDynamics(cfg).init(jax.random.fold_in(rng, 1), states, actions)["params"]
    return {**params, "params": {**params["params"], INVERSE_PARAMS: inverse}}


def apply_inverse(cfg: DenoiserConfig, params: dict, states: jnp.ndarray, actions: jnp.ndarray | None = None):
    """:class:`InverseDynamics` with the inverse models held in a prior's ``params``."""
    return InverseDynamics(cfg).apply({"params": params["params"][INVERSE_PARAMS]}, states, actions)


def _temporal_concat(cfg: DenoiserConfig, inputs: dict[str, jnp.ndarray], e: jnp.ndarray, dtype: jnp.dtype) -> dict:
    """TC: element tokens interleaved in time, ``s_0, a_0, r_0, s_1, ...``, one sequence."""
    width, n = cfg.width("state"), len(cfg.streams)
    tokens = jnp.stack([Encoder(width, cfg.horizon, dtype, name=f"{s}_encoder")(inputs[s]) for s in cfg.streams], 2)
    b, h = tokens.shape[:2]
    x = _self_blocks(cfg, "tokens", tokens.reshape(b, h * n, width), e, cfg.state_blocks + 1, None, dtype)
    x = x.reshape(b, h, n, width)
    return {s: Decoder(width, cfg.element_dim(s), dtype, name=f"{s}_decoder")(x[:, :, i]) for i, s in enumerate(cfg.streams)}


# Temporal U-Net (Janner et al. 2022, Diffuser; Ajay et al. 2023): 1-d convolutions over time.
UNET_CHANNEL_FRACTIONS = (4, 2, 1)  # level i has width("joint") // fraction channels
UNET_KERNEL = 5
UNET_GROUPS = 8


def _mish(x: jnp.ndarray) -> jnp.ndarray:
    return x * jnp.tanh(nn.softplus(x))


class ConvNormMish(nn.Module):
    """Conv1d (``UNET_KERNEL`` wide, same length) -> GroupNorm -> Mish."""

    channels: int
    dtype: jnp.dtype = jnp.float32

    @nn.compact
    def __call__(self, x: jnp.ndarray) -> jnp.ndarray:
        x = nn.Conv(self.channels, (UNET_KERNEL,), padding="SAME", dtype=self.dtype)(x)
        x = nn.GroupNorm(math.gcd(UNET_GROUPS, self.channels), dtype=self.dtype)(x)
        return _mish(x)


class ResidualTemporalBlock(nn.Module):
    """Two :class:`ConvNormMish`, the condition added (per channel) between them, and a residual
    (1x1 convolution where the channel count changes)."""

    channels: int
    dtype: jnp.dtype = jnp.float32

    @nn.compact
    def __call__(self, x: jnp.ndarray, e: jnp.ndarray) -> jnp.ndarray:
        h = ConvNormMish(self.channels, self.dtype)(x)
        h = h + nn.Dense(self.channels, dtype=self.dtype)(_mish(e))[:, None]
        h = ConvNormMish(self.channels, self.dtype)(h)
        skip = x if x.shape[-1] == self.channels else nn.Conv(self.channels, (1,), dtype=self.dtype)(x)
        return h + skip


def _temporal_unet(cfg: DenoiserConfig, inputs: dict[str, jnp.ndarray], e: jnp.ndarray, dtype: jnp.dtype) -> dict:
    """U-Net over the ``[s_t, a_t, r_t]`` sequence: at each level two residual blocks, then a
    stride-2 convolution (time halves, channels per :data:`UNET_CHANNEL_FRACTIONS`); two middle
    blocks; the mirror image upwards with the skip connections concatenated; a final convolution
    block and a zero-initialised 1x1 projection. The window is zero-padded at its end to a multiple
    of ``2 ** (levels - 1)`` and cropped back."""
    joint = jnp.concatenate([inputs[s] for s in cfg.streams], axis=-1)
    length = joint.shape[1]
    factor = 2 ** (len(UNET_CHANNEL_FRACTIONS) - 1)
    x = jnp.pad(joint, ((0, 0), (0, -length % factor), (0, 0)))
    widths = [max(cfg.width("joint") // f, UNET_GROUPS) for f in UNET_CHANNEL_FRACTIONS]
    skips = []
    for level, width in enumerate(widths):
        for i in range(2):
            x = ResidualTemporalBlock(width, dtype, name=f"down_{level}_{i}")(x, e)
        skips.append(x)
        if level < len(widths) - 1:
            x = nn.Conv(width, (3,), strides=(2,), padding=((1, 1),), dtype=dtype, name=f"downsample_{level}")(x)
    for i in range(2):
        x = ResidualTemporalBlock(widths[-1], dtype, name=f"middle_{i}")(x, e)
    for level in reversed(range(len(widths))):
        if level < len(widths) - 1:
            x = nn.ConvTranspose(widths[level + 1], (4,), strides=(2,), padding="SAME", dtype=dtype,
                                 name=f"upsample_{level}")(x)
        x = jnp.concatenate([x, skips[level]], axis=-1)
        for i in range(2):
            x = ResidualTemporalBlock(widths[level], dtype, name=f"up_{level}_{i}")(x, e)
    x = ConvNormMish(widths[0], dtype, name="final_block")(x)
    out = nn.Conv(cfg.element_dim("joint"), (1,), kernel_init=nn.initializers.zeros, dtype=dtype, name="final_projection")(x)
    return _split_joint(cfg, out[:, :length])
