import numpy as np
import pytest

from xted.data.shipped import policies_dir
from xted.pipelines.behaviour_data import BehaviourPolicies, build_dataset, policy_reference, select_checkpoints
from xted.envs import parse_domain
from xted.envs.dynamics import dynamics_error
from xted.errors import InputError
from xted.rl.policy_io import Policy
from xted.rl.run_folder import actor_checkpoint, read_evals
from xted.rl.sac import SACConfig
from xted.rl.online import OnlineRunConfig, train_online

pytestmark = pytest.mark.slow  # every test reads one online training run, made once (about 17 s)


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    run = tmp_path_factory.mktemp("sac") / "halfcheetah"
    config = OnlineRunConfig(algo="sac", total_steps=3000, start_steps=500, checkpoint_every=1000, eval_episodes=1,
                          sac=SACConfig(hidden=(32, 32), batch_size=64))
    train_online(parse_domain("halfcheetah"), run, config, progress=False)
    return run


def test_select_checkpoints_picks_best_and_half_of_it_before():
    evals = [{"step": s, "return_mean": r} for s, r in [(1, 100.0), (2, 1000.0), (3, 1600.0), (4, 3000.0), (5, 2500.0),
                                                          (6, 1500.0)]]
    assert select_checkpoints(evals) == (4, 3)


def test_policy_reference_names_shipped_policies_without_the_install_path(tmp_path):
    shipped = policies_dir() / "halfcheetah-expert.msgpack"
    assert policy_reference(shipped) == "xted/assets/policies/halfcheetah-expert.msgpack"
    assert policy_reference(tmp_path / "mine.msgpack") == str(tmp_path / "mine.msgpack")


@pytest.mark.parametrize("level", ["medium", "medium-replay", "expert", "medium-expert"])
def test_levels_from_a_run(tiny_run, level):
    domain = parse_domain("halfcheetah")
    size = 1000 if level == "medium-replay" else 1500
    data = build_dataset(domain, level, size, BehaviourPolicies.from_run(tiny_run), seed=1, progress=False)
    assert len(data) == size
    assert data.metadata["level"] == level and data.metadata["env"] == "halfcheetah"
    assert np.isfinite(data.metadata["normalized_score"])
    assert data.timeouts[-1] or data.terminals[-1]
    # Real target-domain transitions: the simulator replays them exactly.
    assert dynamics_error(domain, data.observations, data.actions, data.next_observations).mae < 1e-6


def test_a_chosen_medium_step_is_the_medium_policy_and_cuts_the_replay_buffer(tiny_run):
    evaluated = [int(row["step"]) for row in read_evals(tiny_run)]
    default = BehaviourPolicies.from_run(tiny_run)
    step = min(s for s in evaluated if actor_checkpoint(tiny_run, s) != default.medium)
    chosen = BehaviourPolicies.from_run(tiny_run, medium_step=step)
    assert chosen.medium == actor_checkpoint(tiny_run, step) and chosen.expert == default.expert
    assert Policy.load(chosen.medium).meta["step"] == step
    data = build_dataset(parse_domain("halfcheetah"), "medium-replay", 400, chosen, seed=1, progress=False)
    assert data.metadata["policy"] == str(chosen.medium)
    with np.load(tiny_run / "buffer.npz") as buffer:
        prefix = buffer["observations"][:step]
    assert {row.tobytes() for row in data.observations} <= {row.tobytes() for row in prefix}
    with pytest.raises(InputError, match="no evaluated checkpoint at that step"):
        BehaviourPolicies.from_run(tiny_run, medium_step=step + 1)


def test_source_data_is_cut_into_whole_episodes_with_timeouts():
    domain = parse_domain("walker2d", "gravity")
    data = build_dataset(domain, "random", 700, None, seed=0, progress=False)
    assert len(data) == 700
    assert data.metadata["gap"] == "gravity"
    ends = data.terminals | data.timeouts
    assert ends[-1] and ends.sum() >= 2
    assert dynamics_error(domain, data.observations, data.actions, data.next_observations).mae < 1e-6


def test_same_seed_same_data(tiny_run):
    domain = parse_domain("halfcheetah")
    policies = BehaviourPolicies.from_run(tiny_run)
    a = build_dataset(domain, "medium", 1000, policies, seed=3, progress=False)
    b = build_dataset(domain, "medium", 1000, policies, seed=3, progress=False)
    np.testing.assert_array_equal(a.observations, b.observations)
    np.testing.assert_array_equal(a.actions, b.actions)


def test_replay_buffer_too_small_is_refused(tiny_run):
    with pytest.raises(InputError, match="fewer than"):
        build_dataset(parse_domain("halfcheetah"), "medium-replay", 10**6, BehaviourPolicies.from_run(tiny_run))


def test_bad_level_and_missing_policies():
    with pytest.raises(InputError, match="level"):
        build_dataset(parse_domain("halfcheetah"), "expertish", 10, None)
    with pytest.raises(InputError, match="policies"):
        build_dataset(parse_domain("halfcheetah"), "medium", 10, None)
