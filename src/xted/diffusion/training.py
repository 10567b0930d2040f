"""Training the diffusion prior on target windows, checkpointed and resumable.

A prior folder holds ``prior.json`` (format, full config, normaliser, return range, a fingerprint
of the training data), ``log.csv`` (step, loss averaged since the previous row, cumulative
seconds) and ``checkpoints/`` (Orbax: params, EMA params, optimiser state, step, and the state of
the NumPy generator that draws batches, so a killed run resumes exactly).

Loss: epsilon-prediction MSE with the first transition of every window held clean (inpainting)
and excluded. Every unmasked scalar counts equally: the squared errors of all streams are summed
and divided by the number of unmasked elements (``unmasked steps * (ds + da + 1)``), so a
17-d state weighs 17 times a reward.
"""

from __future__ import annotations

import csv
import dataclasses
import functools
import json
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import flax.serialization
import flax.struct
import jax
import jax.numpy as jnp
import numpy as np
import optax
import orbax.checkpoint as ocp
from tqdm.auto import tqdm

from xted.atomic import atomic_path
from xted.data import Dataset, Normalizer
from xted.data.windows import window_index
from xted.diffusion.denoiser import ARCHITECTURES, Denoiser, DenoiserConfig, apply_inverse, init_params
from xted.diffusion.schedule import Schedule, cosine_schedule, q_sample
from xted.envs.domains import dataset_env
from xted.errors import InputError

FORMAT = "xted-prior/1"

# Per-sample loss weight as a function of the signal-to-noise ratio of the sampled timestep.
LOSS_WEIGHTS: dict[str, Callable[[jnp.ndarray], jnp.ndarray]] = {
    "uniform": jnp.ones_like,
    "min_snr": lambda snr: jnp.minimum(snr, 5.0) / snr,  # Min-SNR-5 (Hang et al. 2023), eps-prediction
}

_DENOISER_FIELDS = tuple(f.name for f in dataclasses.fields(DenoiserConfig))


@dataclass(frozen=True)
class PriorConfig(DenoiserConfig):
    """The denoiser's architecture (the fields of :class:`DenoiserConfig`), diffusion and
    optimisation, in one flat record so that every field is a ``--set FIELD=VALUE`` override.

    Learning rate: linear warm-up over ``warmup_steps``, then constant, or, with ``decay_steps``,
    multiplied by a cosine from 1 at step 0 to 0.1 at ``decay_steps`` (constant after).
    """

    num_timesteps: int = 200
    batch_size: int = 256
    learning_rate: float = 2e-4
    warmup_steps: int = 0
    decay_steps: int | None = None
    grad_clip: float | None = 1.0
    ema_decay: float = 0.999
    condition_dropout: float = 0.25
    loss_weighting: str = "uniform"
    seed: int = 0

    def __post_init__(self) -> None:
        checks = [
            (self.state_dim >= 1 and self.action_dim >= 1, "state_dim and action_dim must be >= 1"),
            (self.horizon >= 2, f"horizon must be >= 2, got {self.horizon}"),
            (self.num_timesteps >= 1, f"num_timesteps must be >= 1, got {self.num_timesteps}"),
            (self.batch_size >= 1, f"batch_size must be >= 1, got {self.batch_size}"),
            (self.warmup_steps >= 0, f"warmup_steps must be >= 0, got {self.warmup_steps}"),
            (self.decay_steps is None or self.decay_steps >= 1, f"decay_steps must be >= 1, got {self.decay_steps}"),
            (0.0 <= self.ema_decay < 1.0, f"ema_decay must be in [0, 1), got {self.ema_decay}"),
            (0.0 <= self.condition_dropout <= 1.0,
             f"condition_dropout must be in [0, 1], got {self.condition_dropout}"),
            (self.loss_weighting in LOSS_WEIGHTS, f"loss_weighting must be one of {sorted(LOSS_WEIGHTS)}"),
            (self.architecture in ARCHITECTURES,
             f"architecture must be one of {list(ARCHITECTURES)}, got {self.architecture!r}"),
            (min(map(self.denoiser.width, self.denoiser.streams)) >= 1, "every stream width must be >= 1"),
        ]
        for ok, message in checks:
            if not ok:
                raise InputError(f"PriorConfig: {message}")

    @property
    def denoiser(self) -> DenoiserConfig:
        return DenoiserConfig(**{name: getattr(self, name) for name in _DENOISER_FIELDS})

    def to_dict(self) -> dict[str, Any]:
        return json.loads(json.dumps(dataclasses.asdict(self)))

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> PriorConfig:
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = set(data) - names
        if unknown:
            raise InputError(f"PriorConfig: unknown fields {sorted(unknown)}")
        return cls(**data)


def _paper(state_dim: int, action_dim: int) -> PriorConfig:
    """The paper's setup (appendix hyperparameter table). Optimiser settings are not stated there;
    Adam at 2e-4 with batch 256 follows Diffuser / Decision Diffuser, plus a short warm-up."""
    return PriorConfig(
        state_dim=state_dim, action_dim=action_dim, width_multiplier=16, state_blocks=2, action_blocks=2,
        reward_blocks=1, horizon=20, num_timesteps=200, batch_size=256, learning_rate=2e-4,
        warmup_steps=1000, return_condition=True,
    )


def _cpu(state_dim: int, action_dim: int) -> PriorConfig:
    """Small, fast configuration for a 2-core CPU: stream widths 4x the element's dim (at least 32),
    one block per stream, batch 128 (about 3.4 GFLOP per step; BENCHMARKS.md has the curve that chose it)."""
    return PriorConfig(
        state_dim=state_dim, action_dim=action_dim, width_multiplier=4, min_width=32, state_blocks=1,
        action_blocks=1, reward_blocks=1, cond_dim=64, horizon=20, num_timesteps=200, batch_size=128, learning_rate=1e-3,
        warmup_steps=500, decay_steps=50_000, return_condition=True,
    )


def presets() -> dict[str, Callable[[int, int], PriorConfig]]:
    """Named configurations as functions of ``(state_dim, action_dim)``."""
    return {"paper": _paper, "cpu": _cpu}


def preset(name: str, state_dim: int, action_dim: int, **overrides: Any) -> PriorConfig:
    """``presets()[name](state_dim, action_dim)`` with fields replaced by ``overrides``."""
    table = presets()
    if name not in table:
        raise InputError(f"unknown prior preset {name!r}; expected one of {sorted(table)}")
    return dataclasses.replace(table[name](state_dim, action_dim), **overrides)


# --------------------------------------------------------------------------- pure training step
@flax.struct.dataclass
class TrainState:
    params: Any
    ema_params: Any
    opt_state: Any
    step: jnp.ndarray


def learning_rate(config: PriorConfig, step: jnp.ndarray) -> jnp.ndarray:
    step = jnp.asarray(step, jnp.float32)
    lr = jnp.float32(config.learning_rate)
    if config.warmup_steps:
        lr = lr * jnp.minimum(1.0, (step + 1) / config.warmup_steps)
    if config.decay_steps is not None:
        progress = jnp.clip(step / config.decay_steps, 0.0, 1.0)
        lr = lr * (0.1 + 0.45 * (1 + jnp.cos(jnp.pi * progress)))
    return lr


def make_optimizer(config: PriorConfig) -> optax.GradientTransformation:
    """Adam after global-norm clipping, on the flattened parameter vector (one fused update
    instead of one per parameter array: faster to compile and to run on a CPU)."""
    adam = optax.adam(functools.partial(learning_rate, config))
    if config.grad_clip is not None:
        adam = optax.chain(optax.clip_by_global_norm(config.grad_clip), adam)
    return optax.flatten(adam)


@functools.partial(jax.jit, static_argnums=0)
def init_train_state(config: PriorConfig, rng: jax.Array) -> TrainState:
    """Fresh parameters (EMA equal to them), optimiser state and step 0."""
    h = config.horizon
    dummy = lambda d: jnp.zeros((1, h, d), jnp.float32)  # noqa: E731
    params = init_params(
        config.denoiser, rng, dummy(config.state_dim), dummy(config.action_dim),
        dummy(1) if config.use_reward else None, jnp.zeros(1, jnp.int32), jnp.zeros(1, jnp.float32), jnp.zeros(1, bool),
    )
    return TrainState(
        params=params,
        ema_params=jax.tree.map(jnp.copy, params),
        opt_state=make_optimizer(config).init(params),
        step=jnp.zeros((), jnp.int32),
    )


def loss_fn(
    params: Any, batch: dict[str, jnp.ndarray], rng: jax.Array, *, model: Denoiser, schedule: Schedule,
    config: PriorConfig,
) -> tuple[jnp.ndarray, dict[str, jnp.ndarray]]:
    """Masked epsilon MSE. ``batch``: one ``[B, H, d]`` array per stream ("state", "action",
    "reward"), ``loss_mask [B, H]`` and ``returns [B]`` (normalised to [0, 1]).

    Inv adds the MSE of its inverse models on the window's clean transitions (every one of them,
    the held first included); ``mse_action`` / ``mse_reward`` then report those."""
    streams = config.denoiser.diffused_streams
    mask = batch["loss_mask"].astype(jnp.float32)
    b = mask.shape[0]
    t_rng, drop_rng, noise_rng = jax.random.split(rng, 3)
    t = jax.random.randint(t_rng, (b,), 0, schedule.num_timesteps)
    noise = {s: jax.random.normal(jax.random.fold_in(noise_rng, i), batch[s].shape) for i, s in enumerate(streams)}
    x_t = {s: batch[s] for s in config.denoiser.streams}  # streams not diffused are read by no model
    for s in streams:
        noised = q_sample(schedule, batch[s], t, noise[s])
        x_t[s] = noised.at[:, 0].set(batch[s][:, 0])
    drop = jax.random.bernoulli(drop_rng, config.condition_dropout, (b,))
    returns = batch["returns"] if config.return_condition else None
    eps = model.apply(params, x_t["state"], x_t["action"], x_t.get("reward"), t, returns, drop)
    abar = schedule.alphas_cumprod[t]
    weight = LOSS_WEIGHTS[config.loss_weighting](abar / (1 - abar))
    metrics, total = {}, 0.0
    for s, e in zip(streams, eps):
        se = jnp.sum(jnp.square(e - noise[s]), axis=-1) * mask
        metrics[f"mse_{s}"] = jnp.sum(se) / (jnp.sum(mask) * e.shape[-1])
        total = total + jnp.sum(weight[:, None] * se)
    dims = sum(config.denoiser.element_dim(s) for s in streams)
    loss = total / (jnp.sum(mask) * dims)
    if config.architecture == "inverse_dynamics":
        predicted = apply_inverse(config.denoiser, params, batch["state"], batch["action"])
        for s, p in zip(("action", "reward"), predicted):
            if p is not None:
                metrics[f"mse_{s}"] = jnp.mean(jnp.square(p - batch[s][:, :-1]))
                loss = loss + metrics[f"mse_{s}"]
    return loss, {"loss": loss, **metrics}


def train_step(
    state: TrainState, batch: dict[str, jnp.ndarray], rng: jax.Array, *, model: Denoiser,
    optimizer: optax.GradientTransformation, schedule: Schedule, config: PriorConfig,
) -> tuple[TrainState, dict[str, jnp.ndarray]]:
    """One update: gradient of :func:`loss_fn` (noise from ``rng`` folded with the step), optimiser, EMA."""
    step_rng = jax.random.fold_in(rng, state.step)
    grads, metrics = jax.grad(loss_fn, has_aux=True)(
        state.params, batch, step_rng, model=model, schedule=schedule, config=config
    )
    updates, opt_state = optimizer.update(grads, state.opt_state, state.params)
    params = optax.apply_updates(state.params, updates)
    d = config.ema_decay
    ema = jax.tree.map(lambda e, p: d * e + (1 - d) * p, state.ema_params, params)
    return TrainState(params, ema, opt_state, state.step + 1), metrics


@functools.lru_cache(maxsize=8)
def make_train_step(config: PriorConfig) -> Callable[..., tuple[TrainState, dict[str, jnp.ndarray]]]:
    """``train_step`` bound to ``config`` and jitted: ``(state, batch, rng) -> (state, metrics)``."""
    return jax.jit(
        functools.partial(
            train_step, model=Denoiser(config.denoiser), optimizer=make_optimizer(config),
            schedule=cosine_schedule(config.num_timesteps), config=config,
        )
    )


# ------------------------------------------------------------------------------- training data
@dataclass(frozen=True, eq=False)
class WindowSampler:
    """Stride-1 windows of the normalised target, gathered per batch from flat arrays."""

    flat: dict[str, np.ndarray]
    index: np.ndarray
    returns: np.ndarray
    loss_mask: np.ndarray

    def batch(self, rng: np.random.Generator, size: int) -> dict[str, np.ndarray]:
        pick = rng.integers(0, len(self.index), size=size)
        rows = self.index[pick]
        out = {name: values[rows] for name, values in self.flat.items()}
        out["loss_mask"] = np.broadcast_to(self.loss_mask, rows.shape)
        out["returns"] = self.returns[pick]
        return out


def _normalized_fields(dataset: Dataset, normalizer: Normalizer, use_reward: bool) -> dict[str, np.ndarray]:
    flat = {
        "state": normalizer.normalize("observations", dataset.observations),
        "action": normalizer.normalize("actions", dataset.actions),
    }
    if use_reward:
        flat["reward"] = normalizer.normalize("rewards", dataset.rewards)[:, None]
    return {k: v.astype(np.float32) for k, v in flat.items()}


def _window_sampler(dataset: Dataset, normalizer: Normalizer, config: PriorConfig) -> tuple[WindowSampler, dict]:
    index, skipped = window_index(dataset, config.horizon, stride=1, short_episodes="skip")
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
    return sampler, info


def split_heldout(dataset: Dataset, episodes: int, seed: int = 0) -> tuple[Dataset, Dataset | None]:
    """(training part, ``episodes`` held-out episodes chosen at random, or None for 0): the held-out
    episodes measure the prior's floor, the same edit applied to target data it never saw."""
    if not 0 <= episodes < dataset.num_episodes:
        raise InputError(f"cannot hold out {episodes} of {dataset.num_episodes} episodes")
    if episodes == 0:
        return dataset, None
    order = np.random.default_rng(seed).permutation(dataset.num_episodes)
    return dataset.select_episodes(np.sort(order[episodes:])), dataset.select_episodes(np.sort(order[:episodes]))


def normalize_returns(raw: Any, return_range: tuple[float, float]) -> Any:
    """Window returns mapped to [0, 1] by the target's (min, max) window return, clipped."""
    low, high = return_range
    return np.clip((np.asarray(raw, np.float64) - low) / max(high - low, 1e-8), 0.0, 1.0)


# -------------------------------------------------------------------------------- train / load
def _checkpoint_manager(out_dir: Path) -> ocp.CheckpointManager:
    options = ocp.CheckpointManagerOptions(max_to_keep=2, create=True)
    return ocp.CheckpointManager(out_dir.resolve() / "checkpoints", options=options)


def _read_json(path: Path) -> dict[str, Any]:
    try:
        data = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as err:
        raise InputError(f"{path}: not a readable prior file ({err})") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise InputError(f"{path}: not an xted prior (expected format {FORMAT!r})")
    return data


def _prepare_out_dir(out_dir: Path, meta: dict[str, Any]) -> None:
    """Write ``prior.json``, or check that the one there describes the same run."""
    path = out_dir / "prior.json"
    if path.exists():
        old = _read_json(path)
        old_config = PriorConfig.from_dict(old.get("config", {})).to_dict()  # fields added since take their defaults
        if old_config != meta["config"]:
            differ = sorted(k for k in meta["config"] if old_config.get(k) != meta["config"][k])
            raise InputError(
                f"{out_dir} holds a prior trained with a different config (fields {differ}); "
                f"use another output folder or the same config to resume"
            )
        if old.get("data", {}).get("fingerprint") != meta["data"]["fingerprint"]:
            raise InputError(f"{out_dir} holds a prior trained on different target data; use another output folder")
        return
    out_dir.mkdir(parents=True, exist_ok=True)
    with atomic_path(path, ".json") as tmp:
        tmp.write_text(json.dumps(meta, indent=1))


def _read_log(path: Path, upto: int) -> list[dict[str, float]]:
    if not path.exists():
        return []
    with path.open() as f:
        return [row for row in ({k: float(v) for k, v in r.items()} for r in csv.DictReader(f)) if row["step"] <= upto]


def _write_log(path: Path, rows: list[dict[str, float]]) -> None:
    with atomic_path(path, ".csv") as tmp, tmp.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=["step", "loss", "seconds"])
        writer.writeheader()
        writer.writerows({**r, "step": int(r["step"])} for r in rows)


def train_prior(
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
            raise InputError(f"train_prior: {name} must be a positive integer, got {value}")
    if (target_dataset.observation_dim, target_dataset.action_dim) != (config.state_dim, config.action_dim):
        raise InputError(
            f"target data has (state_dim, action_dim) = ({target_dataset.observation_dim}, "
            f"{target_dataset.action_dim}), the config ({config.state_dim}, {config.action_dim})"
        )
    normalizer = Normalizer.fit(target_dataset)
    sampler, info = _window_sampler(target_dataset, normalizer, config)
    meta = {
        "format": FORMAT,
        "config": config.to_dict(),
        "normalizer": normalizer.to_dict(),
        "return_range": info.pop("return_range"),
        "data": {"fingerprint": target_dataset.fingerprint(), "transitions": len(target_dataset),
                 "env": dataset_env(target_dataset.metadata), **info},
    }
    _prepare_out_dir(out_dir, meta)

    init_key = jax.random.key(config.seed)
    data_rng = np.random.default_rng(config.seed)
    seconds = 0.0
    manager = _checkpoint_manager(out_dir)
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
    rows = _read_log(log_path, start)
    _write_log(log_path, rows)

    step_fn = make_train_step(config)
    rng = jax.random.key(config.seed + 1)
    losses: list[jnp.ndarray] = []
    bar = tqdm(total=steps, initial=start, disable=not progress, unit="step", desc="prior")
    began = time.perf_counter() - seconds
    try:
        with log_path.open("a", newline="") as log_file:
            writer = csv.writer(log_file)
            for step in range(start + 1, steps + 1):
                state, metrics = step_fn(state, sampler.batch(data_rng, config.batch_size), rng)
                losses.append(metrics["loss"])
                bar.update(1)
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
    return out_dir


@dataclass(frozen=True, eq=False)
class Prior:
    """A trained prior ready for editing: config, target normaliser and EMA parameters."""

    config: PriorConfig
    normalizer: Normalizer
    params: Any
    return_range: tuple[float, float]
    step: int = 0
    path: str | None = None
    env: str | None = None  # the env of the target data, where it said

    @property
    def model(self) -> Denoiser:
        return Denoiser(self.config.denoiser)

    @property
    def schedule(self) -> Schedule:
        return cosine_schedule(self.config.num_timesteps)


EXPORTED_PARAMS = "params.msgpack"


def export_prior(prior_dir: str | Path, dest: str | Path, provenance: dict[str, Any] | None = None) -> Path:
    """Write an inference-only copy of a prior (``prior.json`` + EMA parameters): small enough to ship.

    ``provenance`` (for example the command that trained it) is recorded in the copy's ``prior.json``."""
    prior = load_prior(prior_dir)
    dest = Path(dest)
    meta = _read_json(Path(prior_dir) / "prior.json")
    if provenance:
        meta["provenance"] = provenance
    with atomic_path(dest) as tmp:
        tmp.mkdir()
        (tmp / "prior.json").write_text(json.dumps(meta, indent=1))
        payload = {"params": jax.device_get(prior.params), "step": prior.step}
        (tmp / EXPORTED_PARAMS).write_bytes(flax.serialization.msgpack_serialize(payload))
    return dest


def load_prior(out_dir: str | Path) -> Prior:
    """The EMA parameters (latest checkpoint, or an exported prior) with the config and normaliser."""
    out_dir = Path(out_dir)
    meta_path = out_dir / "prior.json"
    if not meta_path.exists():
        raise InputError(f"{out_dir}: no prior.json (not a prior folder)")
    meta = _read_json(meta_path)
    config = PriorConfig.from_dict(meta["config"])
    if (out_dir / EXPORTED_PARAMS).exists():
        payload = flax.serialization.msgpack_restore((out_dir / EXPORTED_PARAMS).read_bytes())
        params, step = payload["params"], int(payload["step"])
    else:
        params, step = _restore_ema(out_dir, config)
    return Prior(
        config=config,
        normalizer=Normalizer.from_dict(meta["normalizer"]),
        params=params,
        return_range=tuple(meta["return_range"]),
        step=step,
        path=str(out_dir.resolve()),
        env=meta.get("data", {}).get("env"),
    )


def _restore_ema(out_dir: Path, config: PriorConfig) -> tuple[Any, int]:
    manager = _checkpoint_manager(out_dir)
    step = manager.latest_step()
    if step is None:
        manager.close()
        raise InputError(f"{out_dir}: no checkpoint yet")
    abstract = jax.eval_shape(functools.partial(init_train_state, config), jax.random.key(0))
    restored = manager.restore(
        step, args=ocp.args.Composite(state=ocp.args.StandardRestore(abstract), sampler=ocp.args.JsonRestore())
    )
    manager.close()
    return restored.state.ema_params, int(step)
