"""Training the diffusion prior on target windows, checkpointed and resumable.

A prior folder holds ``prior.json`` (format, full config, normaliser, return range, a fingerprint
and the env of the training data), ``log.csv`` (step, loss averaged since the previous row,
cumulative seconds) and ``checkpoints/`` (:mod:`xted.diffusion.checkpoint`). The loss and the
jitted step are in :mod:`xted.diffusion.objective`.
"""

from __future__ import annotations

import csv
import functools
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import orbax.checkpoint as ocp
from tqdm.auto import tqdm

from xted.data import Dataset, Normalizer, check_dimensions
from xted.data.windows import WindowSampler, warn_if_one_long_episode, window_index
from xted.diffusion.checkpoint import checkpoint_manager, prepare_out_dir, read_log, write_log
from xted.diffusion.config import PriorConfig
from xted.diffusion.guard import ENSEMBLE_MEMBERS, TargetModel, fit_target_model
from xted.diffusion.objective import init_train_state, make_train_step
from xted.diffusion.prior import FORMAT, normalize_returns
from xted.progress import restart_rate
from xted.envs.domains import dataset_env
from xted.errors import InputError, warn_data


def _normalized_fields(dataset: Dataset, normalizer: Normalizer, use_reward: bool) -> dict[str, np.ndarray]:
    flat = {
        "state": normalizer.normalize("observations", dataset.observations),
        "action": normalizer.normalize("actions", dataset.actions),
    }
    if use_reward:
        flat["reward"] = normalizer.normalize("rewards", dataset.rewards)[:, None]
    return {k: v.astype(np.float32) for k, v in flat.items()}


def training_windows(dataset: Dataset, normalizer: Normalizer, config: PriorConfig) -> tuple[WindowSampler, dict]:
    warn_if_one_long_episode(dataset, "the target data")
    index, skipped = window_index(dataset, config.horizon)
    raw_returns = dataset.rewards.astype(np.float64)[index].sum(axis=1)
    low, high = float(raw_returns.min()), float(raw_returns.max())
    loss_mask = np.ones(config.horizon, bool)
    loss_mask[0] = False
    sampler = WindowSampler(
        flat=_normalized_fields(dataset, normalizer, config.use_reward),
        index=index,
        returns=normalize_returns(raw_returns, (low, high)).astype(np.float32),
        loss_mask=loss_mask,
    )
    info = {"return_range": [low, high], "windows": int(len(index)), "skipped_episodes": int(skipped)}
    if skipped:
        warn_data(f"{skipped} of {dataset.num_episodes} target episodes are shorter than the prior's horizon "
                  f"({config.horizon} steps) and were left out of training")
    return sampler, info


def train_prior_folder(
    target_dataset: Dataset,
    out_dir: str | Path,
    config: PriorConfig,
    steps: int,
    progress: bool = True,
    log_every: int = 100,
    checkpoint_every: int = 1000,
) -> Path:
    """Train (or resume) the prior on ``target_dataset`` until ``steps`` updates; returns ``out_dir``.

    The normaliser is fitted on the target. A folder holding a prior of another config or other
    data is refused (InputError). Checkpoints every ``checkpoint_every`` steps and at the end.
    """
    out_dir = Path(out_dir)
    for name, value in (("steps", steps), ("log_every", log_every), ("checkpoint_every", checkpoint_every)):
        if int(value) != value or value < 1:
            raise InputError(f"train_prior_folder: {name} must be a positive integer, got {value}")
    check_dimensions(target_dataset, (config.state_dim, config.action_dim), "the target data",
                     "the config (state_dim, action_dim)")
    if config.use_reward or config.return_condition:
        target_dataset.require_rewards("a prior with a reward stream or return conditioning",
                                       "train with use_reward=False and return_condition=False (the presets "
                                       "turn both off for reward-free data)")
    normalizer = Normalizer.fit(target_dataset)
    sampler, info = training_windows(target_dataset, normalizer, config)
    meta = {
        "format": FORMAT,
        "config": config.to_dict(),
        "normalizer": normalizer.to_dict(),
        "return_range": info.pop("return_range"),
        "data": {"fingerprint": target_dataset.fingerprint(), "transitions": len(target_dataset),
                 "env": dataset_env(target_dataset.metadata), **info},
    }
    prepare_out_dir(out_dir, meta)

    init_key = jax.random.key(config.seed)
    data_rng = np.random.default_rng(config.seed)
    seconds = 0.0
    manager = checkpoint_manager(out_dir)
    start = manager.latest_step()
    if start is None:
        state = init_train_state(config, init_key)
    else:
        abstract = jax.eval_shape(functools.partial(init_train_state, config), init_key)
        restored = manager.restore(
            start, args=ocp.args.Composite(state=ocp.args.StandardRestore(abstract), sampler=ocp.args.JsonRestore())
        )
        state = jax.tree.map(np.asarray, restored.state)  # uncommitted, like a fresh state: no recompilation
        data_rng.bit_generator.state = restored.sampler["rng"]
        seconds = restored.sampler["seconds"]
    start = start or 0
    log_path = out_dir / "log.csv"
    rows = read_log(log_path, start)
    write_log(log_path, rows)

    step_fn = make_train_step(config)
    rng = jax.random.key(config.seed + 1)
    losses: list[jnp.ndarray] = []
    bar = tqdm(total=steps, initial=start, disable=not progress or start >= steps, unit="step",
               desc="prior (compiling)")
    began = time.perf_counter() - seconds
    try:
        with log_path.open("a", newline="") as log_file:
            writer = csv.writer(log_file)
            for step in range(start + 1, steps + 1):
                state, metrics = step_fn(state, sampler.batch(data_rng, config.batch_size), rng)
                losses.append(metrics["loss"])
                bar.update(1)
                if step == start + 1:  # the rate and ETA from here on: the first step compiled
                    jax.block_until_ready(metrics["loss"])
                    restart_rate(bar, "prior")
                if step % log_every == 0 or step == steps:
                    loss = float(np.mean(jax.device_get(losses)))
                    losses = []
                    writer.writerow([step, loss, time.perf_counter() - began])
                    log_file.flush()
                    bar.set_postfix(loss=f"{loss:.4f}")
                if step % checkpoint_every == 0 or step == steps:
                    sampler_state = {"rng": data_rng.bit_generator.state, "seconds": time.perf_counter() - began}
                    manager.save(
                        step,
                        args=ocp.args.Composite(
                            state=ocp.args.StandardSave(state), sampler=ocp.args.JsonSave(sampler_state)
                        ),
                    )
    finally:
        bar.close()
        manager.wait_until_finished()
        manager.close()
    if TargetModel.load(out_dir) is None:  # written once training is complete
        fit_target_model(target_dataset, seed=config.seed, progress=progress, members=ENSEMBLE_MEMBERS).save(out_dir)
    return out_dir
