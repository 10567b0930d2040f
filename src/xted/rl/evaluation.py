"""Vectorised policy evaluation in a domain: N episodes stepped together, one batched policy call."""

from __future__ import annotations

from typing import Callable

import numpy as np

from xted.envs import Domain, make, normalized_score

# Observation index of the root's pitch angle (qpos[2]) in HalfCheetah and Walker2d. Its mean
# |value| tells a flipped halfcheetah (near pi, or growing while it rolls) from a running one.
ROOT_PITCH = 1

PolicyFn = Callable[[np.ndarray], np.ndarray]  # batch of observations -> batch of actions


def evaluate(policy: PolicyFn, domain: Domain, episodes: int = 10, seed: int = 0) -> dict:
    """Run ``episodes`` episodes side by side; returns returns, lengths, normalised scores and the
    mean |root pitch| over all steps (radians)."""
    envs = [make(domain) for _ in range(episodes)]
    obs = np.stack([env.reset(seed=seed + i)[0] for i, env in enumerate(envs)])
    returns = np.zeros(episodes)
    lengths = np.zeros(episodes, dtype=int)
    pitch_sum = 0.0
    active = np.ones(episodes, dtype=bool)
    while active.any():
        idx = np.flatnonzero(active)
        actions = np.asarray(policy(obs[idx]))
        for j, i in enumerate(idx):
            next_obs, reward, terminated, truncated, _ = envs[i].step(actions[j])
            returns[i] += reward
            lengths[i] += 1
            pitch_sum += abs(float(next_obs[ROOT_PITCH]))
            obs[i] = next_obs
            if terminated or truncated:
                active[i] = False
    for env in envs:
        env.close()
    scores = normalized_score(domain.env, returns)
    return {
        "returns": returns,
        "lengths": lengths,
        "return_mean": float(returns.mean()),
        "return_std": float(returns.std()),
        "normalized_scores": scores,
        "normalized_score": float(scores.mean()),
        "root_pitch_mean": pitch_sum / max(int(lengths.sum()), 1),
    }
