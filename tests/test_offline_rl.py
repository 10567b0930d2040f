"""Offline RL: losses fall, vmapped seeds equal single-seed runs, evaluation, DARA's reward sign."""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from xted.envs import make, normalized_score, parse_domain
from xted.rl.bc import BCConfig, init_bc
from xted.rl.dara import DARAConfig, corrected_rewards, source_reward_deltas
from xted.rl.evaluation import evaluate
from xted.rl.iql import IQLConfig
from xted.rl.offline_train import init_seeds, init_state, seed_policy, train_seeds, train_steps
from xted.rl.td3bc import TD3BCConfig

TINY = {
    "iql": IQLConfig(hidden=(32, 32), batch_size=64, actor_lr=1e-3, critic_lr=1e-3, value_lr=1e-3),
    "td3bc": TD3BCConfig(hidden=(32, 32), batch_size=64, actor_lr=1e-3, critic_lr=1e-3),
    "bc": BCConfig(hidden=(32, 32), batch_size=64, learning_rate=1e-3),
}
LOSSES = {"iql": ("value_loss", "critic_loss", "actor_loss"), "td3bc": ("critic_loss", "actor_loss"),
          "bc": ("bc_loss",)}


def synthetic(n: int = 512, seed: int = 0) -> dict[str, np.ndarray]:
    """2-d states, a deterministic behaviour policy and a linear reward; every step terminal."""
    rng = np.random.default_rng(seed)
    obs = rng.normal(size=(n, 2))
    actions = np.tanh(obs @ np.array([[0.8, -0.3], [0.2, 0.5]]))
    data = {"observations": obs, "actions": actions, "rewards": obs @ [1.0, -0.5] + actions @ [0.5, 1.0],
            "next_observations": obs + 0.1 * actions, "terminals": np.ones(n)}
    return {k: v.astype(np.float32) for k, v in data.items()}


@pytest.mark.parametrize("name", TINY)
def test_losses_fall(name):
    config = TINY[name]
    state = init_state(config, jax.random.PRNGKey(0), 2, 2, steps=200)
    _, _, infos = train_steps(config, state, jax.random.PRNGKey(1), synthetic(), 200)
    for key in LOSSES[name]:
        values = np.asarray(infos[key])
        values = values[~np.isnan(values)]  # TD3+BC's actor steps every second update
        assert values[-20:].mean() < values[:20].mean(), key


@pytest.mark.slow
def test_vmapped_seeds_match_single_seed_runs():
    config, data = TINY["td3bc"], synthetic()
    keys = jnp.stack([jax.random.PRNGKey(s) for s in (3, 4)])
    rewards = np.stack([data["rewards"], data["rewards"] + 1.0])
    states = init_seeds(config, keys, 2, 2, 10)
    for a, b in zip(jax.tree.leaves(init_state(config, keys[1], 2, 2, 10)), jax.tree.leaves(states)):
        np.testing.assert_allclose(a, np.asarray(b)[1], rtol=1e-6, atol=1e-7)
    batched, _, _ = train_seeds(config, states, keys, {**data, "rewards": rewards}, 10, s4rl_noise=0.01)
    for i in range(2):
        single = jax.tree.map(lambda x: np.asarray(x)[i], states)
        single, _, _ = train_steps(config, single, keys[i], {**data, "rewards": rewards[i]}, 10, s4rl_noise=0.01)
        for a, b in zip(jax.tree.leaves(single), jax.tree.leaves(batched)):
            np.testing.assert_allclose(a, np.asarray(b)[i], rtol=1e-4, atol=1e-5)


def test_td3bc_delayed_actor_step_stays_a_branch_under_vmap():
    """The actor step is scheduled on the unbatched update index, so vmapping seeds keeps it a
    ``cond``; scheduled on the per-seed state it would become a select computing both branches."""
    config, data = TINY["td3bc"], synthetic()
    keys = jnp.stack([jax.random.PRNGKey(s) for s in (3, 4)])
    states = init_seeds(config, keys, 2, 2, 10)
    data = {**data, "rewards": np.stack([data["rewards"]] * 2)}
    jaxpr = str(jax.make_jaxpr(lambda s, k: train_seeds(config, s, k, data, 4, start=1))(states, keys))
    assert " cond[" in jaxpr
    _, _, infos = train_seeds(config, states, keys, data, 4, start=1)
    actor_updated = ~np.isnan(np.asarray(infos["actor_loss"]))
    np.testing.assert_array_equal(actor_updated, [[False, True, False, True]] * 2)  # updates 1..4


def test_evaluation_of_a_zero_policy_matches_a_manual_rollout():
    domain, config = parse_domain("halfcheetah"), BCConfig(hidden=(8,))
    actor = init_bc(jax.random.PRNGKey(0), 17, 6, config, 0).actor
    actor = actor.replace(params=jax.tree.map(jnp.zeros_like, actor.params))  # tanh(0): zero actions
    result = evaluate(seed_policy(config, actor, np.ones(17), np.full(17, 2.0)), domain, episodes=1, seed=7)
    env = make(domain)
    env.reset(seed=7)
    total, done = 0.0, False
    while not done:
        _, reward, terminated, truncated, _ = env.step(np.zeros(6))
        total, done = total + reward, terminated or truncated
    assert result["return_mean"] == pytest.approx(total)
    assert result["normalized_score"] == pytest.approx(normalized_score("halfcheetah", total))


@pytest.mark.slow
def test_dara_penalises_transitions_the_target_dynamics_would_not_produce():
    rng = np.random.default_rng(0)

    def transitions(n: int, shift: float) -> dict[str, np.ndarray]:
        obs, actions = rng.normal(size=(n, 2)), rng.uniform(-1, 1, (n, 2))
        return {"observations": obs, "actions": actions, "next_observations": obs + actions + shift}

    target, shifted, alike = transitions(1000, 0.0), transitions(500, 1.0), transitions(500, 0.0)
    source = {k: np.concatenate([shifted[k], alike[k]]).astype(np.float32) for k in shifted}
    target = {k: v.astype(np.float32) for k, v in target.items()}
    config = DARAConfig(classifier_steps=600, classifier_hidden=(32, 32), classifier_lr=1e-3, classifier_batch=128)
    deltas, losses = source_reward_deltas(jax.random.PRNGKey(0)[None], target, source, config)
    assert losses[0, -50:].mean() < losses[0, :50].mean() - 0.1
    change = corrected_rewards(np.zeros(1000), deltas[0], config)
    assert change[:500].mean() < -0.2
    assert change[500:].mean() > -0.02


def test_action_range_is_the_env_s_or_else_the_data_s():
    from xted.errors import DataWarning
    from xted.rl.offline_train import action_range

    inside = np.array([[0.5, -1.0], [1.0, 0.2]])
    assert action_range(inside, None) is None
    assert action_range(inside, (-np.ones(2), np.ones(2))) is None
    wide = np.array([[4.0, 0.5], [0.2, -0.5]])
    with pytest.warns(DataWarning, match=r"dimension\(s\) \[0\] span beyond \[-1, 1\]"):
        low, high = action_range(wide, None)
    np.testing.assert_array_equal(low, [-1, -1])
    np.testing.assert_array_equal(high, [4, 1])
    with pytest.warns(DataWarning, match=r"50.0% of the training actions lie outside the env's action space"):
        assert action_range(wide, (-np.ones(2), np.ones(2))) is None


def test_a_policy_acts_in_its_data_s_action_range(make_dataset):
    """Own data whose actions span +-5 (no env to declare a range): BC learns them rescaled and the
    saved policy acts in the data's range instead of saturating at 1."""
    from xted.errors import DataWarning
    from xted.rl.offline_train import train_offline

    base = make_dataset(lengths=(60, 60), obs_dim=3, act_dim=2, seed=3)
    actions = np.stack([5 * np.tanh(base.observations[:, 0]), 0.5 * np.tanh(base.observations[:, 1])], axis=1)
    data = dataclasses.replace(base, actions=actions.astype(np.float32))
    with pytest.warns(DataWarning, match="acts in the data's range"):
        [result] = train_offline(BCConfig(hidden=(32, 32)), data, [], None, 1500, [0], eval_every=1500,
                                 progress=False)
    policy = result["policy"]
    assert policy.meta["action_high"][0] == pytest.approx(actions[:, 0].max())
    assert policy.meta["action_low"][1] == -1.0 and policy.meta["action_high"][1] == 1.0
    acted = policy.act(data.observations)
    assert np.abs(acted[:, 0]).max() > 2.5 and np.abs(acted).max() <= np.abs(actions).max() + 1e-5
    assert np.mean(np.abs(acted[:, 0] - actions[:, 0])) < 1.0
