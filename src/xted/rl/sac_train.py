"""Online SAC in one domain, checkpointed along training and resumable.

A run folder holds ``run.json`` (what is trained), ``state.msgpack`` + ``buffer.npz`` (the
resume point, written at episode boundaries so a resumed run is the same run), ``evals.csv``
(greedy evaluation returns along training) and ``checkpoints/actor_STEP.msgpack``.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import time
from pathlib import Path

import flax.serialization
import jax
import numpy as np
from tqdm.auto import tqdm

from xted.atomic import atomic_path
from xted.envs import Domain, make
from xted.errors import InputError
from xted.rl.evaluation import evaluate
from xted.rl.policy_io import GaussianActor, save_actor
from xted.rl.sac import SACConfig, init_sac, sac_update, sample_action

BUFFER_FIELDS = ("observations", "actions", "rewards", "next_observations", "terminals", "timeouts")


@dataclasses.dataclass(frozen=True)
class SACRunConfig:
    total_steps: int = 300_000
    start_steps: int = 5_000
    checkpoint_every: int = 10_000
    eval_episodes: int = 10
    seed: int = 0
    sac: SACConfig = SACConfig()


def _empty_buffer(size: int, obs_dim: int, action_dim: int) -> dict[str, np.ndarray]:
    return {
        "observations": np.zeros((size, obs_dim), np.float32),
        "actions": np.zeros((size, action_dim), np.float32),
        "rewards": np.zeros(size, np.float32),
        "next_observations": np.zeros((size, obs_dim), np.float32),
        "terminals": np.zeros(size, bool),
        "timeouts": np.zeros(size, bool),
    }


def _run_meta(domain: Domain, config: SACRunConfig) -> dict:
    return {"domain": dataclasses.asdict(domain), "config": json.loads(json.dumps(dataclasses.asdict(config)))}


def read_evals(run_dir: str | Path) -> list[dict]:
    path = Path(run_dir) / "evals.csv"
    if not path.exists():
        return []
    with path.open() as f:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]


def _write_evals(run_dir: Path, rows: list[dict]) -> None:
    with atomic_path(run_dir / "evals.csv") as tmp, tmp.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


def actor_checkpoint(run_dir: str | Path, step: int) -> Path:
    return Path(run_dir) / "checkpoints" / f"actor_{int(step):07d}.msgpack"


def train_sac(domain: Domain, run_dir: str | Path, config: SACRunConfig = SACRunConfig(), progress: bool = True) -> Path:
    """Train (or resume) SAC in ``domain`` until ``config.total_steps`` env steps."""
    run_dir = Path(run_dir)
    meta = _run_meta(domain, config)
    meta_path = run_dir / "run.json"
    if meta_path.exists():
        stored = json.loads(meta_path.read_text())
        if stored["domain"] != meta["domain"] or stored["config"]["seed"] != config.seed:
            raise InputError(f"{run_dir} holds a run of another domain or seed: {stored['domain']}")
    run_dir.mkdir(parents=True, exist_ok=True)
    with atomic_path(meta_path) as tmp:
        tmp.write_text(json.dumps(meta, indent=2))

    env = make(domain)
    obs_dim, action_dim = env.observation_space.shape[0], env.action_space.shape[0]
    state = init_sac(jax.random.PRNGKey(config.seed), obs_dim, action_dim, config.sac)
    buffer = _empty_buffer(config.total_steps, obs_dim, action_dim)
    step, episode = 0, 0
    explore_rng = np.random.default_rng(config.seed)
    evals = read_evals(run_dir)
    if (run_dir / "state.msgpack").exists():
        saved = flax.serialization.msgpack_restore((run_dir / "state.msgpack").read_bytes())
        state = flax.serialization.from_state_dict(state, saved["state"])
        step, episode = int(saved["step"]), int(saved["episode"])
        explore_rng.bit_generator.state = json.loads(saved["numpy_rng"])
        with np.load(run_dir / "buffer.npz") as stored:
            for key in BUFFER_FIELDS:
                buffer[key][:step] = stored[key][:step]
    actor_meta = {"hidden": list(config.sac.hidden), "obs_dim": obs_dim, "action_dim": action_dim,
                  "domain": dataclasses.asdict(domain), "seed": config.seed}
    act_key = jax.random.PRNGKey(config.seed + 1)

    obs, _ = env.reset(seed=config.seed * 1_000_003 + episode)
    episode_return, last_return = 0.0, float("nan")
    bar = tqdm(total=config.total_steps, initial=step, desc=f"SAC {domain.name}", unit="step",
               disable=not progress, smoothing=0.05)
    next_checkpoint = (step // config.checkpoint_every + 1) * config.checkpoint_every
    while step < config.total_steps:
        if step < config.start_steps:
            action = explore_rng.uniform(-1.0, 1.0, action_dim).astype(np.float32)
        else:
            action = np.asarray(sample_action(state.actor, obs[None], jax.random.fold_in(act_key, step))[0])
        next_obs, reward, terminated, truncated, _ = env.step(action)
        for key, value in zip(BUFFER_FIELDS, (obs, action, reward, next_obs, terminated, truncated and not terminated)):
            buffer[key][step] = value
        step += 1
        episode_return += float(reward)
        obs = next_obs
        if step >= config.start_steps:
            idx = explore_rng.integers(0, step, config.sac.batch_size)
            batch = {k: buffer[k][idx] for k in ("observations", "actions", "rewards", "next_observations")}
            batch["terminals"] = buffer["terminals"][idx].astype(np.float32)
            state, _ = sac_update(state, batch, config.sac)
        bar.update(1)
        if terminated or truncated:
            episode += 1
            last_return, episode_return = episode_return, 0.0
            bar.set_postfix(ret=f"{last_return:.0f}", refresh=False)
            if step >= next_checkpoint or step >= config.total_steps:
                evals.append(_checkpoint(run_dir, state, buffer, step, episode, explore_rng, domain, config, actor_meta))
                _write_evals(run_dir, evals)
                bar.set_postfix(ret=f"{last_return:.0f}", eval=f"{evals[-1]['return_mean']:.0f}")
                next_checkpoint = (step // config.checkpoint_every + 1) * config.checkpoint_every
            obs, _ = env.reset(seed=config.seed * 1_000_003 + episode)
    if not (buffer["terminals"][step - 1] or buffer["timeouts"][step - 1]):
        # The run ended mid-episode: close the episode as truncated so the buffer stays coherent.
        buffer["timeouts"][step - 1] = True
        evals.append(_checkpoint(run_dir, state, buffer, step, episode + 1, explore_rng, domain, config, actor_meta))
        _write_evals(run_dir, evals)
    bar.close()
    return run_dir


def _checkpoint(run_dir, state, buffer, step, episode, explore_rng, domain, config, actor_meta) -> dict:
    save_actor(actor_checkpoint(run_dir, step), state.actor.params, {**actor_meta, "step": step})
    greedy = GaussianActor(jax.device_get(state.actor.params), actor_meta)
    started = time.time()
    result = evaluate(greedy.act, domain, config.eval_episodes, seed=10_000 + step)
    with atomic_path(run_dir / "buffer.npz", suffix=".npz") as tmp:
        np.savez(tmp, **{k: v[:step] for k, v in buffer.items()})
    payload = {"state": flax.serialization.to_state_dict(jax.device_get(state)), "step": step, "episode": episode,
               "numpy_rng": json.dumps(explore_rng.bit_generator.state)}
    with atomic_path(run_dir / "state.msgpack") as tmp:
        tmp.write_bytes(flax.serialization.msgpack_serialize(payload))
    return {"step": step, "return_mean": result["return_mean"], "return_std": result["return_std"],
            "normalized_score": result["normalized_score"], "eval_seconds": time.time() - started,
            "wall_time": time.time()}
