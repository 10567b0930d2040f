"""Computing each kind of cell: an edit, an oracle relabelling, an S4RL copy of the target, SER
samples, and one group of learner seeds."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from xted.data import Dataset, load, split_heldout
from xted.data.augment import gaussian_copy
from xted.diffusion.transitions import TransitionModelConfig, sample_transitions, train_transition_model
from xted.diffusion.prior import load_prior
from xted.envs import parse_domain
from xted.envs.dynamics import predict_next_observations, recovered_velocities, replayed_rewards
from xted.envs.make import forward_velocity_index, observation_velocity_clip
from xted.pipelines.bench.grid import DataCell, LearnerCell, first_transitions
from xted.pipelines.edit import edit_source
from xted.rl.offline_train import train_offline


def edited(cell: DataCell, source: Dataset) -> Dataset:
    """The source edited with the cell's prior, as ``xted edit`` does (``--project-dynamics`` where
    the cell names a dynamics model; the guard's target model fitted to the row's target where the
    prior holds none)."""
    prior = load_prior(cell.prior)
    dynamics_target = None
    if cell.dynamics is not None:
        dynamics_target = first_transitions(load(cell.dynamics.target), cell.dynamics.transitions)
    guard_target = None
    if cell.edit.guard and prior.target_model is None:  # a prior from before the guard: fit its model here
        guard_target = load(f"{cell.env}-{cell.target}")
    elif cell.edit.guard and cell.edit.guard_disagreement > 0 and not prior.target_model.members:
        # A prior from before the ensemble: fitted as its training would have, to the episodes it trained on.
        guard_target = load(f"{cell.env}-{cell.target}")
        if cell.prior_cell is not None:
            guard_target, _ = split_heldout(guard_target, cell.prior_cell.heldout_episodes)
    data, _ = edit_source(prior, source, cell.edit, guard_target=guard_target, project_onto=dynamics_target,
                          dynamics_proxy=None if cell.dynamics is None else cell.dynamics.proxy)
    return data


def oracle(env: str, gap: str, source: Dataset) -> Dataset:
    """The source's (s, a) with the target simulator's next state and reward: perfect editing.

    ``source`` is a recording of the ``gap`` domain's simulator. Where its observation has a velocity
    at the clip (Walker2d-v5 clips to +-10: 37-54% of the shipped walker2d data), the state is
    recovered by replaying the source's episode in its own domain (:func:`recovered_velocities`);
    the metadata counts any left clipped. Next observations are clipped as the target env's are.
    Terminals and timeouts are carried from the source, as an edit carries them; extras describe
    the source's simulator and are dropped."""
    domain = parse_domain(env)
    recovered = recovered_velocities(parse_domain(env, gap), source)
    next_observations = predict_next_observations(domain, source.observations, source.actions, recovered.velocities)
    clip = observation_velocity_clip(domain)
    velocities = slice(forward_velocity_index(domain), None)
    next_observations[:, velocities] = np.clip(next_observations[:, velocities], -clip, clip)
    rewards = replayed_rewards(domain, source.observations, source.actions, recovered.velocities)
    return dataclasses.replace(
        source, next_observations=next_observations.astype(source.observations.dtype),
        rewards=rewards.astype(source.rewards.dtype), extras={},
        metadata={**source.metadata, "relabelled": f"next states and rewards of the {env} simulator (oracle)",
                  "states_at_velocity_clip": {"observations": recovered.at_clip,
                                              "left_clipped": recovered.unrecovered}})


def make_data(cell: DataCell, source: Dataset) -> Dataset:
    if cell.kind == "edit":
        return edited(cell, source)
    if cell.kind == "s4rl":
        return gaussian_copy(source, cell.inputs["state_std"], cell.inputs["seed"])
    if cell.kind == "ser":  # as many transitions as the target holds, from a model trained on it
        return sample_transitions(train_transition_model(source, TransitionModelConfig(**cell.inputs["model"])),
                                  len(source))
    return oracle(cell.env, cell.gap, source)


def train_group(cells: Sequence[LearnerCell], training: Sequence[Dataset], progress: bool) -> list[dict]:
    """Train the seeds of one group together (one vmapped ``train_offline``); one result per cell."""
    first = cells[0]
    run = first.inputs
    results = train_offline(first.config, training[0], list(training[1:]), parse_domain(first.env), run["steps"],
                            [cell.seed for cell in cells], eval_every=run["eval_every"],
                            eval_episodes=run["eval_episodes"], progress=progress)
    keep = ("seed", "final_score", "best_score", "evals", "updates_per_second")
    return [{name: result[name] for name in keep} for result in results]
