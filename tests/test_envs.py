import numpy as np
import pytest

import xted.envs as envs
from xted.data import Dataset, load
from xted.envs.dynamics import dynamics_error, predict_next_observations, recovered_velocities, reward_error
from xted.envs.make import forward_velocity_index
from xted.envs.termination import termination
from xted.errors import InputError
from xted.pipelines.bench.grid import first_transitions


def rollout(domain, steps=300, seed=0, with_rewards=False):
    env = envs.make(domain)
    rng = np.random.default_rng(seed)
    obs, _ = env.reset(seed=seed)
    rows = []
    for _ in range(steps):
        action = rng.uniform(-0.3, 0.3, env.action_space.shape).astype(np.float32)
        next_obs, reward, terminated, truncated, _ = env.step(action)
        rows.append((obs, action, next_obs, reward))
        obs = next_obs
        if terminated or truncated:
            obs, _ = env.reset()
    arrays = [np.array(x) for x in zip(*rows)]
    return arrays if with_rewards else arrays[:3]


def as_dataset(obs, act, nxt, rewards):
    timeouts = np.zeros(len(obs), bool)
    timeouts[-1] = True
    return Dataset(observations=obs, actions=act, rewards=rewards, terminals=np.zeros(len(obs), bool),
                   timeouts=timeouts, next_observations=nxt)


def test_parse_paper_and_parametric_gaps():
    assert envs.parse_domain("halfcheetah", "friction").friction == 0.25
    assert envs.parse_domain("walker2d", "friction").friction == 0.5
    combo = envs.parse_domain("walker2d", "gravity=1.5,thigh=3")
    assert (combo.gravity, combo.friction, combo.thigh) == (1.5, 1.0, 3.0)
    assert envs.parse_domain("halfcheetah", "thigh=2").gap == "thigh"
    assert envs.parse_domain("halfcheetah", None).is_target
    assert envs.parse_domain("Hopper-v5", "gravity") == envs.parse_domain("hopper", "gravity")  # a Gymnasium id


@pytest.mark.parametrize("env,gap", [("halfcheetah", "wind"), ("halfcheetah", "gravity=-1"), ("humanoid", None),
                                     ("walker2d", "gravity=abc"), ("ant", "thigh"), ("ant", "thigh=2")])
def test_bad_gaps_are_refused(env, gap):
    with pytest.raises(InputError):
        envs.parse_domain(env, gap)


@pytest.mark.parametrize("env", ["halfcheetah", "walker2d", "hopper", "ant"])
def test_target_transitions_replay_exactly(env):
    obs, act, nxt = rollout(envs.parse_domain(env), steps=200)
    result = dynamics_error(envs.parse_domain(env), obs, act, nxt)
    assert result.n > 0
    assert result.mae < 1e-8


@pytest.mark.parametrize("env", ["halfcheetah", "walker2d", "hopper"])
@pytest.mark.parametrize("gap", ["gravity", "friction", "thigh", "thigh=0.5"])
def test_each_gap_changes_the_dynamics(env, gap):
    source = envs.parse_domain(env, gap)
    obs, act, nxt = rollout(source, steps=300)
    in_source = dynamics_error(source, obs, act, nxt)
    in_target = dynamics_error(envs.parse_domain(env), obs, act, nxt)
    assert in_source.mae < 1e-8
    assert in_target.mae > 1e-3


@pytest.mark.parametrize("env", ["halfcheetah", "walker2d"])
@pytest.mark.parametrize("factor", [0.5, 2.0, 3.0])
def test_morphology_loads_and_starts_upright(env, factor):
    domain = envs.parse_domain(env, f"thigh={factor}")
    env_instance = envs.make(domain)
    env_instance.reset(seed=0)
    model, data = env_instance.unwrapped.model, env_instance.unwrapped.data
    thigh = "thigh" if env == "walker2d" else "bthigh"
    baseline = envs.make(envs.parse_domain(env)).unwrapped.model
    geom = model.geom(thigh + ("_geom" if env == "walker2d" else ""))
    base_geom = baseline.geom(thigh + ("_geom" if env == "walker2d" else ""))
    assert geom.size[1] == pytest.approx(base_geom.size[1] * factor)
    import mujoco

    mujoco.mj_resetData(model, data)
    mujoco.mj_forward(model, data)
    # The default pose touches nothing; the robot stays upright for a moment at rest.
    assert data.ncon == 0
    env_instance.reset(seed=0)
    for _ in range(20):
        _, _, terminated, _, _ = env_instance.step(np.zeros(6))
        assert not terminated
    assert abs(data.qpos[2]) < 0.5  # pitch


def test_velocity_clip_transitions_are_excluded():
    domain = envs.parse_domain("walker2d")
    obs, act, nxt = rollout(domain, steps=100)
    obs[0, -1] = 10.0
    result = dynamics_error(domain, obs, act, nxt)
    assert result.excluded_clipped >= 1
    assert result.n + result.excluded_clipped == len(obs)


def test_states_beyond_the_velocity_clip_count_as_errors_against_the_clipped_prediction():
    domain = envs.parse_domain("walker2d")
    obs, act, nxt = rollout(domain, steps=50)
    exact = dynamics_error(domain, obs, act, nxt)
    assert exact.beyond_clip == 0 and exact.mae < 1e-6
    fixed = ~np.any(np.isclose(np.abs(obs[:, 8:]), 10.0), axis=1)  # qvel starts at nq - 1 = 8
    i = int(np.flatnonzero(fixed & (np.abs(nxt[:, -1]) < 9))[0])
    edited = nxt.copy()
    edited[i, -1] = 13.0  # no observation can hold this: the env would show at most 10
    result = dynamics_error(domain, obs, act, edited)
    assert (result.n, result.excluded_clipped) == (exact.n, exact.excluded_clipped) and result.beyond_clip == 1
    row = int(fixed[:i].sum())
    assert result.mae_per_transition[row] == pytest.approx(abs(13.0 - nxt[i, -1]) / obs.shape[1], rel=1e-5)
    assert result.summary()["beyond_clip"] == 1
    # An edit's states are no recording: those at the clip are replayed as they stand, not excluded.
    edited_obs = obs.copy()
    edited_obs[i, -1] = 10.0
    as_recorded = dynamics_error(domain, edited_obs, act, nxt)
    as_edit = dynamics_error(domain, edited_obs, act, nxt, replay_states_at_clip=True)
    assert as_recorded.excluded_clipped == exact.excluded_clipped + 1
    assert (as_edit.n, as_edit.excluded_clipped) == (len(obs), 0)


def test_dimension_mismatch_is_refused():
    domain = envs.parse_domain("halfcheetah")
    with pytest.raises(InputError, match="dims"):
        dynamics_error(domain, np.zeros((3, 11)), np.zeros((3, 6)), np.zeros((3, 11)))


def test_ant_observations_with_contact_forces_are_refused_with_the_option_that_records_the_state():
    with pytest.raises(InputError, match="105 dims but ant states have 27.*include_cfrc_ext_in_observation=False"):
        dynamics_error(envs.parse_domain("ant"), np.zeros((3, 105)), np.zeros((3, 8)), np.zeros((3, 105)))


@pytest.mark.parametrize("gap", ["gravity", "friction"])
def test_ant_gaps_change_its_dynamics(gap):
    source = envs.parse_domain("ant", gap)
    obs, act, nxt = rollout(source, steps=200)
    assert obs.shape[1] == 27  # qpos without x and y, then qvel: no contact forces
    assert dynamics_error(source, obs, act, nxt).mae < 1e-8
    assert dynamics_error(envs.parse_domain("ant"), obs, act, nxt).mae > 1e-3


def test_ant_rewards_replay_up_to_the_lag_of_its_forward_velocity():
    domain = envs.parse_domain("ant")
    obs, act, nxt, rewards = rollout(domain, steps=200, with_rewards=True)
    replayed = reward_error(domain, as_dataset(obs, act, nxt, rewards))
    assert replayed.n == 200 and 0 < replayed.mae < 0.02 and replayed.correlation > 0.99


@pytest.mark.parametrize("env", ["halfcheetah", "walker2d"])
def test_recorded_rewards_replay_exactly_and_a_shift_shows_as_bias(env):
    domain = envs.parse_domain(env)
    obs, act, nxt, rewards = rollout(domain, steps=200, with_rewards=True)
    exact = reward_error(domain, as_dataset(obs, act, nxt, rewards))
    assert exact.n > 0 and exact.mae < 1e-6
    shifted = reward_error(domain, as_dataset(obs, act, nxt, rewards - 0.5))
    assert shifted.bias == pytest.approx(-0.5, abs=1e-6)
    assert shifted.mae == pytest.approx(0.5, abs=1e-6)


def test_source_rewards_differ_from_the_targets_where_the_morphology_does():
    source = envs.parse_domain("halfcheetah", "thigh")
    obs, act, nxt, rewards = rollout(source, steps=200, with_rewards=True)
    data = as_dataset(obs, act, nxt, rewards)
    assert reward_error(source, data).mae < 1e-6
    assert reward_error(envs.parse_domain("halfcheetah"), data).mae > 1e-3


def test_recovered_velocities_replay_a_recording_through_its_clipped_states():
    """A walker2d recording stepped from its recovered states gives its next observations (clipped as
    observed) on every transition; the same data read as another domain's recording is not
    reproduced there, and its states at the clip stay clipped and are counted."""
    data = first_transitions(load("walker2d-medium-replay"), 400)
    domain = envs.parse_domain("walker2d")
    recovered = recovered_velocities(domain, data)
    velocities = slice(forward_velocity_index(domain), None)
    assert recovered.at_clip > 50 and recovered.unrecovered == 0
    assert np.abs(recovered.velocities).max() > 10.5  # beyond the clip
    predicted = predict_next_observations(domain, data.observations, data.actions, recovered.velocities)
    predicted[:, velocities] = np.clip(predicted[:, velocities], -10, 10)
    assert np.abs(predicted - data.next_observations).max() < 1e-3

    elsewhere = recovered_velocities(envs.parse_domain("walker2d", "gravity"), data)
    assert elsewhere.at_clip == recovered.at_clip and elsewhere.unrecovered > recovered.at_clip // 2
    observed = data.observations[:, velocities]
    assert np.sum(np.any(elsewhere.velocities != observed, axis=1)) == elsewhere.at_clip - elsewhere.unrecovered


def test_ant_termination_rule_agrees_with_ant_v5():
    env = envs.make("ant")
    rng = np.random.default_rng(0)
    obs, _ = env.reset(seed=0)
    next_observations, terminated = [], []
    for _ in range(600):
        obs, _, done, truncated, _ = env.step(rng.uniform(-1, 1, 8))
        next_observations.append(obs)
        terminated.append(done)
        if done or truncated:
            obs, _ = env.reset(seed=len(terminated))
    rule = termination("Ant-v5")(np.array(next_observations))
    assert np.array(terminated).any() and rule.tolist() == terminated
