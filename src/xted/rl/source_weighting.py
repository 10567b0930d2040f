"""Filtering a batch's source transitions by a per-transition score, as IGDF and OTDF do.

The scores are computed once before training (:mod:`xted.rl.igdf`, :mod:`xted.rl.otdf`); in every
batch the source transitions of highest score are kept (a share ``keep_fraction`` of those the batch
holds) and the kept ones' Q loss weighted ``exp(weight_scale * score)``; target transitions are
always kept and weigh 1. OTDF first rescales the batch's source scores to [-1, 0].
"""

from __future__ import annotations

import jax.numpy as jnp

from xted.rl.config import IGDFConfig, OTDFConfig

ScoredSource = IGDFConfig | OTDFConfig
ROWS = ("is_source", "source_score")  # the rows a filtered batch reads beside the transitions


def weigh_batch(batch: dict, method: ScoredSource) -> dict:
    """``batch`` with ``sample_weight`` (1 kept, 0 dropped) and ``q_weight`` (the critic's weights)."""
    is_source = batch["is_source"] > 0
    score = batch["source_score"]
    if isinstance(method, OTDFConfig):  # min-max over the batch's source transitions, onto [-1, 0]
        high = jnp.max(jnp.where(is_source, score, -jnp.inf))
        low = jnp.min(jnp.where(is_source, score, jnp.inf))
        score = (score - high) / jnp.maximum(high - low, 1e-8)
        scale = 1.0
    else:
        scale = method.weight_scale
    threshold = jnp.nanquantile(jnp.where(is_source, score, jnp.nan), 1.0 - method.keep_fraction)
    keep = ~is_source | (score >= threshold)
    q_weight = jnp.where(is_source, jnp.exp(scale * jnp.where(keep, score, 0.0)), 1.0) * keep
    return {**batch, "sample_weight": keep.astype(jnp.float32), "q_weight": q_weight.astype(jnp.float32)}
