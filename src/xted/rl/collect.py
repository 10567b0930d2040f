"""Roll a policy out in a domain and record whole episodes as flat transition arrays."""

from __future__ import annotations

from typing import Callable

import numpy as np
from tqdm.auto import tqdm

from xted.envs import Domain, make

# batch of observations, numpy Generator -> batch of actions
SamplingPolicy = Callable[[np.ndarray, np.random.Generator], np.ndarray]


def uniform_policy(action_dim: int) -> SamplingPolicy:
    return lambda obs, rng: rng.uniform(-1.0, 1.0, (len(obs), action_dim)).astype(np.float32)


def collect(
    policy: SamplingPolicy,
    domain: Domain,
    transitions: int,
    seed: int = 0,
    num_envs: int = 10,
    progress: bool = True,
    desc: str = "collect",
) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Collect at least ``transitions`` steps as whole episodes, then cut to exactly that many.

    Episodes run side by side in ``num_envs`` envs; each finished episode is appended whole, in
    the order episodes finish. If the last kept episode is longer than needed it is cut and its
    final kept step marked as a timeout (a contiguous segment with a correct time-limit end).
    Returns the flat arrays and the returns of the complete (uncut) episodes.
    """
    rng = np.random.default_rng(seed)
    envs = [make(domain) for _ in range(num_envs)]
    episode_seed = seed * 1_000_003
    obs = np.stack([env.reset(seed=episode_seed + i)[0] for i, env in enumerate(envs)])
    next_seed = episode_seed + num_envs
    running = [{k: [] for k in ("observations", "actions", "rewards", "next_observations", "terminals", "timeouts")}
               for _ in envs]
    episodes: list[dict[str, np.ndarray]] = []
    collected = 0
    bar = tqdm(total=transitions, desc=desc, unit="step", disable=not progress)
    while collected < transitions:
        actions = np.asarray(policy(obs, rng), dtype=np.float32)
        for i, env in enumerate(envs):
            next_obs, reward, terminated, truncated, _ = env.step(actions[i])
            record = running[i]
            for key, value in (("observations", obs[i].copy()), ("actions", actions[i]), ("rewards", reward),
                               ("next_observations", next_obs), ("terminals", terminated),
                               ("timeouts", truncated and not terminated)):
                record[key].append(value)
            obs[i] = next_obs
            if terminated or truncated:
                episodes.append({k: np.asarray(v) for k, v in record.items()})
                collected += len(record["rewards"])
                bar.update(len(record["rewards"]))
                running[i] = {k: [] for k in record}
                obs[i] = env.reset(seed=next_seed)[0]
                next_seed += 1
                if collected >= transitions:
                    break
    bar.close()
    for env in envs:
        env.close()
    returns = np.array([ep["rewards"].sum() for ep in episodes])
    flat = {k: np.concatenate([ep[k] for ep in episodes]) for k in episodes[0]}
    flat = {k: v[:transitions] for k, v in flat.items()}
    if not (flat["terminals"][-1] or flat["timeouts"][-1]):
        flat["timeouts"][-1] = True
    return flat, returns

