import dataclasses

import numpy as np
import pytest

from xted.analysis import ProxyConfig, content_similarity, fit_proxy, fit_reward_proxy, relabel_rewards
from xted.data import Dataset
from xted.errors import InputError


def linear_system(episodes: int, length: int, seed: int) -> Dataset:
    """s' = s + 0.1 (A s + B a), reward (s'_0 - s_0) / 0.1 - 0.1 |a|^2 (locomotion-like): a smooth
    system an MLP can learn from a few hundred steps."""
    rng = np.random.default_rng(seed)
    a_matrix = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.5], [0.2, 0.0, -0.3]])
    b_matrix = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    observations, actions, nexts = [], [], []
    for _ in range(episodes):
        s = rng.normal(size=3)
        for _ in range(length):
            a = rng.uniform(-1, 1, size=2)
            s_next = s + 0.1 * (a_matrix @ s + b_matrix @ a)
            observations.append(s), actions.append(a), nexts.append(s_next)
            s = s_next
    n = episodes * length
    timeouts = np.zeros(n, bool)
    timeouts[length - 1 :: length] = True
    observations, actions, nexts = (np.array(x, np.float32) for x in (observations, actions, nexts))
    rewards = (nexts[:, 0] - observations[:, 0]) / 0.1 - 0.1 * np.sum(actions**2, axis=1)
    return Dataset(observations, actions, rewards, np.zeros(n, bool), timeouts, nexts)


def naive_error(data: Dataset) -> float:
    return float(np.abs(data.next_observations - data.observations).mean())


@pytest.fixture(scope="module")
def fitted():
    return fit_proxy(linear_system(20, 50, seed=0), ProxyConfig(hidden=(64, 64), steps=1500, seed=3), progress=False)


def test_proxy_learns_held_out_dynamics(fitted):
    heldout = linear_system(4, 50, seed=1)
    error = fitted.error(heldout)
    assert error.n == len(heldout)
    assert error.mae < 0.1 * naive_error(heldout)


def test_proxy_flags_other_dynamics(fitted):
    heldout = linear_system(4, 50, seed=1)
    shifted = dataclasses.replace(heldout, next_observations=heldout.next_observations + 0.05)
    assert fitted.error(shifted).mae > fitted.error(heldout).mae + 0.03


def test_proxy_is_deterministic_per_seed(fitted):
    data = linear_system(20, 50, seed=0)
    again = fit_proxy(data, ProxyConfig(hidden=(64, 64), steps=1500, seed=3), progress=False)
    other = fit_proxy(data, ProxyConfig(hidden=(64, 64), steps=1500, seed=4), progress=False)
    probe = linear_system(1, 20, seed=2)
    predict = lambda proxy: proxy.predict(probe.observations, probe.actions)  # noqa: E731
    np.testing.assert_array_equal(predict(fitted), predict(again))
    assert not np.array_equal(predict(fitted), predict(other))


def test_proxy_refuses_other_dims(fitted):
    with pytest.raises(InputError, match="3-d observations and 2-d actions"):
        fitted.predict(np.zeros((2, 4)), np.zeros((2, 2)))


@pytest.fixture(scope="module")
def reward_proxy():
    config = ProxyConfig(hidden=(64, 64), steps=1500, seed=3)
    return fit_reward_proxy(linear_system(20, 50, seed=0), config, progress=False)


def test_reward_proxy_relabels_wrong_rewards_back_to_the_targets(reward_proxy):
    heldout = linear_system(4, 50, seed=1)
    wrong = dataclasses.replace(heldout, rewards=np.zeros_like(heldout.rewards))
    relabelled = relabel_rewards(wrong, reward_proxy)
    scale = np.abs(heldout.rewards - heldout.rewards.mean()).mean()
    assert np.abs(relabelled.rewards - heldout.rewards).mean() < 0.1 * scale
    assert not wrong.rewards.any()  # the input is not modified
    np.testing.assert_array_equal(relabelled.observations, heldout.observations)
    assert "reward proxy" in relabelled.metadata["rewards"]


def test_reward_proxy_refuses_other_dims(reward_proxy):
    with pytest.raises(InputError, match="3-d observations, 2-d actions and 3-d next observations"):
        reward_proxy.predict(np.zeros((2, 3)), np.zeros((2, 1)), np.zeros((2, 3)))


def test_content_of_an_unchanged_edit_is_perfect(make_dataset):
    data = make_dataset(lengths=(40, 40, 40), obs_dim=4)
    scores = content_similarity(data, data, forward_index=1)
    assert scores["matched"] == {"low_freq_magnitude_difference": 0.0, "low_pass_difference": 0.0,
                                 "forward_velocity_correlation": pytest.approx(1.0)}
    assert scores["mismatched"]["low_pass_difference"] > 0.5


def test_content_separates_small_edits_from_replaced_episodes(make_dataset):
    source = make_dataset(lengths=(64, 64, 64, 64), obs_dim=4, seed=0)
    smooth = np.cumsum(source.observations, axis=0)  # slow, content-bearing signals
    source = dataclasses.replace(source, observations=smooth.astype(np.float32))
    noise = np.random.default_rng(1).normal(scale=0.05 * smooth.std(0), size=smooth.shape)
    edited = dataclasses.replace(source, observations=(smooth + noise).astype(np.float32))
    scores = content_similarity(source, edited, forward_index=0)
    for measure in ("low_freq_magnitude_difference", "low_pass_difference"):
        assert scores["matched"][measure] < 0.5 * scores["mismatched"][measure]
    assert scores["matched"]["forward_velocity_correlation"] > 0.9


def test_content_refuses_different_episodes(make_dataset):
    with pytest.raises(InputError, match="must have the source's episodes"):
        content_similarity(make_dataset(lengths=(4, 6)), make_dataset(lengths=(5, 5)))
    with pytest.raises(InputError, match="forward_index"):
        content_similarity(make_dataset(), make_dataset(), forward_index=7)


def _with(data, velocity: float, reward: float):
    """``data`` with observation column 1 (its forward velocity here) and every reward set to constants."""
    observations = data.observations.copy()
    observations[:, 1] = velocity
    return dataclasses.replace(data, observations=observations, rewards=np.full_like(data.rewards, reward))


def test_content_shift_says_whether_the_edit_moved_the_source_toward_the_target(make_dataset):
    from xted.analysis import content_shift

    source = _with(make_dataset(lengths=(10, 10), obs_dim=4), velocity=6.0, reward=5.0)
    edited = _with(source, velocity=3.5, reward=5.5)
    target = _with(make_dataset(lengths=(8, 12, 5), obs_dim=4, seed=1), velocity=3.7, reward=3.0)
    shift = content_shift(source, edited, target, forward_index=1)
    assert shift["forward_velocity"] == {"source": pytest.approx(6.0), "edited": pytest.approx(3.5),
                                         "target": pytest.approx(3.7), "nearer_target": True}
    assert shift["return_per_1000_steps"] == {"source": pytest.approx(5000.0), "edited": pytest.approx(5500.0),
                                              "target": pytest.approx(3000.0), "nearer_target": False}
    assert set(content_shift(source, edited, target)) == {"return_per_1000_steps"}  # no velocity column named
    with pytest.raises(InputError, match="4-d observations"):
        content_shift(make_dataset(obs_dim=3), make_dataset(obs_dim=3), target)


def test_edit_report_of_an_unchanged_source():
    from xted.analysis import edit_report
    from xted.data import load
    from xted.envs import parse_domain

    source = load("halfcheetah-gravity").select_episodes([0, 1])
    report = edit_report(parse_domain("halfcheetah"), source, source)
    assert report["simulator"]["source"] == report["simulator"]["edited"]
    assert report["simulator"]["source"]["mae"] > 0.05  # 2x gravity is not the target's dynamics
    assert report["content"]["matched"]["forward_velocity_correlation"] == pytest.approx(1.0)
    assert "proxy" not in report
