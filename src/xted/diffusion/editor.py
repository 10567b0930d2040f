"""Editing source trajectories with a trained prior (paper §4.2).

A window is noised to step ``k = round(kappa * K)`` and denoised by the reverse chain from exactly
that step (``k`` DDPM model calls, or ``sampler_steps`` DDIM calls), with the first transition
re-imposed clean after every step. The whole chain is one jitted
``fori_loop``. Each window's noise comes from ``fold_in(key, window number)``, so the random draws
do not depend on how windows are grouped into batches.

Dataset tiling: an episode of ``L`` steps becomes the state sequence ``s_0 .. s_L`` (``s_L`` the
final next observation; the last action and reward repeated at position ``L``), cut into windows
of ``H`` with stride ``H - 1`` (neighbours share one state) and a last window aligned to the end
(:func:`xted.data.windows.tile_episodes`). The edit is stitched: an episode's windows are edited in
order, and each window after the first holds, in place of the source's, the state, action and
reward its predecessor edited at the shared position, so an edited episode is one sequence
(``next_observations[t] == observations[t + 1]``) and only its very first transition is the
source's. Windows of different episodes are edited side by side (``batch_size`` slots, each
working through whole episodes). Edited values are mapped back as
``raw + denormalize(edited) - denormalize(normalized raw)``, which leaves every value the editor
did not change (held steps, ``kappa = 0``) bit-identical to the source.
"""

from __future__ import annotations

import dataclasses
import functools
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from tqdm.auto import tqdm

from xted.data import Dataset, check_dimensions
from xted.data.windows import EpisodeTiling, tile_episodes, warn_if_one_long_episode
from xted.diffusion.config import DenoiserConfig, EditConfig
from xted.diffusion.denoiser import Denoiser, apply_inverse
from xted.diffusion.guard import GuardVerdict, TargetModel, judge_windows, required_gain, verdict_line, window_means
from xted.diffusion.prior import Prior
from xted.diffusion.schedule import (
    Schedule,
    ddim_step,
    ddim_timesteps,
    ddpm_step,
    q_sample,
)
from xted.envs.make import action_bounds, observation_bounds
from xted.envs.step_function import predicted_next_observations
from xted.envs.termination import Termination
from xted.envs.termination import termination as termination_rule
from xted.errors import InputError


@dataclass(frozen=True)
class _Plan:
    """Everything static about one edit (hashable: the jit cache key)."""

    denoiser: DenoiserConfig
    timesteps: tuple[int, ...]
    sampler: str
    iterations: int
    hold_actions: bool
    guidance: float | None
    clip: float | None
    temperature: float
    eta: float


def _plan(prior: Prior, config: EditConfig) -> _Plan:
    k = config.noise_steps(prior.config.num_timesteps)
    if k > prior.config.trained_noise_steps:
        raise InputError(f"EditConfig: kappa={config.kappa} noises to step {k}, but this prior was trained on noise "
                         f"steps up to {prior.config.trained_noise_steps} (train_kappa_max="
                         f"{prior.config.train_kappa_max}); use kappa <= {prior.config.train_kappa_max}")
    if config.sampler == "ddim":
        steps = config.sampler_steps or k
        if steps > k:
            raise InputError(f"EditConfig: sampler_steps={steps} exceeds the {k} noise steps of kappa={config.kappa}")
        timesteps = tuple(int(t) for t in ddim_timesteps(k, steps))
    else:
        timesteps = tuple(range(k - 1, -1, -1))
    return _Plan(
        denoiser=prior.config.denoiser,
        timesteps=timesteps,
        sampler=config.sampler,
        iterations=config.iterations,
        hold_actions=config.hold_actions,
        guidance=float(config.guidance) if prior.config.return_condition else None,
        clip=config.clip_denoised,
        temperature=float(config.temperature),
        eta=float(config.eta),
    )


def _predict_noise(params: Any, plan: _Plan, x: dict[str, jnp.ndarray], t: jnp.ndarray, returns: jnp.ndarray) -> dict:
    model = Denoiser(plan.denoiser)
    streams = plan.denoiser.diffused_streams

    def apply(inputs: dict[str, jnp.ndarray], tt: jnp.ndarray, r: jnp.ndarray | None, drop: jnp.ndarray | None):
        eps = model.apply(params, inputs["state"], inputs["action"], inputs.get("reward"), tt, r, drop)
        return dict(zip(streams, eps))

    if plan.guidance is None:
        return apply(x, t, None, None)
    if plan.guidance == 1.0:
        return apply(x, t, returns, None)
    b = t.shape[0]
    if plan.guidance == 0.0:
        return apply(x, t, returns, jnp.ones(b, bool))
    both = apply(
        {s: jnp.concatenate([v, v]) for s, v in x.items()},
        jnp.concatenate([t, t]),
        jnp.concatenate([returns, returns]),
        jnp.concatenate([jnp.zeros(b, bool), jnp.ones(b, bool)]),
    )
    return {s: e[b:] + plan.guidance * (e[:b] - e[b:]) for s, e in both.items()}  # xTED Eq. 13 (appendix)


def _noise(keys: jnp.ndarray, path: tuple[Any, ...], like: jnp.ndarray) -> jnp.ndarray:
    """Standard normals shaped like ``like`` ``[B, ...]``; window ``b`` folds ``path`` into ``keys[b]``."""

    def one(key: jax.Array) -> jnp.ndarray:
        for p in path:
            key = jax.random.fold_in(key, p)
        return jax.random.normal(key, like.shape[1:], like.dtype)

    return jax.vmap(one)(keys)


@functools.partial(jax.jit, static_argnames=("plan",))
def _edit(
    params: Any, schedule: Schedule, x0: dict[str, jnp.ndarray], keys: jnp.ndarray, returns: jnp.ndarray,
    held_first: jnp.ndarray, plan: _Plan
) -> dict[str, jnp.ndarray]:
    """Noise ``x0`` to ``timesteps[0]`` and run the reverse chain over ``timesteps``, ``iterations`` times,
    holding the first transition of the windows where ``held_first`` ``[B]`` is true.

    Inv runs the chain over states alone, then its inverse models give the actions and rewards of
    every transition but the held ones."""
    streams = plan.denoiser.diffused_streams
    b = keys.shape[0]
    ts = jnp.asarray(plan.timesteps, jnp.int32)
    ts_prev = jnp.concatenate([ts[1:], jnp.array([-1], jnp.int32)])

    def hold(x: dict[str, jnp.ndarray]) -> dict[str, jnp.ndarray]:
        out = {s: x[s].at[:, 0].set(jnp.where(held_first[:, None], x0[s][:, 0], x[s][:, 0])) for s in streams}
        if plan.hold_actions and "action" in out:
            out["action"] = x0["action"]
        return out

    def iteration(it: jnp.ndarray, x: dict[str, jnp.ndarray]) -> dict[str, jnp.ndarray]:
        t_start = jnp.full((b,), ts[0])
        x = hold({s: q_sample(schedule, x[s], t_start, _noise(keys, (it, 0, j), x[s])) for j, s in enumerate(streams)})

        def step(i: jnp.ndarray, x: dict[str, jnp.ndarray]) -> dict[str, jnp.ndarray]:
            t = jnp.full((b,), ts[i])
            eps = _predict_noise(params, plan, {**x0, **x}, t, returns)  # Inv reads no action or reward
            if plan.sampler == "ddim":
                t_prev = jnp.full((b,), ts_prev[i])
                return hold({
                    s: ddim_step(schedule, x[s], t, t_prev, eps[s], plan.clip, plan.eta,
                                 _noise(keys, (it, i + 1, j), x[s]), plan.temperature)
                    for j, s in enumerate(streams)
                })
            return hold({
                s: ddpm_step(schedule, x[s], t, eps[s], _noise(keys, (it, i + 1, j), x[s]), plan.clip, plan.temperature)
                for j, s in enumerate(streams)
            })

        return jax.lax.fori_loop(0, len(plan.timesteps), step, x)

    edited = jax.lax.fori_loop(0, plan.iterations, iteration, {s: x0[s] for s in streams})
    if plan.denoiser.architecture != "inverse_dynamics":
        return edited
    out = dict(x0, state=edited["state"])
    for s, predicted in zip(("action", "reward"), apply_inverse(plan.denoiser, params, edited["state"])):
        held = s == "action" and plan.hold_actions
        if predicted is not None and not held:  # the window's last action and reward belong to no transition in it
            out[s] = x0[s].at[:, 1:-1].set(predicted[:, 1:])
    return out


def _editor(prior: Prior, config: EditConfig
            ) -> Callable[[dict[str, np.ndarray], jnp.ndarray, np.ndarray | None], dict[str, jnp.ndarray]]:
    """``(normalised windows per stream, per-window keys, windows continuing an edited one or None)
    -> edited windows`` for this prior and config: a window holds its first transition where it
    continues one or ``config.hold_first``."""
    plan = _plan(prior, config)
    schedule = prior.schedule

    def run(x: dict[str, np.ndarray], keys: jnp.ndarray, continued: np.ndarray | None = None) -> dict[str, jnp.ndarray]:
        returns = jnp.full((keys.shape[0],), config.target_return, jnp.float32)
        x = {s: jnp.asarray(v, jnp.float32) for s, v in x.items()}
        held = np.full(keys.shape[0], config.hold_first) | (False if continued is None else continued)
        return _edit(prior.params, schedule, x, keys, returns, jnp.asarray(held), plan)

    return run


def _check_windows(prior: Prior, arrays: dict[str, np.ndarray]) -> None:
    cfg = prior.config
    for stream, array in arrays.items():
        expected = (cfg.horizon, cfg.denoiser.element_dim(stream))
        if np.ndim(array) != 3 or tuple(np.shape(array)[1:]) != expected:
            shape = f"[B, {expected[0]}, {expected[1]}]"
            raise InputError(f"{stream} windows must have shape {shape}, got {np.shape(array)}")


def edit_windows(
    prior: Prior,
    states: np.ndarray,
    actions: np.ndarray,
    rewards: np.ndarray | None,
    config: EditConfig,
    rng: jax.Array,
) -> tuple[Any, Any, Any]:
    """Edit normalised windows ``[B, H, ds]``, ``[B, H, da]``, ``[B, H, 1]``; returns JAX arrays.

    For a reward-free prior ``rewards`` may be None and is returned as given. ``kappa = 0``
    returns the inputs themselves.
    """
    x = {"state": states, "action": actions}
    if prior.config.use_reward:
        if rewards is None:
            raise InputError("edit_windows: this prior models rewards; rewards must be given")
        x["reward"] = rewards
    _check_windows(prior, x)
    if config.noise_steps(prior.config.num_timesteps) == 0:
        return states, actions, rewards
    out = _editor(prior, config)(x, jax.random.split(rng, np.shape(states)[0]))
    return out["state"], out["action"], out["reward"] if prior.config.use_reward else rewards


def _rollout(prior: Prior, dynamics: Dynamics, states: np.ndarray, actions: np.ndarray, weight: float) -> np.ndarray:
    """Normalised ``[B, H, D]`` states: the first as given, each next ``weight * dynamics(state, action)
    + (1 - weight) * `` the given one, from the state before it so made."""
    denormalize = functools.partial(prior.normalizer.denormalize, "observations")
    raw_actions = prior.normalizer.denormalize("actions", actions)
    current, out = denormalize(states[:, 0]), states.copy()  # the held state stays bit-identical
    for t in range(states.shape[1] - 1):
        predicted = predicted_next_observations(dynamics, current, raw_actions[:, t])
        current = weight * predicted + (1.0 - weight) * denormalize(states[:, t + 1])
        out[:, t + 1] = prior.normalizer.normalize("observations", current)
    return out


# ------------------------------------------------------------------------------- datasets
Dynamics = Callable[[np.ndarray, np.ndarray], np.ndarray]  # (observations, actions) -> next observations, raw units


def edit_dataset(
    prior: Prior, source: Dataset, config: EditConfig, progress: bool = False, dynamics: Dynamics | None = None,
    target_model: TargetModel | None = None, termination: Termination | None = None,
) -> tuple[Dataset, dict[str, Any]]:
    """Edit every episode of ``source`` with ``prior``; returns the edited dataset and a report.

    Terminals and timeouts are carried from the source, and rewards too for a reward-free prior.
    Episodes shorter than ``H - 1`` steps are passed through unedited. Extras (e.g. simulator
    states) describe the unedited source and are dropped, unless ``kappa = 0`` (source returned as is).
    The source must store next observations (the final state of each episode is edited too).
    Report: ``windows`` edited, ``transitions`` taken from edited windows,
    ``passed_through_episodes``, ``clipped_to_observation_space`` (edited next states outside what
    the prior's target env can observe, clipped into it: walker2d's velocities), ``dropped_extras``
    and wall ``seconds`` (compilation included).
    ``progress`` shows a bar over the stitched steps.

    ``dynamics`` (opt-in, beyond the paper): a model of the target's one-step dynamics, such as
    ``xted.analysis.fit_proxy(target).predict``. Each denoised window's states after its held first
    one are replaced, in order, by ``w * dynamics(state before, action) + (1 - w) * denoised state``
    (``w = config.dynamics_weight``; 1: the model's rollout under the edited actions, every edited
    transition one the model predicts); the episode stays one sequence, and the next window starts
    from the last state so made, its actions denoised from there.
    """
    began = time.perf_counter()
    cfg = prior.config
    k = config.noise_steps(cfg.num_timesteps)
    guard_model = _checked_edit(prior, source, config, k, target_model or prior.target_model)
    metadata = {
        **source.metadata,
        "edit": {"config": dataclasses.asdict(config), "prior": prior.path, "prior_step": prior.step, "noise_steps": k,
                 "dynamics_projection": dynamics is not None},
    }
    bounds = source.episode_bounds()
    if k == 0:
        report = {"windows": 0, "transitions": 0, "passed_through_episodes": len(bounds), "dropped_extras": [],
                  "seconds": time.perf_counter() - began}
        return source.with_metadata(**metadata), report

    warn_if_one_long_episode(source, "the source data")
    tiling = tile_episodes(bounds, cfg.horizon)
    if not len(tiling.window_rows):
        raise InputError(f"nothing to edit: every episode of the source is shorter than the prior's windows "
                         f"({cfg.horizon - 1} steps; the longest has {int(np.diff(bounds).max())})")
    next_observations = source.require_next_observations()
    steps, is_next = tiling.sequence_steps, tiling.sequence_is_next
    raw = {
        "state": np.where(is_next[:, None], next_observations[steps], source.observations[steps]),
        "action": source.actions[steps],
        "reward": source.rewards[steps][:, None],
    }
    norm = {s: prior.normalizer.normalize(_FIELDS[s], raw[s]).astype(np.float32) for s in cfg.denoiser.streams}
    edited_windows = _stitched_edit(prior, config, tiling, norm, dynamics, progress)
    edited_t = _edited_transitions(prior, tiling, raw, norm, edited_windows)
    clipped = _clip_to_observation_space(prior, edited_t)
    t = tiling.transition_steps
    keep, drop = np.ones(len(t), bool), np.zeros(len(t), bool)
    report: dict[str, Any] = {}
    if config.guard:
        report["guard"], edited_t, verdict = _guard(prior, source, next_observations, tiling, norm["state"], edited_t,
                                                    config, guard_model, termination)
        keep, drop = verdict.edit[tiling.transition_window], verdict.drop[tiling.transition_window]

    columns = {"observations": source.observations, "next_observations": next_observations,
               "actions": source.actions, "rewards": source.rewards}
    out = {name: array.copy() for name, array in columns.items()}
    for name, values in edited_t.items():
        out[name][t[keep]] = values[keep]
    result = Dataset(**out, terminals=source.terminals, timeouts=source.timeouts, metadata=metadata)
    if drop.any():
        result = _without_rows(result, t[drop])
    report = {
        "windows": int(len(tiling.window_rows)),
        "transitions": int(keep.sum()),
        "passed_through_episodes": int(tiling.passed_through.sum()),
        "clipped_to_observation_space": clipped,
        "dropped_extras": sorted(source.extras),
        **report,
        "seconds": time.perf_counter() - began,
    }
    return result, report


_FIELDS = {"state": "observations", "action": "actions", "reward": "rewards"}  # a stream's dataset field


def _checked_edit(prior: Prior, source: Dataset, config: EditConfig, noise_steps: int,
                  guard_model: TargetModel | None) -> TargetModel | None:
    """InputError where ``source`` cannot be edited with ``prior`` under ``config``; the guard's model."""
    cfg = prior.config
    check_dimensions(source, (cfg.state_dim, cfg.action_dim), "the source data", "the prior's training data")
    if cfg.use_reward:
        source.require_rewards("editing with this prior's reward stream",
                               "edit it with a reward-free prior (trained on reward-free target data)")
    if config.guard and noise_steps > 0 and guard_model is None:
        raise InputError(f"the guarded edit needs a model of the target's dynamics, and the prior {prior.path} holds "
                         "none (trained before xted fitted one): give the target data (--target, "
                         "Prior.edit(target=...)), or edit without the guard (--no-guard, guard=False: the paper's "
                         "plain edit)")
    if config.guard and noise_steps > 0 and config.guard_disagreement > 0 and not guard_model.members:
        raise InputError(f"guard_disagreement {config.guard_disagreement} needs the target model's ensemble, and the "
                         f"prior {prior.path} holds none: give the target data (--target, "
                         "Prior.edit(target=...)) to fit it, or leave guard_disagreement at 0")
    return guard_model


def _stitched_edit(prior: Prior, config: EditConfig, tiling: EpisodeTiling, norm: dict[str, np.ndarray],
                   dynamics: Dynamics | None, progress: bool) -> dict[str, np.ndarray]:
    """Every window edited, ``[W, H, d]`` per stream (normalised): in rounds of windows, each starting
    from the edited state its previous window of the episode ends on (the stitching), each projected
    onto ``dynamics`` where given."""
    cfg, streams = prior.config, prior.config.denoiser.streams
    n_windows = len(tiling.window_rows)
    edited = {s: np.empty((n_windows, cfg.horizon, norm[s].shape[-1]), np.float32) for s in streams}
    edit = _editor(prior, config)
    seed_key = jax.random.key(config.seed)
    table = tiling.schedule(min(config.batch_size, max(int(tiling.window_episode.max(initial=0)) + 1, 1)))
    for ids in tqdm(table, disable=not progress, unit="round", desc="edit (rounds of windows)"):
        live = ids >= 0
        x = {s: norm[s][tiling.window_rows[np.where(live, ids, 0)]] for s in streams}
        previous, carried = tiling.window_previous[ids], tiling.window_carry_position[ids]
        stitched = live & (previous >= 0)
        for s in streams:
            x[s][stitched, 0] = edited[s][previous[stitched], carried[stitched]]
        keys = jax.vmap(jax.random.fold_in, (None, 0))(seed_key, jnp.asarray(np.where(live, ids, n_windows), jnp.uint32))
        out = edit(x, keys, stitched)
        if dynamics is not None:
            out = {**out, "state": _rollout(prior, dynamics, np.asarray(out["state"]), np.asarray(out["action"]),
                                            config.dynamics_weight)}
        for s in streams:
            edited[s][ids[live]] = np.asarray(out[s])[live]
    return edited


def _edited_transitions(prior: Prior, tiling: EpisodeTiling, raw: dict[str, np.ndarray], norm: dict[str, np.ndarray],
                        edited: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The edited windows as one value per source transition (raw units): the source's value plus what
    the edit changed, so a stream the edit left alone comes back bit-identical."""
    def transitions(stream: str, shift: int) -> np.ndarray:
        window, position = tiling.transition_window, tiling.transition_position + shift
        rows = tiling.window_rows[window, position]
        values = edited[stream][window, position]
        denormalize = functools.partial(prior.normalizer.denormalize, _FIELDS[stream])
        return (raw[stream][rows] + (denormalize(values) - denormalize(norm[stream][rows]))).astype(np.float32)

    edited_t = {"observations": transitions("state", 0), "next_observations": transitions("state", 1),
                "actions": transitions("action", 0)}
    if prior.config.use_reward:
        edited_t["rewards"] = transitions("reward", 0)[:, 0]
    return edited_t


def _clip_to_observation_space(prior: Prior, edited_t: dict[str, np.ndarray]) -> int:
    """Clip edited states into what the prior's target env can observe (walker2d's velocities within
    +-10), in place; returns how many edited next states lay outside it."""
    bounds = observation_bounds(prior.env)
    if bounds is None or len(bounds[0]) != prior.config.state_dim:
        return 0
    clipped = int(np.any((edited_t["next_observations"] < bounds[0]) | (edited_t["next_observations"] > bounds[1]),
                         axis=1).sum())
    for name in ("observations", "next_observations"):
        edited_t[name] = np.clip(edited_t[name], *bounds).astype(np.float32)
    return clipped


def _guard(prior: Prior, source: Dataset, next_observations: np.ndarray, tiling: EpisodeTiling,
           source_states: np.ndarray, edited: dict[str, np.ndarray], config: EditConfig, model: TargetModel,
           termination: Termination | None) -> tuple[dict[str, Any], dict[str, np.ndarray], GuardVerdict]:
    """Judge every window (:func:`xted.diffusion.guard.judge_windows`) and clip edited actions into the
    action space; returns the guard's report, the edited transitions and the verdict."""
    t, windows, n_windows = tiling.transition_steps, tiling.transition_window, len(tiling.window_rows)
    source_error = model.errors(source.observations[t], source.actions[t], next_observations[t])
    edited_error = model.errors(edited["observations"], edited["actions"], edited["next_observations"])
    farthest = np.abs(source_states[tiling.window_rows]).max(axis=(1, 2))  # target standard deviations
    inside = (farthest <= config.support_z)[windows]
    rule = termination or termination_rule(prior.env)
    wrong_flag = np.zeros(len(t), bool) if rule is None else rule(edited["next_observations"]) != source.terminals[t]
    disagreement = None
    if config.guard_disagreement > 0:
        disagreement = window_means(model.disagreement(source.observations[t], source.actions[t]), windows, n_windows)
    verdict = judge_windows(window_means(source_error, windows, n_windows), window_means(edited_error, windows, n_windows),
                            farthest > config.support_z, np.bincount(windows, wrong_flag, n_windows) > 0,
                            required_gain(model.resolution, config.guard_margin, config.guard_disagreement, disagreement),
                            config.outside_support)
    kept = verdict.edit[windows]
    guarded_error = np.where(kept, edited_error, source_error)
    low, high = action_bounds(prior.env) or (model.action_low, model.action_high)
    outside_actions = np.any((edited["actions"] < low) | (edited["actions"] > high), axis=1) & kept
    edited = {**edited, "actions": np.clip(edited["actions"], low, high).astype(np.float32)}
    report = {
        **verdict.counts,
        "actions_clipped": int(outside_actions.sum()),
        "termination_rule": rule is not None,
        "edited_states_outside_target_range": int((model.outside_range(edited["next_observations"]) & kept).sum()),
        "source_error": float(source_error.mean()),
        "edited_error": float(edited_error.mean()),
        "guarded_error": float(guarded_error.mean()),
        "source_error_inside_support": float(source_error[inside].mean()) if inside.any() else None,
        "guarded_error_inside_support": float(guarded_error[inside].mean()) if inside.any() else None,
        "resolution": model.resolution,
        "source_disagreement": None if disagreement is None else float(disagreement.mean()),
    }
    report["verdict"] = verdict_line(verdict.counts, report["source_error"], model.resolution)
    return report, edited, verdict


def _without_rows(data: Dataset, rows: np.ndarray) -> Dataset:
    """``data`` less ``rows``; a kept transition followed by a removed one ends its episode (a timeout)."""
    keep = np.ones(len(data), bool)
    keep[rows] = False
    before_gap = keep & ~np.append(keep[1:], True)
    timeouts = data.timeouts | (before_gap & ~data.terminals)
    return Dataset(observations=data.observations[keep], actions=data.actions[keep], rewards=data.rewards[keep],
                   terminals=data.terminals[keep], timeouts=timeouts[keep],
                   next_observations=data.next_observations[keep], metadata=data.metadata)
