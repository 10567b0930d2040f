"""Augmenting a dataset without a model: S4RL's Gaussian state noise as a perturbed copy."""

from __future__ import annotations

import dataclasses

import numpy as np

from xted.data.dataset import Dataset

# S4RL's noise (Sinha et al., CoRL 2021), as the xTED paper's §5.4 states it: N(0, 3e-4) on every state dimension.
S4RL_STATE_STD = 3e-4


def gaussian_copy(data: Dataset, std: float, seed: int) -> Dataset:
    """A copy of ``data`` whose observations and next observations carry independent N(0, std^2)
    noise (raw units); actions, rewards, episode ends as given, extras (simulator states) dropped.
    Added to the original it doubles the dataset, as the paper's S4RL baseline does."""
    rng = np.random.default_rng(seed)
    noisy = {name: (array + rng.normal(0.0, std, array.shape)).astype(array.dtype)
             for name, array in (("observations", data.observations),
                                 ("next_observations", data.require_next_observations()))}
    return dataclasses.replace(data, **noisy, extras={},
                               metadata={**data.metadata, "augmented": {"method": "gaussian state noise (S4RL)",
                                                                        "std": std, "seed": seed}})
