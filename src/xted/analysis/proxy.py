"""Learned models of the target domain: the paper's dynamics proxy, and a reward proxy.

Each is an MLP fitted to target transitions (inputs and outputs standardised, MSE, Adam with
cosine decay).

- The dynamics proxy ``(s, a) -> s' - s``: its error on a dataset, ``|proxy(s, a) - s'|``, is the
  paper's "dynamics error" (its §5 figure), the measure a user has when the target is a real
  robot. With a simulator, :func:`xted.envs.dynamics.dynamics_error` is the ground truth; the
  proxy's own simulator error on held-out target data says how much a model learned from this
  target data can resolve at all.
- The reward proxy ``(s, a, s') -> r``: :func:`relabel_rewards` gives edited transitions the
  target's reward for what they now do. The prior's own reward stream regresses toward the
  rewards it saw in the target data, which understates a source that moves faster than the
  target ever did (measured in BENCHMARKS.md).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from xted.analysis.config import ProxyConfig
from xted.data import Dataset
from xted.data.dataset import REWARD_FREE
from xted.envs.dynamics import DynamicsError
from xted.errors import InputError
from xted.nn import FittedMLP, fit_mlp


def _check_dims(kind: str, expected: tuple[int, ...], given: tuple[int, ...]) -> None:
    if expected != given:
        parts = [f"{d}-d {name}" for d, name in zip(expected, ("observations", "actions", "next observations"))]
        raise InputError(f"the {kind} takes {', '.join(parts[:-1])} and {parts[-1]}; got dims {given}")


@dataclass(frozen=True)
class DynamicsProxy:
    """A fitted dynamics proxy: ``predict`` gives next observations, ``error`` the paper's dynamics error."""

    model: FittedMLP

    @property
    def observation_dim(self) -> int:
        return len(self.model.output_mean)

    def predict(self, observations: np.ndarray, actions: np.ndarray) -> np.ndarray:
        observations = np.asarray(observations, np.float64)
        obs_dim = self.observation_dim
        _check_dims("proxy", (obs_dim, self.model.input_dim - obs_dim), (observations.shape[1], np.shape(actions)[1]))
        return observations + self.model(np.concatenate([observations, actions], axis=1))

    def error(self, data: Dataset) -> DynamicsError:
        predicted = self.predict(data.observations, data.actions)
        return DynamicsError.from_differences(predicted - data.require_next_observations())


def fit_proxy(target: Dataset, config: ProxyConfig = ProxyConfig(), progress: bool = True) -> DynamicsProxy:
    """Fit the dynamics proxy to ``target``'s transitions; the same seed gives the same proxy."""
    inputs = np.concatenate([target.observations, target.actions], axis=1)
    deltas = target.require_next_observations() - target.observations
    return DynamicsProxy(fit_mlp(inputs, deltas, config, progress))


@dataclass(frozen=True)
class RewardProxy:
    """A fitted reward model of the target, ``r = g(s, a, s')``."""

    model: FittedMLP
    observation_dim: int

    def predict(self, observations: np.ndarray, actions: np.ndarray, next_observations: np.ndarray) -> np.ndarray:
        obs_dim = self.observation_dim
        _check_dims("reward proxy", (obs_dim, self.model.input_dim - 2 * obs_dim, obs_dim),
                    (np.shape(observations)[1], np.shape(actions)[1], np.shape(next_observations)[1]))
        return self.model(np.concatenate([observations, actions, next_observations], axis=1))[:, 0]


def fit_reward_proxy(target: Dataset, config: ProxyConfig = ProxyConfig(), progress: bool = True) -> RewardProxy:
    """Fit the reward proxy to ``target``'s transitions; the same seed gives the same model."""
    target.require_rewards("a reward proxy", "relabel with a target dataset that records rewards")
    inputs = np.concatenate([target.observations, target.actions, target.require_next_observations()], axis=1)
    model = fit_mlp(inputs, target.rewards[:, None], config, progress, desc="reward proxy")
    return RewardProxy(model, target.observation_dim)


def relabel_rewards(data: Dataset, proxy: RewardProxy) -> Dataset:
    """``data`` (a copy) with every reward given by ``proxy`` from its ``(s, a, s')``."""
    rewards = proxy.predict(data.observations, data.actions, data.require_next_observations())
    metadata = {**{k: v for k, v in data.metadata.items() if k != REWARD_FREE},
                "rewards": "relabelled by a reward proxy fitted to the target"}
    return dataclasses.replace(data, rewards=rewards.astype(data.rewards.dtype), metadata=metadata)
