"""Network building blocks shared across xted (RL learners, the learned dynamics and reward proxies)."""

from __future__ import annotations

import math
from typing import Callable, Sequence

import flax.linen as nn
import jax
import jax.numpy as jnp


def dense(width: int, fan_in: int) -> nn.Dense:
    """A Dense layer initialised as PyTorch's ``nn.Linear`` (kernel and bias U(+-1/sqrt(fan_in))), the
    init of the reference SAC/TD3/TD3+BC code. Flax's default (LeCun-normal kernels, zero biases)
    made online halfcheetah runs flip onto their backs early and stall near 1,000 (BENCHMARKS.md)."""
    bound = 1.0 / math.sqrt(fan_in)

    def uniform(key, shape, dtype=jnp.float32):
        return jax.random.uniform(key, shape, dtype, -bound, bound)

    return nn.Dense(width, kernel_init=uniform, bias_init=uniform)


class MLP(nn.Module):
    hidden: Sequence[int]
    out: int
    activate_final: bool = False
    activation: Callable[[jax.Array], jax.Array] = nn.relu

    @nn.compact
    def __call__(self, x):
        for width in self.hidden:
            x = self.activation(dense(width, x.shape[-1])(x))
        x = dense(self.out, x.shape[-1])(x)
        return self.activation(x) if self.activate_final else x
