"""Offline policy learning on a target dataset mixed with source datasets, several seeds at once.

Every algorithm is a frozen config (its hyperparameters) plus ``init`` / ``update`` / ``act``. Training
runs ``lax.scan`` over jitted updates, each seed with its own batches drawn on device, and ``jax.vmap``
over the seeds' stacked states; :func:`train_steps` is the single-seed path through the same update.
Observations are standardised with the training data's mean and std (+1e-3, as TD3+BC does); the
evaluation policy standardises the same way before acting. S4RL's Gaussian state noise
(``s4rl_noise``, in standardised units) perturbs the states of each batch, for any algorithm.
"""

from __future__ import annotations

import dataclasses
import json
import time
from functools import partial
from pathlib import Path
from typing import Any, Callable, NamedTuple, Sequence

import jax
import jax.numpy as jnp
import numpy as np
from tqdm.auto import tqdm

from xted.atomic import atomic_path
from xted.data import Dataset, check_dimensions
from xted.envs import Domain, dataset_env, make
from xted.envs.make import action_bounds
from xted.errors import InputError, warn_data
from xted.jsonfiles import read_json
from xted.resume import check_same_run
from xted.rl import igdf, otdf
from xted.rl.config import IQL_WRAPPERS, OFFLINE_ALGORITHMS, TRAINING_SEGMENT, IGDFConfig, OTDFConfig
from xted.rl.bc import BCConfig, bc_update, deterministic_act, init_bc
from xted.rl.dara import CLASSIFIER_INPUTS, DARAConfig, corrected_rewards, source_reward_deltas
from xted.rl.evaluation import PolicyFn, evaluate
from xted.rl.iql import IQLConfig, iql_act, iql_step, init_iql, locomotion_reward_scale
from xted.progress import restart_rate
from xted.rl.policy_io import POLICY_FILE, Policy, to_action_range
from xted.rl.source_weighting import ScoredSource, weigh_batch
from xted.rl.td3bc import TD3BCConfig, init_td3bc, td3bc_update

AlgoConfig = IQLConfig | TD3BCConfig | BCConfig | DARAConfig | IGDFConfig | OTDFConfig
Learner = IQLConfig | TD3BCConfig | BCConfig
OBS_STD_EPS = 1e-3


class Algorithm(NamedTuple):
    """An offline learner: every one has the same signatures."""

    init: Callable[..., Any]  # (rng, obs_dim, action_dim, config, steps) -> state; steps: the run's length
    update: Callable[..., Any]  # (state, batch, config, step, actor_penalty=None) -> (state, info); step: its index
    act: Callable[..., Any]  # (actor TrainState, standardised obs) -> actions
    policy_kind: str  # the actor's kind in a saved policy (xted.rl.policy_io)


_ALGORITHMS: dict[type, Algorithm] = {
    IQLConfig: Algorithm(init_iql, iql_step, iql_act, "gaussian"),
    TD3BCConfig: Algorithm(init_td3bc, td3bc_update, deterministic_act, "deterministic"),
    BCConfig: Algorithm(init_bc, bc_update, deterministic_act, "deterministic"),
}


def default_config(name: str) -> AlgoConfig:
    if name not in OFFLINE_ALGORITHMS:
        raise InputError(f"unknown algorithm {name!r}; known: {', '.join(OFFLINE_ALGORITHMS)}")
    return OFFLINE_ALGORITHMS[name]()


def algorithm_name(config: AlgoConfig) -> str:
    return next(name for name, kind in OFFLINE_ALGORITHMS.items() if isinstance(config, kind))


def learner_config(config: AlgoConfig) -> Learner:
    """The config of the networks trained: the IQL backbone of DARA, IGDF and OTDF, else the config itself."""
    return config.iql if isinstance(config, IQL_WRAPPERS) else config


# ------------------------------------------------------------------------------------------- data
@dataclasses.dataclass(frozen=True, eq=False)
class OfflineData:
    """Training arrays (observations standardised), the standardisation, and the target's share."""

    arrays: dict[str, np.ndarray]  # observations, actions, rewards, next_observations, terminals
    obs_mean: np.ndarray
    obs_std: np.ndarray
    target_size: int
    action_range: tuple[np.ndarray, np.ndarray] | None = None  # actions were rescaled from it into [-1, 1]


ACTION_TOLERANCE = 1e-6


def action_range(actions: np.ndarray, declared: tuple[np.ndarray, np.ndarray] | None
                 ) -> tuple[np.ndarray, np.ndarray] | None:
    """The range a policy must act in, where it is not [-1, 1] (the learners' tanh range): the env's
    declared action space, else the data's own per dimension (widened to [-1, 1]). Actions outside a
    declared space are reported (the policy cannot reproduce them); a range learnt from the data is
    reported too, so no saturation goes unsaid."""
    if declared is not None:
        low, high = (np.asarray(b, np.float64) for b in declared)
        outside = ((actions < low - ACTION_TOLERANCE) | (actions > high + ACTION_TOLERANCE)).any(axis=1)
        if outside.any():
            warn_data(f"{outside.mean():.1%} of the training actions lie outside the env's action space "
                      f"[{low.min():g}, {high.max():g}] (up to {np.abs(actions).max():.3g}): the policy acts inside "
                      "it, so it cannot reproduce them")
    else:
        low, high = np.minimum(actions.min(axis=0), -1.0), np.maximum(actions.max(axis=0), 1.0)
        wider = np.flatnonzero((low < -1 - ACTION_TOLERANCE) | (high > 1 + ACTION_TOLERANCE))
        if wider.size:
            warn_data(f"actions of dimension(s) {wider.tolist()} span beyond [-1, 1] (up to "
                      f"{np.abs(actions).max():.3g}) and the data records no env whose action space says otherwise: "
                      "the policy learns them rescaled into [-1, 1] and acts in the data's range (action_low / "
                      "action_high of the saved policy)")
    if np.allclose(low, -1.0) and np.allclose(high, 1.0):
        return None
    return low.astype(np.float32), high.astype(np.float32)


def prepare_data(target: Dataset, sources: Sequence[Dataset], normalize_rewards: bool = False,
                 next_states: bool = True, declared_actions: tuple[np.ndarray, np.ndarray] | None = None
                 ) -> OfflineData:
    """Target then sources as flat arrays; with ``normalize_rewards`` IQL's locomotion reward scale.
    Without ``next_states`` (behaviour cloning) the arrays hold no next observations, so data that
    stores none trains too. Actions are rescaled into [-1, 1] from :func:`action_range`'s range
    (``declared_actions``: the env's action space) where that is not [-1, 1]."""
    datasets = [target, *sources]
    actions = np.concatenate([d.actions for d in datasets])
    scale = action_range(actions, declared_actions)
    if scale is not None:
        actions = 2 * (actions - scale[0]) / (scale[1] - scale[0]) - 1
    observations = np.concatenate([d.observations for d in datasets])
    mean = observations.mean(axis=0)
    std = observations.std(axis=0) + OBS_STD_EPS
    rewards = np.concatenate([d.rewards for d in datasets])
    if normalize_rewards:
        rewards = rewards * locomotion_reward_scale(np.concatenate([d.episode_returns() for d in datasets]))
    arrays = {
        "observations": (observations - mean) / std,
        "actions": actions,
        "rewards": rewards,
        "terminals": np.concatenate([d.terminals for d in datasets]),
    }
    if next_states:
        arrays["next_observations"] = (np.concatenate([d.require_next_observations() for d in datasets]) - mean) / std
    arrays = {k: v.astype(np.float32) for k, v in arrays.items()}
    return OfflineData(arrays, mean.astype(np.float32), std.astype(np.float32), len(target), scale)


def s4rl_augment(batch: dict, key, std: float) -> dict:
    """S4RL's Gaussian-noise augmentation: independent N(0, std^2) noise on s and s' (where the batch has s')."""
    keys = dict(zip(("observations", "next_observations"), jax.random.split(key)))
    return {**batch, **{name: batch[name] + std * jax.random.normal(keys[name], batch[name].shape)
                        for name in keys if name in batch}}


# --------------------------------------------------------------------------------------- training
_STATIC_INIT = ("config", "obs_dim", "action_dim", "steps")


@partial(jax.jit, static_argnames=_STATIC_INIT)
def init_state(config: Learner, rng, obs_dim: int, action_dim: int, steps: int):
    """A fresh state; ``steps`` is the run's length (IQL's actor learning-rate schedule)."""
    return _ALGORITHMS[type(config)].init(rng, obs_dim, action_dim, config, steps)


@partial(jax.jit, static_argnames=_STATIC_INIT)
def init_seeds(config: Learner, keys, obs_dim: int, action_dim: int, steps: int):
    """States of every seed (one key each), stacked on a leading axis."""
    return jax.vmap(lambda key: init_state(config, key, obs_dim, action_dim, steps))(keys)


_STATIC_TRAIN = ("config", "steps", "s4rl_noise", "source_filter")
# Rows that differ between seeds: DARA's rewards, IGDF's and OTDF's scores, OTDF's decoded behaviour actions.
PER_SEED_ROWS = ("rewards", "source_score", "behaviour_actions")


@partial(jax.jit, static_argnames=_STATIC_TRAIN)
def train_steps(config: Learner, state, key, data: dict, steps: int, s4rl_noise: float = 0.0, start=0,
                source_filter: ScoredSource | None = None):
    """``steps`` updates of one seed on batches drawn from ``data``: (state, key, per-step infos).

    ``start`` is the index of the first update. It is passed apart from the state so that under
    ``vmap`` over seeds it stays unbatched and a schedule on it (TD3+BC's delayed actor step)
    remains a ``lax.cond`` instead of becoming a select that computes both branches.
    ``source_filter`` (IGDF's or OTDF's config) keeps and weights each batch's source transitions
    by ``data["source_score"]``; ``data["behaviour_actions"]`` (OTDF's decoded behaviour actions per
    state) regularises the actor.
    """
    update = _ALGORITHMS[type(config)].update
    size = data["observations"].shape[0]

    def step(carry, index):
        state, key = carry
        key, batch_key, noise_key = jax.random.split(key, 3)
        idx = jax.random.randint(batch_key, (config.batch_size,), 0, size)
        batch = {k: v[idx] for k, v in data.items()}
        if s4rl_noise > 0:
            batch = s4rl_augment(batch, noise_key, s4rl_noise)
        extra = {}
        if source_filter is not None:
            batch = weigh_batch(batch, source_filter)
        if "behaviour_actions" in batch:
            extra["actor_penalty"] = otdf.behaviour_penalty(batch.pop("behaviour_actions"), source_filter)
        state, info = update(state, batch, config, index, **extra)
        return (state, key), info

    (state, key), infos = jax.lax.scan(step, (state, key), start + jnp.arange(steps))
    return state, key, infos


@partial(jax.jit, static_argnames=_STATIC_TRAIN)
def train_seeds(config: Learner, states, keys, data: dict, steps: int, s4rl_noise: float = 0.0, start=0,
                source_filter: ScoredSource | None = None):
    """:func:`train_steps` vmapped over stacked seeds; ``data``'s PER_SEED_ROWS (``rewards``, and
    ``source_score`` and ``behaviour_actions`` where it has them) have the seeds on their first axis."""
    own = {k: data[k] for k in PER_SEED_ROWS if k in data}

    def one(state, key, rows):
        return train_steps(config, state, key, {**data, **rows}, steps, s4rl_noise, start, source_filter)

    return jax.vmap(one)(states, keys, own)


@partial(jax.jit, static_argnames="config")
def _greedy(config: Learner, actor, obs, obs_mean, obs_std):
    return jnp.clip(_ALGORITHMS[type(config)].act(actor, (obs - obs_mean) / obs_std), -1.0, 1.0)


def seed_policy(config: Learner, actor, obs_mean: np.ndarray, obs_std: np.ndarray,
                action_range: tuple[np.ndarray, np.ndarray] | None = None) -> PolicyFn:
    """Evaluation policy of one seed's actor: standardise, act (greedy), clip to [-1, 1], and map into
    ``action_range`` where the data's actions were rescaled from it."""
    def act(obs):
        action = np.asarray(_greedy(config, actor, jnp.asarray(obs, jnp.float32), obs_mean, obs_std))
        return action if action_range is None else to_action_range(action, *action_range)
    return act


# ----------------------------------------------------------------------------------------- driver
def _segment_ends(steps: int, eval_every: int, chunk: int = TRAINING_SEGMENT) -> list[int]:
    ends = set(range(chunk, steps, chunk)) | set(range(eval_every, steps, eval_every)) | {steps}
    return sorted(ends)


def _check_inputs(target: Dataset, sources: Sequence[Dataset], domain: Domain | None, steps: int,
                  seeds: Sequence[int], eval_every: int, eval_episodes: int, s4rl_noise: float,
                  config: AlgoConfig, out_dir: str | Path | None, save_dir: str | Path | None) -> None:
    for name, value in (("steps", steps), ("eval_every", eval_every), ("eval_episodes", eval_episodes)):
        if value <= 0:
            raise InputError(f"{name} must be positive, got {value}")
    if not seeds or len(set(seeds)) != len(seeds) or any(s < 0 for s in seeds):
        raise InputError(f"seeds must be distinct non-negative integers, got {list(seeds)}")
    if not s4rl_noise >= 0:
        raise InputError(f"the S4RL noise std must be >= 0, got {s4rl_noise}")
    if not isinstance(config, BCConfig):
        for data in (target, *sources):
            data.require_rewards(algorithm_name(config), "train bc, which learns from the actions alone")
    if isinstance(config, IQL_WRAPPERS) and not sources:
        raise InputError(f"{algorithm_name(config)} weighs source data against the target: give at least one "
                         "source dataset")
    for name, folder in (("results", out_dir), ("policies", save_dir)):
        if folder is not None and Path(folder).exists() and not Path(folder).is_dir():
            raise InputError(f"{folder} is not a folder: cannot keep {name} there")
    if domain is None:
        dims, where = (target.observation_dim, target.action_dim), "the target"
    else:
        env = make(domain)
        dims, where = (env.observation_space.shape[0], env.action_space.shape[0]), domain.name
        env.close()
    for i, data in enumerate([target, *sources]):
        check_dimensions(data, dims, "the target dataset" if i == 0 else f"source dataset {i - 1}", where)


def train_offline(
    algo: str | AlgoConfig,
    target: Dataset,
    sources: Sequence[Dataset],
    domain: Domain | None,
    steps: int,
    seeds: Sequence[int],
    eval_every: int = 10_000,
    eval_episodes: int = 10,
    out_dir: str | Path | None = None,
    progress: bool = True,
    s4rl_noise: float = 0.0,
    save_dir: str | Path | None = None,
) -> list[dict]:
    """Train ``algo`` on target + sources for every seed at once; evaluate in ``domain``.

    Evaluates every ``eval_every`` steps and at the end; with ``domain`` None nothing is evaluated
    (``final_score`` and ``best_score`` are None, ``evals`` empty) and the progress bar shows the
    losses instead. Returns one result per seed (in ``seeds`` order): ``final_score`` and
    ``best_score`` (normalised), the evaluations, ``losses`` (each loss and value estimate the update
    reports, averaged over every 1,000 updates or evaluation interval), training speed, and ``policy``,
    the trained :class:`~xted.rl.policy_io.Policy` (absent for a seed resumed from ``out_dir`` alone,
    whose actor was not saved).

    With ``out_dir`` each seed's result is written to ``out_dir/seed_N.json`` when it finishes; with
    ``save_dir`` its policy to the folder ``save_dir/seed_N``. A seed is loaded instead of trained
    when what was asked for is there (a result, and a policy where ``save_dir`` is given); files of
    another run are an InputError.
    """
    config = default_config(algo) if isinstance(algo, str) else algo
    learner = learner_config(config)
    seeds = [int(s) for s in seeds]
    _check_inputs(target, sources, domain, steps, seeds, eval_every, eval_episodes, s4rl_noise, config, out_dir,
                  save_dir)
    run = json.loads(json.dumps({
        "algo": algorithm_name(config), "config": dataclasses.asdict(config),
        "domain": None if domain is None else domain.name, "steps": steps,
        "transitions": len(target) + sum(len(s) for s in sources),
        "data": [dataset.fingerprint() for dataset in (target, *sources)], "s4rl_noise": s4rl_noise,
        "eval_every": eval_every, "eval_episodes": eval_episodes,
    }))
    done = {seed: _load_seed(out_dir, save_dir, seed, run) for seed in seeds}
    todo = [seed for seed in seeds if done[seed] is None]
    if todo:
        for result in _train_group(config, learner, target, sources, domain, todo, run, progress):
            seed = result["seed"]
            if save_dir is not None:
                result["policy"].save(policy_folder(save_dir, seed))
            if out_dir is not None:
                with atomic_path(Path(out_dir) / f"seed_{seed}.json") as tmp:
                    tmp.write_text(json.dumps({k: v for k, v in result.items() if k != "policy"}, indent=2))
            done[seed] = result
    return [done[seed] for seed in seeds]


def policy_folder(save_dir: str | Path, seed: int) -> Path:
    return Path(save_dir) / f"seed_{seed}"


def _load_seed(out_dir: str | Path | None, save_dir: str | Path | None, seed: int, run: dict) -> dict | None:
    """A finished seed's result (with its policy where ``save_dir`` is given), or None to train it."""
    result = None if out_dir is None else _load_result(Path(out_dir), seed, run)
    if save_dir is None:
        return result
    folder = policy_folder(save_dir, seed)
    if not (folder / POLICY_FILE).exists():
        return None
    policy = Policy.load(folder)
    check_same_run(folder, {k: policy.meta.get(k) for k in run}, run)
    if result is None:
        result = {**run, "seed": seed, **policy.meta["scores"]}
    return {**result, "policy": policy}


def _load_result(out_dir: Path, seed: int, run: dict) -> dict | None:
    path = out_dir / f"seed_{seed}.json"
    if not path.exists():
        return None
    result = read_json(path, "unreadable result", f"remove it to retrain seed {seed}")
    check_same_run(path, {k: result.get(k) for k in run}, run)
    return result


def _policy(learner: Learner, actor_params, data: OfflineData, obs_dim: int, action_dim: int, meta: dict) -> Policy:
    """A trained seed's actor as a :class:`Policy` that standardises observations as training did."""
    return Policy(actor_params, {
        **meta, "policy": _ALGORITHMS[type(learner)].policy_kind, "hidden": list(learner.hidden),
        "obs_dim": obs_dim, "action_dim": action_dim,
        "obs_mean": data.obs_mean.tolist(), "obs_std": data.obs_std.tolist(),
        **({} if data.action_range is None else {"action_low": data.action_range[0].tolist(),
                                                 "action_high": data.action_range[1].tolist()})})


def _weigh_source(config: AlgoConfig, data: OfflineData, keys) -> tuple[np.ndarray, dict, Any]:
    """What the learner reads beside the transitions, per seed (one key each): the rewards ``[S, N]``
    (DARA's corrected on the source's share), IGDF's or OTDF's ``is_source`` and ``source_score``
    rows, and OTDF's behaviour CVAEs (None for the others)."""
    seeds, n = len(keys), data.target_size
    rewards = np.broadcast_to(data.arrays["rewards"], (seeds, len(data.arrays["rewards"])))
    if not isinstance(config, IQL_WRAPPERS):
        return rewards, {}, None
    target = {k: data.arrays[k][:n] for k in CLASSIFIER_INPUTS}
    source = {k: data.arrays[k][n:] for k in CLASSIFIER_INPUTS}
    if isinstance(config, DARAConfig):
        deltas, _ = source_reward_deltas(keys, target, source, config)
        return np.concatenate([rewards[:, :n], corrected_rewards(rewards[:, n:], deltas, config)], axis=1), {}, None
    behaviour = None
    if isinstance(config, IGDFConfig):
        scores, _ = igdf.source_scores(keys, target, source, config)
    else:
        scores = np.broadcast_to(-otdf.source_deviations(target, source, config), (seeds, rewards.shape[1] - n))
        behaviour, _ = otdf.train_behaviours(keys, target, config)
    rows = {"is_source": jnp.asarray(np.arange(rewards.shape[1]) >= n, jnp.float32),
            "source_score": jnp.asarray(np.concatenate([np.zeros((seeds, n)), scores], axis=1), jnp.float32)}
    return rewards, rows, behaviour


def _train_group(config: AlgoConfig, learner: Learner, target: Dataset, sources: Sequence[Dataset],
                 domain: Domain | None, seeds: list[int], run: dict, progress: bool) -> list[dict]:
    steps, eval_every, s4rl_noise = run["steps"], run["eval_every"], run["s4rl_noise"]
    data = prepare_data(target, sources, getattr(learner, "normalize_rewards", False),
                        next_states=not isinstance(learner, BCConfig),
                        declared_actions=action_bounds(domain.env if domain else dataset_env(target.metadata)))
    keys = jax.vmap(lambda s: jax.random.split(jax.random.PRNGKey(s), 3))(jnp.asarray(seeds))
    init_keys, train_keys, source_keys = keys[:, 0], keys[:, 1], keys[:, 2]
    rewards, rows, behaviour = _weigh_source(config, data, source_keys)
    source_filter = config if isinstance(config, IGDFConfig | OTDFConfig) else None
    device_data = {**{k: jnp.asarray(v) for k, v in data.arrays.items()}, "rewards": jnp.asarray(rewards), **rows}
    states = init_seeds(learner, init_keys, target.observation_dim, target.action_dim, steps)

    def actor(i: int):
        return jax.tree.map(lambda x: jnp.asarray(np.asarray(x)[i]), states.actor)

    evals: list[list[dict]] = [[] for _ in seeds]
    losses: list[list[dict]] = [[] for _ in seeds]
    train_seconds, position = 0.0, 0
    description = f"{run['algo']} x{len(seeds)} seeds"
    bar = tqdm(total=steps, desc=description, unit="step", disable=not progress, smoothing=0.1)
    for end in _segment_ends(steps, eval_every):
        started = time.perf_counter()
        if behaviour is not None and position % config.behaviour_redraw_every == 0:
            draw_keys = jax.vmap(jax.random.fold_in, (0, None))(source_keys, 1 + position)  # 0: the CVAEs' own
            device_data["behaviour_actions"] = otdf.decode_behaviours(behaviour, device_data["observations"],
                                                                      draw_keys, config, target.action_dim)
        states, train_keys, infos = train_seeds(learner, states, train_keys, device_data, end - position, s4rl_noise,
                                                position, source_filter)
        jax.block_until_ready(states)
        train_seconds += time.perf_counter() - started
        segment = {name: np.asarray(values).mean(axis=1) for name, values in infos.items()}  # per seed
        for i in range(len(seeds)):
            losses[i].append({"step": end, **{name: float(means[i]) for name, means in segment.items()}})
        if domain is None:
            bar.set_postfix({name: f"{means.mean():.3g}" for name, means in segment.items() if name.endswith("loss")})
        bar.update(end - position)
        if position == 0:  # the first segment compiled: rate and ETA from the second on
            restart_rate(bar, description)
        position = end
        if domain is not None and (end % eval_every == 0 or end == steps):
            for i, seed in enumerate(seeds):
                policy = seed_policy(learner, actor(i), data.obs_mean, data.obs_std, data.action_range)
                result = evaluate(policy, domain, run["eval_episodes"], seed=seed * 1_000_003 + end)
                evals[i].append({"step": end, "normalized_score": result["normalized_score"],
                                 "return_mean": result["return_mean"]})
            bar.set_postfix(score=f"{np.mean([e[-1]['normalized_score'] for e in evals]):.1f}")
    bar.close()
    rate = steps * len(seeds) / train_seconds  # updates per second over all seeds, compilation included
    results = []
    for i, (seed, history) in enumerate(zip(seeds, evals)):
        scores = {"final_score": history[-1]["normalized_score"] if history else None,
                  "best_score": max(e["normalized_score"] for e in history) if history else None,
                  "evals": history, "losses": losses[i], "updates_per_second": rate}
        meta = {**run, "seed": seed, "scores": scores}
        results.append({**run, "seed": seed, **scores, "policy": _policy(
            learner, actor(i).params, data, target.observation_dim, target.action_dim, meta)})
    return results
