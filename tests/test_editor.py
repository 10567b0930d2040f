"""Editing windows and datasets with a (random, untrained) tiny prior."""

from __future__ import annotations

import dataclasses
import functools

import jax
import numpy as np
import pytest
from conftest import build_dataset
from test_diffusion import TINY

from xted.data import Normalizer
from xted.diffusion import EditConfig, Prior, PriorConfig, edit_dataset, edit_windows
from xted.diffusion.denoiser import apply_inverse
from xted.diffusion.editor import _plan, _predict_noise
from xted.diffusion.objective import init_train_state
from xted.errors import InputError

H = TINY.horizon  # 4: windows overlap by one state, stride 3
LENGTHS = (9, 10, 2, 12)  # 10 states -> 3 windows; 11 -> 3 + 1 aligned to the end; too short; 13 -> 4
BATCH = 8  # windows per editor call, in every test: one compilation per edit plan


def random_prior(config: PriorConfig, seed: int = 0) -> Prior:
    """A prior with random parameters (no training, no init compilation)."""
    shapes = jax.eval_shape(functools.partial(init_train_state, config), jax.random.key(0)).params
    rng = np.random.default_rng(seed)
    params = jax.tree.map(lambda x: (0.3 * rng.normal(size=x.shape)).astype(x.dtype), shapes)
    data = build_dataset(lengths=LENGTHS, obs_dim=config.state_dim, act_dim=config.action_dim)
    return Prior(config, Normalizer.fit(data), params, return_range=(-5.0, 5.0))


@pytest.fixture(scope="module")
def prior() -> Prior:
    return random_prior(TINY)


@pytest.fixture(scope="module")
def source():
    return build_dataset(lengths=LENGTHS, obs_dim=3, act_dim=2, seed=1)


@pytest.fixture(scope="module")
def edited(prior, source):
    return edit_dataset(prior, source, EditConfig(guard=False, batch_size=BATCH, seed=0))


def _windows(b: int = BATCH, seed: int = 0):
    rng = np.random.default_rng(seed)
    return tuple(rng.normal(size=(b, H, d)).astype(np.float32) for d in (3, 2, 1))


def test_edit_windows_holds_the_first_transition(prior):
    s, a, r = _windows()
    out = edit_windows(prior, s, a, r, EditConfig(guard=False), jax.random.key(0))
    for x, y in zip((s, a, r), out):
        y = np.asarray(y)
        assert y.shape == x.shape and np.all(np.isfinite(y))
        np.testing.assert_array_equal(y[:, 0], x[:, 0])
        assert not np.allclose(y[:, 1:-1], x[:, 1:-1])


@pytest.mark.parametrize("architecture", ["xted", "inverse_dynamics"])
def test_hold_actions_keeps_every_action_and_edits_states_and_rewards(architecture):
    prior = random_prior(dataclasses.replace(TINY, architecture=architecture))
    s, a, r = _windows()
    out_s, out_a, out_r = (np.asarray(x) for x in edit_windows(prior, s, a, r, EditConfig(guard=False, hold_actions=True),
                                                             jax.random.key(0)))
    np.testing.assert_array_equal(out_a, a)
    assert not np.allclose(out_s[:, 1:], s[:, 1:])
    assert not np.allclose(out_r[:, 1:-1], r[:, 1:-1])
    free_s = np.asarray(edit_windows(prior, s, a, r, EditConfig(guard=False), jax.random.key(0))[0])
    if architecture == "inverse_dynamics":  # its chain reads states alone
        np.testing.assert_array_equal(out_s, free_s)
    else:  # the held actions condition the denoised states
        assert not np.allclose(out_s[:, 1:], free_s[:, 1:])


def test_reverse_chain_starts_at_k(prior):
    # K = 10, kappa = 0.5: noise to t = k - 1 = 4, then exactly k = 5 model calls t = 4 .. 0.
    assert _plan(prior, EditConfig(guard=False)).timesteps == (4, 3, 2, 1, 0)
    assert _plan(prior, EditConfig(guard=False, kappa=1.0)).timesteps == tuple(range(9, -1, -1))
    assert _plan(prior, EditConfig(guard=False, kappa=0.5, sampler="ddim", sampler_steps=3)).timesteps == (4, 2, 0)


def test_a_prior_trained_on_low_noise_levels_refuses_larger_kappas():
    low = random_prior(dataclasses.replace(TINY, train_kappa_max=0.5))
    assert _plan(low, EditConfig(guard=False, kappa=0.5)).timesteps == (4, 3, 2, 1, 0)
    with pytest.raises(InputError, match="train_kappa_max=0.5"):
        _plan(low, EditConfig(guard=False, kappa=0.6))


def test_kappa_zero_windows_identity(prior):
    s, a, r = _windows()
    out = edit_windows(prior, s, a, r, EditConfig(guard=False, kappa=0.0), jax.random.key(0))
    assert all(y is x for x, y in zip((s, a, r), out))


def test_kappa_zero_dataset_unchanged(prior, source):
    result, report = edit_dataset(prior, source, EditConfig(guard=False, kappa=0.0))
    for name in ("observations", "actions", "rewards", "terminals", "timeouts", "next_observations"):
        np.testing.assert_array_equal(getattr(result, name), getattr(source, name), err_msg=name)
    assert sorted(result.extras) == sorted(source.extras)
    assert report["windows"] == 0 and result.metadata["edit"]["noise_steps"] == 0


def test_edit_dataset_transitions(source, edited):
    result, report = edited
    assert len(result) == len(source)
    np.testing.assert_array_equal(result.terminals, source.terminals)
    np.testing.assert_array_equal(result.timeouts, source.timeouts)
    assert report["windows"] == 3 + 4 + 4 and report["transitions"] == 9 + 10 + 12
    assert report["passed_through_episodes"] == 1
    assert result.extras == {} and report["dropped_extras"] == sorted(source.extras)
    assert result.metadata["edit"]["config"]["kappa"] == 0.5 and result.metadata["env"] == "Toy-v0"

    starts = np.cumsum((0,) + LENGTHS)
    for (start, length) in zip(starts, LENGTHS):
        steps = np.arange(start, start + length)
        if length + 1 < H:  # passed through unedited
            for name in ("observations", "actions", "rewards", "next_observations"):
                np.testing.assert_array_equal(getattr(result, name)[steps], getattr(source, name)[steps])
            continue
        for name in ("observations", "actions", "rewards"):  # only the episode's first transition is held
            np.testing.assert_array_equal(getattr(result, name)[start], getattr(source, name)[start])
        later = steps[1:]
        assert not np.isclose(result.observations[later], source.observations[later]).all(axis=1).any()
        assert not np.isclose(result.actions[later], source.actions[later]).all(axis=1).any()


def test_edited_episodes_are_stitched(source, edited):
    """Every edited next state is the next edited state, across window boundaries too."""
    result, _ = edited
    for start, end in result.episode_bounds():
        np.testing.assert_array_equal(result.next_observations[start:end - 1], result.observations[start + 1:end])
    assert not np.allclose(result.next_observations[-1], source.next_observations[-1])  # the final state is edited


def test_without_the_held_first_transition_episodes_are_generated_and_still_stitched(prior, source):
    """hold_first=False at kappa 1 (the paper's Tgt (Gen)): each episode's first transition is made
    too, and every later window still starts where the one before ended."""
    result, _ = edit_dataset(prior, source, EditConfig(guard=False, kappa=1.0, hold_first=False, batch_size=BATCH, seed=0))
    held, _ = edit_dataset(prior, source, EditConfig(guard=False, kappa=1.0, batch_size=BATCH, seed=0))
    for start, end in result.episode_bounds():
        if end - start + 1 < H:
            continue
        for name in ("observations", "actions", "rewards"):
            assert not np.isclose(getattr(result, name)[start], getattr(source, name)[start]).all(), name
            np.testing.assert_array_equal(getattr(held, name)[start], getattr(source, name)[start])
        np.testing.assert_array_equal(result.next_observations[start:end - 1], result.observations[start + 1:end])
    windows = _windows()
    free = edit_windows(prior, *windows, EditConfig(guard=False, hold_first=False), jax.random.key(0))
    assert not np.isclose(np.asarray(free[0])[:, 0], windows[0][:, 0]).all()


def test_a_dynamics_projection_makes_every_edited_transition_the_models_and_keeps_the_stitching(prior, source, edited):
    """With ``dynamics`` at weight 1, each edited next state is the model's prediction for the edited (state,
    action); episodes stay one sequence at every weight, and the actions are still the prior's edit."""
    weights = np.random.default_rng(3).normal(size=(5, 3)) * 0.1

    def dynamics(observations, actions):
        return 0.9 * observations + np.concatenate([observations, actions], axis=1) @ weights

    projected, _ = edit_dataset(prior, source, EditConfig(guard=False, batch_size=BATCH, seed=0, dynamics_weight=1.0),
                                dynamics=dynamics)
    edited_rows = np.ones(len(source.observations), bool)
    edited_rows[[start for start, _ in projected.episode_bounds()]] = False  # each episode's first state is held
    short = [i for start, end in projected.episode_bounds() if end - start < H - 1 for i in range(start, end)]
    edited_rows[short] = False  # episodes too short to edit pass through
    predicted = dynamics(projected.observations, projected.actions)
    np.testing.assert_allclose(projected.next_observations[edited_rows], predicted[edited_rows], rtol=1e-4, atol=1e-4)
    for start, end in projected.episode_bounds():
        np.testing.assert_array_equal(projected.next_observations[start:end - 1], projected.observations[start + 1:end])
    assert not np.allclose(projected.actions[edited_rows], source.actions[edited_rows])
    assert projected.metadata["edit"]["dynamics_projection"] and not edited[0].metadata["edit"]["dynamics_projection"]
    unweighted, _ = edit_dataset(prior, source, EditConfig(guard=False, batch_size=BATCH, seed=0, dynamics_weight=0.0),
                                 dynamics=dynamics)
    np.testing.assert_allclose(unweighted.next_observations, edited[0].next_observations, atol=1e-5)
    halfway, _ = edit_dataset(prior, source, EditConfig(guard=False, batch_size=BATCH, seed=0, dynamics_weight=0.5),
                              dynamics=dynamics)
    for start, end in halfway.episode_bounds():
        np.testing.assert_array_equal(halfway.next_observations[start:end - 1], halfway.observations[start + 1:end])
    assert 0 < np.abs(halfway.next_observations - edited[0].next_observations).max() < np.abs(
        projected.next_observations - edited[0].next_observations).max()


def test_edits_of_a_walker2d_prior_stay_inside_its_observation_space():
    """Walker2d observes velocities within +-10: edited states beyond are clipped into it (and counted)."""
    config = dataclasses.replace(TINY, state_dim=17, action_dim=6)
    wide = build_dataset(lengths=LENGTHS, obs_dim=17, act_dim=6)
    wide = dataclasses.replace(wide, observations=30 * wide.observations, next_observations=30 * wide.next_observations)
    prior = dataclasses.replace(random_prior(config), normalizer=Normalizer.fit(wide))
    source = build_dataset(lengths=LENGTHS, obs_dim=17, act_dim=6, seed=1)
    unbounded, report = edit_dataset(prior, source, EditConfig(guard=False, batch_size=BATCH))
    assert report["clipped_to_observation_space"] == 0 and np.abs(unbounded.observations[:, 8:]).max() > 10
    bounded, report = edit_dataset(dataclasses.replace(prior, env="walker2d"), source, EditConfig(guard=False, batch_size=BATCH))
    assert report["clipped_to_observation_space"] > 0
    for states in (bounded.observations, bounded.next_observations):
        assert np.abs(states[:, 8:]).max() <= 10 and np.abs(states[:, :8]).max() > 10  # positions are not bounded
    np.testing.assert_array_equal(bounded.observations[:, 8:], np.clip(unbounded.observations[:, 8:], -10, 10))
    for start, end in bounded.episode_bounds():
        np.testing.assert_array_equal(bounded.next_observations[start:end - 1], bounded.observations[start + 1:end])


def test_edit_does_not_depend_on_how_windows_are_batched(prior, source, edited):
    one_at_a_time, _ = edit_dataset(prior, source, EditConfig(guard=False, batch_size=1, seed=0))
    for name in ("observations", "actions", "rewards", "next_observations"):
        np.testing.assert_allclose(getattr(one_at_a_time, name), getattr(edited[0], name), atol=1e-5, err_msg=name)


def test_edit_dataset_deterministic(prior, source, edited):
    again, _ = edit_dataset(prior, source, EditConfig(guard=False, batch_size=BATCH, seed=0))
    other, _ = edit_dataset(prior, source, EditConfig(guard=False, batch_size=BATCH, seed=1))
    for name in ("observations", "actions", "rewards", "next_observations"):
        np.testing.assert_array_equal(getattr(again, name), getattr(edited[0], name), err_msg=name)
    assert not np.allclose(other.observations, again.observations)


@pytest.mark.slow
def test_guidance_zero_is_the_unconditional_prediction(prior):
    """eps(w) = eps_u + w (eps_c - eps_u) is affine in w, so eps(0) = 2 eps(1/2) - eps(1)."""
    assert prior.config.return_condition and EditConfig(guard=False).guidance == 0.0
    s, a, r = _windows()
    x = {"state": s, "action": a, "reward": r}
    t, returns = np.full(BATCH, 3), np.full(BATCH, 0.9, np.float32)
    eps = {w: _predict_noise(prior.params, _plan(prior, EditConfig(guidance=w)), x, t, returns) for w in (0.0, 0.5, 1.0)}
    for stream in x:
        np.testing.assert_allclose(eps[0.0][stream], 2 * eps[0.5][stream] - eps[1.0][stream], rtol=1e-4, atol=1e-5)
        assert not np.allclose(eps[0.0][stream], eps[1.0][stream])


def test_ddim_with_guidance(prior):
    s, a, r = _windows()
    config = EditConfig(guard=False, sampler="ddim", sampler_steps=2, guidance=2.0, iterations=2)
    out = edit_windows(prior, s, a, r, config, jax.random.key(0))
    assert all(np.all(np.isfinite(np.asarray(y))) for y in out)
    np.testing.assert_array_equal(np.asarray(out[0])[:, 0], s[:, 0])
    again = edit_windows(prior, s, a, r, config, jax.random.key(0))
    np.testing.assert_array_equal(np.asarray(again[0]), np.asarray(out[0]))  # DDIM (eta = 0) is deterministic
    with pytest.raises(InputError, match="exceeds"):
        edit_windows(prior, s, a, r, dataclasses.replace(config, sampler_steps=6), jax.random.key(0))
    with pytest.raises(InputError, match="ddim sampler only"):
        EditConfig(guard=False, sampler_steps=3)


def test_reward_free_prior_carries_rewards(source):
    prior = random_prior(dataclasses.replace(TINY, use_reward=False, return_condition=False))
    result, _ = edit_dataset(prior, source, EditConfig(guard=False, batch_size=BATCH))
    np.testing.assert_array_equal(result.rewards, source.rewards)
    assert not np.allclose(result.observations, source.observations)


def test_inverse_dynamics_prior_fills_actions_and_rewards_from_edited_states():
    """Inv: states are denoised; every transition's action and reward inside the window comes from
    the inverse models applied to the edited states; held transitions stay bit-identical."""
    prior = random_prior(dataclasses.replace(TINY, architecture="inverse_dynamics"))
    s, a, r = _windows()
    out_s, out_a, out_r = (np.asarray(x) for x in edit_windows(prior, s, a, r, EditConfig(guard=False),
                                                             jax.random.key(0)))
    for x, y in zip((s, a, r), (out_s, out_a, out_r)):
        np.testing.assert_array_equal(y[:, 0], x[:, 0])
    for x, y in zip((a, r), (out_a, out_r)):  # the last action and reward are in no transition of the window
        np.testing.assert_array_equal(y[:, -1], x[:, -1])
    assert not np.allclose(out_s[:, 1:-1], s[:, 1:-1])
    predicted_a, predicted_r = apply_inverse(prior.config.denoiser, prior.params, out_s)
    np.testing.assert_allclose(out_a[:, 1:-1], np.asarray(predicted_a)[:, 1:], rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(out_r[:, 1:-1], np.asarray(predicted_r)[:, 1:], rtol=1e-5, atol=1e-6)


def test_a_source_of_only_short_episodes_is_refused(prior):
    short = build_dataset(lengths=(2, 1, 2), obs_dim=3, act_dim=2)
    with pytest.raises(InputError, match="every episode of the source is shorter than the prior's windows"):
        edit_dataset(prior, short, EditConfig(guard=False))


def test_dimension_mismatch(prior):
    wrong = build_dataset(lengths=LENGTHS, obs_dim=4, act_dim=2)
    with pytest.raises(InputError, match="4-d observations and 2-d actions; the prior.s training data has 3 and 2"):
        edit_dataset(prior, wrong, EditConfig(guard=False))

