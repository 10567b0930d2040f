"""The guarded edit: which windows it keeps, and that every edited transition it keeps is valid."""

from __future__ import annotations

import dataclasses

import flax.linen as nn
import jax
import numpy as np
import pytest
from conftest import build_dataset
from test_diffusion import TINY
from test_editor import BATCH, LENGTHS, random_prior

from xted.diffusion import EditConfig, edit_dataset
from xted.diffusion.guard import (ENSEMBLE_FILE, TARGET_MODEL_FILE, TargetModel, fit_target_model, judge_windows,
                                  required_gain, window_means)
from xted.envs.termination import termination
from xted.errors import InputError
from xted.nn import MLP, FittedMLP


def constant_model(delta: np.ndarray, action_range: float = 1.0, resolution: float = 0.0) -> TargetModel:
    """A target model predicting ``s' = s + delta`` whatever the action (zero output spread)."""
    d, a = len(delta), 2
    params = MLP((4,), d, activation=nn.silu).init(jax.random.key(0), np.zeros((1, d + a), np.float32))
    mlp = FittedMLP(hidden=(4,), params=params, input_mean=np.zeros(d + a, np.float32),
                    input_std=np.ones(d + a, np.float32), output_mean=np.asarray(delta, np.float32),
                    output_std=np.zeros(d, np.float32))
    return TargetModel(mlp, resolution, np.full(a, -action_range, np.float32), np.full(a, action_range, np.float32),
                       np.full(d, -1.0, np.float32), np.full(d, 1.0, np.float32))


@pytest.fixture(scope="module")
def prior():
    return random_prior(TINY)


def source_following(delta: np.ndarray, shift: float = 0.0, seed: int = 1):
    """Episodes whose every next state is ``s + delta + shift``, but each episode's final one
    ``s + delta`` (so that the source's states stay inside the prior's support)."""
    data = build_dataset(lengths=LENGTHS, obs_dim=3, act_dim=2, seed=seed)
    next_observations = data.observations + delta + shift
    last = data.terminals | data.timeouts
    next_observations[last] -= shift
    return dataclasses.replace(data, next_observations=next_observations)


def test_judge_windows_keeps_an_edit_only_inside_the_support_valid_and_with_a_gain_beyond_the_margin():
    source = np.array([1.0, 1.0, 1.0, 1.0, 1.0, 1.0])
    edited = np.array([0.2, 0.95, 0.2, 0.2, 0.2, 0.2])
    outside = np.array([False, False, True, False, True, True])
    invalid = np.array([False, False, False, True, False, False])
    verdict = judge_windows(source, edited, outside, invalid, needed=0.1, outside_action="keep")
    assert verdict.edit.tolist() == [True, False, False, False, False, False]
    assert not verdict.drop.any()
    assert verdict.counts == {"windows": 6, "edited": 1, "source_outside_support": 3, "dropped_outside_support": 0,
                              "source_invalid_edit": 1, "source_no_gain": 1}
    dropped = judge_windows(source, edited, outside, invalid, 0.1, "drop")
    assert dropped.drop.tolist() == outside.tolist() and dropped.counts["dropped_outside_support"] == 3
    anyway = judge_windows(source, edited, outside, invalid, 0.1, "edit")
    assert anyway.edit.tolist() == [True, False, True, False, True, True]
    wide = judge_windows(source, edited, outside, invalid, 0.9, "edit")  # a gain of 0.8 < 0.9
    assert not wide.edit.any() and wide.counts["source_no_gain"] == 5


def test_window_means():
    np.testing.assert_allclose(window_means(np.array([1.0, 3.0, 5.0]), np.array([0, 0, 2]), 3), [2.0, 0.0, 5.0])


def test_termination_rules():
    walker = np.zeros((4, 17))
    walker[:, 0] = [1.2, 0.5, 1.2, 2.5]
    walker[:, 1] = [0.0, 0.0, 1.5, 0.0]
    assert termination("walker2d")(walker).tolist() == [False, True, True, True]
    assert termination("Walker2d-v5") is termination("walker2d")
    assert not termination("halfcheetah")(np.full((3, 17), 50.0)).any()
    hopper = np.zeros((3, 11))
    hopper[:, 0] = [1.2, 0.5, 1.2]
    hopper[2, 5] = 150.0
    assert termination("hopper")(hopper).tolist() == [False, True, True]
    assert termination("my-robot") is None and termination(None) is None


def test_a_source_already_consistent_with_the_target_comes_back_unchanged(prior):
    delta = np.array([0.1, -0.2, 0.3])
    source = source_following(delta)
    result, report = edit_dataset(prior, source, EditConfig(batch_size=BATCH), target_model=constant_model(delta))
    for name in ("observations", "actions", "rewards", "next_observations", "terminals", "timeouts"):
        np.testing.assert_array_equal(getattr(result, name), getattr(source, name), err_msg=name)
    guard = report["guard"]
    assert guard["edited"] == 0 and guard["source_no_gain"] == guard["windows"] == 11
    assert report["transitions"] == 0 and "keep the source" in guard["verdict"]


def test_kept_edits_are_valid_transitions_and_the_rest_is_the_source(prior):
    """A far-off source: the edits gain, so they are kept where valid; the toy termination rule makes
    some invalid (those windows stay the source's); kept actions are clipped into the action space."""
    delta = np.zeros(3)
    source = source_following(delta, shift=50.0)
    def rule(next_observations):
        return next_observations[:, 0] > 0.5

    model = constant_model(delta, action_range=0.05)
    plain, _ = edit_dataset(prior, source, EditConfig(batch_size=BATCH, guard=False))
    result, report = edit_dataset(prior, source, EditConfig(batch_size=BATCH), target_model=model, termination=rule)
    guard = report["guard"]
    assert guard["edited"] > 0 and guard["source_invalid_edit"] > 0
    assert guard["edited"] + guard["source_invalid_edit"] + guard["source_no_gain"] == guard["windows"]
    assert guard["actions_clipped"] > 0 and guard["termination_rule"]
    changed = np.any(result.next_observations != source.next_observations, axis=1)
    assert changed.sum() == report["transitions"] > 0
    np.testing.assert_array_equal(rule(result.next_observations[changed]), result.terminals[changed])
    np.testing.assert_array_equal(result.next_observations[changed], plain.next_observations[changed])
    assert np.abs(result.actions[changed]).max() <= 0.05 < np.abs(plain.actions[changed]).max()
    for name in ("observations", "actions", "rewards", "next_observations"):
        np.testing.assert_array_equal(getattr(result, name)[~changed], getattr(source, name)[~changed], err_msg=name)


def test_windows_beyond_the_support_are_kept_dropped_or_edited_by_option(prior):
    delta = np.zeros(3)
    source = source_following(delta, shift=50.0)
    far = dataclasses.replace(source, observations=source.observations.copy())
    far.observations[3] += 1e4  # one state, in the first episode's second window, far beyond the target's spread
    model = constant_model(delta)
    edit = EditConfig(batch_size=BATCH)
    kept, report = edit_dataset(prior, far, edit, target_model=model)
    inside_edited = report["guard"]["edited"]
    assert report["guard"]["source_outside_support"] == 2  # the state is shared by the first two windows
    np.testing.assert_array_equal(kept.observations[:6], far.observations[:6])
    dropped, report = edit_dataset(prior, far, dataclasses.replace(edit, outside_support="drop"), target_model=model)
    assert report["guard"]["dropped_outside_support"] == 2 and len(dropped) == len(far) - 6
    assert dropped.num_episodes == far.num_episodes  # the cut episode keeps its tail as its own episode
    anyway, report = edit_dataset(prior, far, dataclasses.replace(edit, outside_support="edit"), target_model=model)
    judged = report["guard"]
    assert judged["source_outside_support"] == 0 and judged["edited"] > inside_edited
    assert judged["edited"] + judged["source_no_gain"] + judged["source_invalid_edit"] == judged["windows"]


def test_a_prior_without_a_target_model_asks_for_target_data(prior):
    source = source_following(np.full(3, 0.1))
    with pytest.raises(InputError, match="target data"):
        edit_dataset(prior, source, EditConfig(batch_size=BATCH))


def test_the_fitted_target_model_learns_the_targets_dynamics_and_round_trips(tmp_path):
    rng = np.random.default_rng(0)
    data = build_dataset(lengths=(40,) * 10, obs_dim=3, act_dim=2, seed=3)
    data = dataclasses.replace(data, next_observations=data.observations + 0.5 * np.tanh(data.actions[:, :1]))
    model = fit_target_model(data, seed=0)
    assert model.resolution < 0.05  # a smooth rule, learned
    noise = rng.normal(size=data.observations.shape)
    assert model.errors(data.observations, data.actions, data.next_observations + noise).mean() > 10 * model.resolution
    model.save(tmp_path)
    again = TargetModel.load(tmp_path)
    np.testing.assert_array_equal(again.predict(data.observations, data.actions),
                                  model.predict(data.observations, data.actions))
    assert again.resolution == model.resolution and TargetModel.load(tmp_path / "none") is None


def test_the_required_gain_adds_the_windows_disagreement_only_where_asked():
    assert required_gain(0.2, 1.5) == pytest.approx(0.3)
    np.testing.assert_allclose(required_gain(0.2, 1.0, 0.5, np.array([0.0, 1.0, 4.0])), [0.2, 0.7, 2.2])
    verdict = judge_windows(np.ones(3), np.full(3, 0.5), np.zeros(3, bool), np.zeros(3, bool),
                            required_gain(0.2, 1.0, 0.5, np.array([0.0, 1.0, 4.0])), "keep")
    assert verdict.edit.tolist() == [True, False, False] and verdict.counts["source_no_gain"] == 2


def test_the_ensemble_disagrees_off_the_target_data_and_leaves_the_models_own_file_as_it_was(tmp_path):
    data = build_dataset(lengths=(40,) * 10, obs_dim=3, act_dim=2, seed=3)
    data = dataclasses.replace(data, next_observations=data.observations + 0.5 * np.tanh(data.actions[:, :1]))
    alone, ensemble = fit_target_model(data, seed=0), fit_target_model(data, seed=0, members=2)
    assert len(ensemble.members) == 2 and ensemble.resolution == alone.resolution
    with pytest.raises(InputError, match="ensemble"):
        alone.disagreement(data.observations, data.actions)
    inside = ensemble.disagreement(data.observations, data.actions)
    outside = ensemble.disagreement(data.observations + 20.0, data.actions)
    assert inside.shape == (len(data),) and outside.mean() > 10 * inside.mean() > 0
    alone.save(tmp_path / "alone")
    ensemble.save(tmp_path / "ensemble")
    assert not (tmp_path / "alone" / ENSEMBLE_FILE).exists()
    assert (tmp_path / "alone" / TARGET_MODEL_FILE).read_bytes() == (tmp_path / "ensemble" / TARGET_MODEL_FILE).read_bytes()
    again = TargetModel.load(tmp_path / "ensemble")
    np.testing.assert_array_equal(again.disagreement(data.observations, data.actions), inside)


def test_the_disagreement_test_reverts_edits_the_ensemble_cannot_judge(prior):
    """A far-off source the model alone says every edit improves: a large enough weight on the
    ensemble's disagreement there keeps the source; weight 0 is the guard as before."""
    source = source_following(np.zeros(3), shift=50.0)
    target = build_dataset(lengths=LENGTHS, obs_dim=3, act_dim=2, seed=4)
    target = dataclasses.replace(target, next_observations=target.observations + 0.5 * np.tanh(target.actions[:, :1]))
    edit = EditConfig(batch_size=BATCH)
    with pytest.raises(InputError, match="ensemble"):
        edit_dataset(prior, source, dataclasses.replace(edit, guard_disagreement=1.0),
                     target_model=fit_target_model(target))
    model = fit_target_model(target, members=2)
    base, base_report = edit_dataset(prior, source, edit, target_model=model)
    before, _ = edit_dataset(prior, source, edit, target_model=dataclasses.replace(model, members=()))
    np.testing.assert_array_equal(base.next_observations, before.next_observations)
    assert base_report["guard"]["edited"] > 0 and base_report["guard"]["source_disagreement"] is None
    strict, report = edit_dataset(prior, source, dataclasses.replace(edit, guard_disagreement=1e6), target_model=model)
    assert report["guard"]["edited"] == 0 and report["guard"]["source_disagreement"] > 0
    np.testing.assert_array_equal(strict.next_observations, source.next_observations)


def test_the_diagnosis_chooses_a_kappa_where_edits_gain_and_none_where_the_source_is_already_right(prior):
    from xted.diffusion.diagnosis import diagnose_edit

    delta = np.full(3, 0.1)
    model = constant_model(delta)
    far = diagnose_edit(prior, source_following(delta, shift=50.0), EditConfig(batch_size=BATCH), kappas=(0.2, 0.5),
                        transitions=15, target_model=model)
    assert far["episodes"] < 4 and far["transitions"] >= 15 and [row["kappa"] for row in far["kappas"]] == [0.2, 0.5]
    assert far["kappa"] in (0.2, 0.5) and far["kappas"][0]["score"] < far["kappas"][0]["source_score"]
    right = diagnose_edit(prior, source_following(delta), EditConfig(batch_size=BATCH), kappas=(0.2, 0.5),
                          target_model=model)
    assert right["kappa"] is None and "keep the source" in right["verdict"]


def test_transition_validity_counts_what_breaks_the_targets_rules():
    from xted.analysis import transition_validity

    data = build_dataset(lengths=(5, 5), obs_dim=17, act_dim=6, seed=2)
    next_observations = data.next_observations.copy()
    next_observations[:, 0], next_observations[:, 1] = 1.2, 0.0  # a healthy walker everywhere...
    next_observations[2, 0] = 0.3  # ...but one unflagged fall
    actions = data.actions.copy()
    actions[3, 1] = 1.5
    data = dataclasses.replace(data, next_observations=next_observations, actions=actions)
    report = transition_validity(data, "walker2d")
    assert report["unflagged_terminal"] == 1 and report["flagged_but_healthy"] == int(data.terminals.sum())
    assert report["actions_outside"] == 1 and report["states_outside_target_range"] is None
    unknown = transition_validity(data, None, target=data.select_episodes([0]))
    assert unknown["unflagged_terminal"] is None and unknown["actions_outside"] >= 0
    assert unknown["states_outside_target_range"] > 0


@pytest.mark.parametrize("env", ["halfcheetah", "walker2d"])
def test_the_shipped_priors_hold_the_guards_ensemble(env):
    from xted.data import load, shipped
    from xted.diffusion.guard import ENSEMBLE_MEMBERS

    model = TargetModel.load(shipped.prior_dir(f"{env}-medium-replay-cpu"))
    target = load(f"{env}-medium-replay")
    assert len(model.members) == ENSEMBLE_MEMBERS
    on_target = model.disagreement(target.observations[:500], target.actions[:500]).mean()
    assert 0 < on_target < model.resolution
