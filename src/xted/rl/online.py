"""Online off-policy RL in one domain (behaviour policies): SAC or TD3, checkpointed and resumable.

The loop alternates blocks of environment steps and updates. A block is up to ``block`` steps of
one episode, acted on the host by the current actor (one small jitted call per step); then one
jitted call writes the block into the replay buffer, which lives on the device, and runs one
update per new step (after ``start_steps``) in a ``lax.fori_loop`` that draws every batch from that
buffer. So there is one update per environment step, as in the per-step loop, without a
dispatch, a host gather and a host-to-device copy per update; the acting actor is at most
``block`` updates old. Blocks end at episode ends, so a run resumed from its last checkpoint (always
at an episode end) replays the same blocks and is the same run.

A run folder holds ``run.json`` (domain and config: the run's fingerprint, :mod:`xted.resume`),
``state.msgpack`` + ``buffer.npz`` (the resume point), ``evals.csv`` (greedy evaluation along
training, with the run's wall and CPU seconds so far) and ``checkpoints/actor_STEP.msgpack``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import time
from functools import partial
from pathlib import Path
from typing import Any, Callable, NamedTuple

import flax.serialization
import jax
import jax.numpy as jnp
import numpy as np
from tqdm.auto import tqdm

from xted.atomic import atomic_path
from xted.envs import Domain, make
from xted.errors import InputError
from xted.resume import resume_or_record
from xted.rl.config import OnlineRunConfig
from xted.rl.run_folder import actor_checkpoint, read_evals, write_evals
from xted.rl.evaluation import ROOT_PITCH, evaluate
from xted.rl.policy_io import Policy, save_actor
from xted.rl.sac import init_sac, sac_update
from xted.rl.td3bc import init_td3bc, td3bc_update

BUFFER_FIELDS = ("observations", "actions", "rewards", "next_observations", "terminals", "timeouts")
BATCH_FIELDS = ("observations", "actions", "rewards", "next_observations", "terminals")


class OnlineAlgorithm(NamedTuple):
    init: Callable[..., Any]  # (rng, obs_dim, action_dim, config, steps) -> state with .actor, as offline
    update: Callable[..., Any]  # (state, batch, config) -> (state, info)
    policy: str  # the actor's kind in xted.rl.policy_io


ONLINE_ALGORITHMS = {
    "sac": OnlineAlgorithm(init_sac, sac_update, "tanh_gaussian"),
    "td3": OnlineAlgorithm(init_td3bc, td3bc_update, "deterministic"),
}


def empty_buffer(size: int, obs_dim: int, action_dim: int) -> dict[str, np.ndarray]:
    """Zeroed replay-buffer arrays of ``size`` transitions, one per field of ``BUFFER_FIELDS``."""
    return {"observations": np.zeros((size, obs_dim), np.float32), "actions": np.zeros((size, action_dim), np.float32),
            "rewards": np.zeros(size, np.float32), "next_observations": np.zeros((size, obs_dim), np.float32),
            "terminals": np.zeros(size, bool), "timeouts": np.zeros(size, bool)}


@partial(jax.jit, static_argnames=("update", "config"), donate_argnames=("buffer",))
def train_block(state, buffer: dict, rows: dict, start, size, num_updates, first_update, sample_key, *,
                update: Callable, config):
    """Write ``rows`` into ``buffer`` at ``start``, then ``num_updates`` updates on batches drawn
    uniformly from the first ``size`` transitions. Update ``i`` of the run draws with
    ``fold_in(sample_key, i)``, so the batches do not depend on how the run was split into blocks."""
    buffer = {k: jax.lax.dynamic_update_slice_in_dim(buffer[k], rows[k], start, axis=0) for k in buffer}

    def one_update(i, state):
        key = jax.random.fold_in(sample_key, first_update + i)
        idx = jax.random.randint(key, (config.batch_size,), 0, size)
        batch = {k: buffer[k][idx] for k in BATCH_FIELDS}
        batch["terminals"] = batch["terminals"].astype(jnp.float32)
        return update(state, batch, config)[0]

    return jax.lax.fori_loop(0, num_updates, one_update, state), buffer


def train_online(domain: Domain, run_dir: str | Path, config: OnlineRunConfig = OnlineRunConfig(),
                 progress: bool = True) -> Path:
    """Train (or resume) ``config.algo`` in ``domain`` until ``config.total_steps`` env steps."""
    run_dir = Path(run_dir)
    algorithm, agent = ONLINE_ALGORITHMS[config.algo], config.agent
    env = make(domain)
    obs_dim, action_dim = env.observation_space.shape[0], env.action_space.shape[0]
    state = algorithm.init(jax.random.PRNGKey(config.seed), obs_dim, action_dim, agent, config.total_steps)
    record = {"domain": dataclasses.asdict(domain), "run": config.fingerprint()}
    if config.init_from is not None:
        init_state, record["init_sha256"] = _initial_state(Path(config.init_from), state, config)
    resume_or_record(run_dir / "run.json", record)
    if config.init_from is not None:
        state = init_state
    host_buffer = empty_buffer(config.total_steps, obs_dim, action_dim)
    step, episode, seconds = 0, 0, {"wall": 0.0, "cpu": 0.0}
    explore_rng = np.random.default_rng(config.seed)
    evals = read_evals(run_dir)
    if (run_dir / "state.msgpack").exists():
        saved = flax.serialization.msgpack_restore((run_dir / "state.msgpack").read_bytes())
        state = flax.serialization.from_state_dict(state, saved["state"])
        step, episode = int(saved["step"]), int(saved["episode"])
        seconds = json.loads(saved.get("seconds", '{"wall": 0.0, "cpu": 0.0}'))
        explore_rng.bit_generator.state = json.loads(saved["numpy_rng"])
        if step > config.total_steps:
            raise InputError(f"{run_dir} is already at step {step}, beyond --steps {config.total_steps}")
        with np.load(run_dir / "buffer.npz") as stored:
            for key in BUFFER_FIELDS:
                host_buffer[key][:step] = stored[key][:step]
    if step >= config.total_steps or _should_stop(evals, config):
        return run_dir

    # The device buffer has one block of slack: a block's padded rows never clip at the end.
    buffer = {k: jnp.concatenate([v, np.zeros((config.block, *v.shape[1:]), v.dtype)]) for k, v in host_buffer.items()}
    del host_buffer
    actor_meta = {"policy": algorithm.policy, "hidden": list(agent.hidden), "obs_dim": obs_dim,
                  "action_dim": action_dim, "domain": dataclasses.asdict(domain), "seed": config.seed,
                  "algo": config.algo, "exploration_noise": config.exploration_noise}
    sample_key = jax.random.PRNGKey(config.seed + 2)
    clock = {"wall": time.time() - seconds["wall"], "cpu": time.process_time() - seconds["cpu"]}

    def elapsed() -> dict:
        return {"wall": time.time() - clock["wall"], "cpu": time.process_time() - clock["cpu"]}

    obs, _ = env.reset(seed=config.seed * 1_000_003 + episode)
    episode_return, done = 0.0, False
    next_checkpoint = (step // config.checkpoint_every + 1) * config.checkpoint_every
    bar = tqdm(total=config.total_steps, initial=step, desc=f"{config.algo.upper()} {domain.name}", unit="step",
               disable=not progress, smoothing=0.05)
    while step < config.total_steps:
        actor = Policy(state.actor.params, actor_meta)
        start, n = step, min(config.block, config.total_steps - step)
        # Fresh rows every block: the device may still be reading the last block's (zero-copy, async).
        rows = empty_buffer(config.block, obs_dim, action_dim)
        for i in range(n):
            if step < config.start_steps and config.init_from is None:
                action = explore_rng.uniform(-1.0, 1.0, action_dim).astype(np.float32)
            else:
                action = actor.act(obs[None], explore_rng)[0]
            next_obs, reward, terminated, truncated, _ = env.step(action)
            if config.terminate_above_pitch is not None:
                terminated = terminated or abs(float(next_obs[ROOT_PITCH])) > config.terminate_above_pitch
                reward += config.upright_bonus * (not terminated)
            for key, value in zip(BUFFER_FIELDS, (obs, action, reward, next_obs, terminated,
                                                  truncated and not terminated)):
                rows[key][i] = value
            step += 1
            episode_return += float(reward)
            obs = next_obs
            done = terminated or truncated
            if done:
                n = i + 1
                break
        if step == config.total_steps and not done:
            # The run ends mid-episode: close the episode as truncated so the buffer stays coherent.
            rows["timeouts"][n - 1] = done = True
        num_updates = max(0, step - max(start, config.start_steps - 1))
        first_update = max(0, start - config.start_steps + 1)
        state, buffer = train_block(state, buffer, rows, start, step, num_updates, first_update, sample_key,
                                    update=algorithm.update, config=agent)
        bar.update(n)
        if done:
            episode += 1
            bar.set_postfix(ret=f"{episode_return:.0f}", refresh=False)
            episode_return = 0.0
            if step >= next_checkpoint or step >= config.total_steps:
                evals.append(_checkpoint(run_dir, state, buffer, step, episode, explore_rng, domain, config,
                                         actor_meta, elapsed))
                write_evals(run_dir, evals)
                bar.set_postfix(eval=f"{evals[-1]['return_mean']:.0f}")
                next_checkpoint = (step // config.checkpoint_every + 1) * config.checkpoint_every
                if _should_stop(evals, config):
                    break
            obs, _ = env.reset(seed=config.seed * 1_000_003 + episode)
    bar.close()
    return run_dir


def _initial_state(init_run: Path, state, config: OnlineRunConfig) -> tuple[Any, str]:
    """The networks and optimiser state at the end of ``init_run`` (same algo and sizes), and the
    SHA-256 of the file they come from, which the new run records: a resume must start from the same."""
    state_file = init_run / "state.msgpack"
    if not state_file.is_file() or not (init_run / "run.json").is_file():
        raise InputError(f"--init-from {init_run}: not an online run folder (needs run.json and state.msgpack)")
    their_algo = json.loads((init_run / "run.json").read_text())["run"]["algo"]
    if their_algo != config.algo:
        raise InputError(f"--init-from {init_run}: a {their_algo} run, but this run trains {config.algo}")
    raw = state_file.read_bytes()
    try:
        loaded = flax.serialization.from_state_dict(state, flax.serialization.msgpack_restore(raw)["state"])
    except (ValueError, KeyError, TypeError) as error:
        raise InputError(f"--init-from {init_run}: its networks do not fit this run ({error})") from error
    if jax.tree_util.tree_map(np.shape, loaded) != jax.tree_util.tree_map(np.shape, state):
        raise InputError(f"--init-from {init_run}: its networks have other shapes than this run's")
    return loaded, hashlib.sha256(raw).hexdigest()


def _should_stop(evals: list[dict], config: OnlineRunConfig) -> bool:
    """The last evaluation reached ``stop_at_return`` or found the body over ``stop_above_pitch``."""
    if not evals:
        return False
    last = evals[-1]
    reached = config.stop_at_return is not None and last["return_mean"] >= config.stop_at_return
    flipped = config.stop_above_pitch is not None and last["root_pitch_mean"] > config.stop_above_pitch
    return reached or flipped


def _checkpoint(run_dir: Path, state, buffer, step, episode, explore_rng, domain, config, actor_meta,
                elapsed: Callable[[], dict]) -> dict:
    params = jax.device_get(state.actor.params)
    save_actor(actor_checkpoint(run_dir, step), params, {**actor_meta, "step": step})
    started = time.time()
    result = evaluate(Policy(params, actor_meta).act, domain, config.eval_episodes, seed=10_000 + step)
    eval_seconds = time.time() - started
    with atomic_path(run_dir / "buffer.npz", suffix=".npz") as tmp:
        np.savez(tmp, **{k: np.asarray(v[:step]) for k, v in buffer.items()})
    seconds = elapsed()
    payload = {"state": flax.serialization.to_state_dict(jax.device_get(state)), "step": step, "episode": episode,
               "numpy_rng": json.dumps(explore_rng.bit_generator.state), "seconds": json.dumps(seconds)}
    with atomic_path(run_dir / "state.msgpack") as tmp:
        tmp.write_bytes(flax.serialization.msgpack_serialize(payload))
    return {"step": step, "return_mean": result["return_mean"], "return_std": result["return_std"],
            "normalized_score": result["normalized_score"], "root_pitch_mean": result["root_pitch_mean"],
            "eval_seconds": eval_seconds,
            "wall_seconds": seconds["wall"], "cpu_seconds": seconds["cpu"], "wall_time": time.time()}
