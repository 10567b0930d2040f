"""The SER baseline's transition diffusion model (:mod:`xted.diffusion.transitions`) on toy data."""

from __future__ import annotations

import numpy as np
import pytest

from xted.data import Dataset
from xted.diffusion.transitions import TransitionModelConfig, sample_transitions, train_transition_model
from xted.errors import InputError

TINY = TransitionModelConfig(width=64, blocks=2, time_dim=16, num_timesteps=20, batch_size=128, learning_rate=3e-3,
                             steps=600)


def toy_transitions(n: int = 2000, seed: int = 0) -> Dataset:
    """States around (3, -2), actions in [-1, 1], next state = state + 0.5 action, reward = first coordinate."""
    rng = np.random.default_rng(seed)
    observations = rng.normal((3.0, -2.0), 0.3, (n, 2)).astype(np.float32)
    actions = rng.uniform(-1, 1, (n, 2)).astype(np.float32)
    ends = np.zeros(n, bool)
    ends[99::100] = True
    return Dataset(observations=observations, actions=actions, rewards=observations[:, 0],
                   terminals=np.zeros(n, bool), timeouts=ends, next_observations=observations + 0.5 * actions,
                   metadata={"env": "Toy-v0"})


@pytest.fixture(scope="module")
def model():
    return train_transition_model(toy_transitions(), TINY)


def test_samples_follow_the_training_data(model):
    data, generated = toy_transitions(), sample_transitions(model, 1000, seed=1)
    assert len(generated) == 1000 and generated.observations.shape == (1000, 2)
    np.testing.assert_allclose(generated.observations.mean(0), data.observations.mean(0), atol=0.15)
    assert (generated.observations.std(0) < 0.6).all()  # pure noise through an untrained model: std ~1 in z units
    assert (np.abs(generated.actions) <= 1.0 + 1e-6).all()
    change = generated.next_observations - generated.observations
    shuffled = np.abs(change - 0.5 * generated.actions[::-1]).mean()
    assert np.abs(change - 0.5 * generated.actions).mean() < 0.6 * shuffled  # s' follows (s, a), not just s
    assert not generated.terminals.any() and generated.timeouts.all()  # one-step episodes, none terminal


def test_sampling_is_seeded(model):
    first, again, other = (sample_transitions(model, 50, seed=s) for s in (0, 0, 1))
    np.testing.assert_array_equal(first.observations, again.observations)
    assert not np.allclose(first.observations, other.observations)


def test_bad_settings_are_refused():
    with pytest.raises(InputError, match="time_dim must be even"):
        TransitionModelConfig(time_dim=15)
    with pytest.raises(InputError, match="steps must be >= 1"):
        TransitionModelConfig(steps=0)
