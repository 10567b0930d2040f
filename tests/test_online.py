import dataclasses
import json

import jax
import numpy as np
import pytest

from xted.cli.main import main
from xted.envs import parse_domain
from xted.errors import InputError
from xted.rl.config import ONLINE_ALGORITHM_NAMES
from xted.rl.online import ONLINE_ALGORITHMS, OnlineRunConfig, actor_checkpoint, read_evals, train_online
from xted.rl.policy_io import Policy
from xted.rl.sac import SACConfig, init_sac, sac_update
from xted.rl.td3bc import TD3BCConfig

TINY = SACConfig(hidden=(32, 32), batch_size=64)
TINY_TD3 = TD3BCConfig(hidden=(32, 32), batch_size=64, behaviour_cloning=False)


def test_sac_update_fits_a_one_step_problem():
    rng = np.random.default_rng(0)
    obs = rng.normal(size=(256, 3)).astype(np.float32)
    actions = rng.uniform(-1, 1, (256, 2)).astype(np.float32)
    batch = {"observations": obs, "actions": actions, "rewards": -np.sum(actions**2, axis=1),
             "next_observations": obs, "terminals": np.ones(256, np.float32)}
    state = init_sac(jax.random.PRNGKey(0), 3, 2, TINY, 0)
    losses = []
    for _ in range(300):
        state, info = sac_update(state, batch, TINY)
        losses.append(float(info["critic_loss"]))
    assert np.mean(losses[-20:]) < 0.2 * np.mean(losses[:20])


def _params_equal(a, b):
    for x, y in zip(jax.tree_util.tree_leaves(a), jax.tree_util.tree_leaves(b), strict=True):
        np.testing.assert_array_equal(x, y)


@pytest.mark.slow
@pytest.mark.parametrize("algo", ["sac", "td3"])
def test_online_run_resumes_to_the_same_policy(tmp_path, algo):
    domain = parse_domain("halfcheetah")
    base = dict(algo=algo, start_steps=500, checkpoint_every=1000, eval_episodes=1, block=64, sac=TINY, td3=TINY_TD3)
    train_online(domain, tmp_path / "straight", OnlineRunConfig(total_steps=1500, **base), progress=False)
    train_online(domain, tmp_path / "resumed", OnlineRunConfig(total_steps=1000, **base), progress=False)
    train_online(domain, tmp_path / "resumed", OnlineRunConfig(total_steps=1500, **base), progress=False)
    straight = Policy.load(actor_checkpoint(tmp_path / "straight", 1500))
    resumed = Policy.load(actor_checkpoint(tmp_path / "resumed", 1500))
    _params_equal(straight.params, resumed.params)
    assert straight.kind == {"sac": "tanh_gaussian", "td3": "deterministic"}[algo]
    evals = read_evals(tmp_path / "resumed")
    assert [row["step"] for row in evals] == [1000, 1500]
    assert evals[1]["cpu_seconds"] > evals[0]["cpu_seconds"] > 0
    with np.load(tmp_path / "resumed" / "buffer.npz") as buffer:
        assert buffer["timeouts"][999] and buffer["timeouts"][1499]
        assert len(buffer["rewards"]) == 1500
        assert np.all(buffer["next_observations"][:998] == buffer["observations"][1:999])


@pytest.mark.slow
def test_block_size_changes_only_when_the_actor_is_refreshed(tmp_path):
    """Before learning starts the actor is never used: any block size gives the same buffer and
    the same first updates' batches, so the same parameters after the first update."""
    domain = parse_domain("halfcheetah")
    base = dict(algo="sac", total_steps=1000, start_steps=1000, checkpoint_every=1000, eval_episodes=1, sac=TINY)
    for block in (1, 50):
        train_online(domain, tmp_path / str(block), OnlineRunConfig(block=block, **base), progress=False)
    _params_equal(Policy.load(actor_checkpoint(tmp_path / "1", 1000)).params,
                  Policy.load(actor_checkpoint(tmp_path / "50", 1000)).params)


def test_resume_refuses_other_settings_and_a_shorter_run(tmp_path):
    domain = parse_domain("halfcheetah")
    config = OnlineRunConfig(algo="sac", total_steps=1000, start_steps=500, checkpoint_every=1000, eval_episodes=1, sac=TINY)
    train_online(domain, tmp_path / "run", config, progress=False)
    with pytest.raises(InputError, match="start_steps: 500 -> 400"):
        train_online(domain, tmp_path / "run", dataclasses.replace(config, total_steps=2000, start_steps=400),
                     progress=False)
    with pytest.raises(InputError, match="domain"):
        train_online(parse_domain("halfcheetah", "gravity"), tmp_path / "run", config, progress=False)
    with pytest.raises(InputError, match="beyond --steps 500"):
        train_online(domain, tmp_path / "run", dataclasses.replace(config, total_steps=500), progress=False)


def test_every_online_algorithm_name_has_an_algorithm():
    assert tuple(ONLINE_ALGORITHMS) == ONLINE_ALGORITHM_NAMES


@pytest.mark.parametrize("flag, says", [(["--steps", "0"], "--steps"), (["--checkpoint-every", "0"], "checkpoint_every"),
                                        (["--algo", "ppo"], "'ppo'")])
def test_cli_refuses_bad_settings(tmp_path, capsys, flag, says):
    code = main(["online", "train", "--env", "halfcheetah", "--out", str(tmp_path / "run"), *flag])
    assert code == 2
    assert not (tmp_path / "run").exists()
    assert says in capsys.readouterr().err


def test_cli_trains_and_evaluates(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["online", "train", "--env", "halfcheetah", "--algo", "td3", "--out", str(out), "--steps", "600",
                 "--start-steps", "500", "--checkpoint-every", "600", "--eval-episodes", "1"]) == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["step"] == 600
    assert main(["online", "evaluate", str(actor_checkpoint(out, 600)), "--env", "halfcheetah", "--episodes", "1",
                 "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["domain"] == "halfcheetah"


@pytest.mark.slow
def test_stop_at_return_ends_the_run_at_that_evaluation_and_a_resume_can_go_on(tmp_path):
    domain = parse_domain("halfcheetah")
    base = dict(algo="td3", total_steps=2000, start_steps=500, checkpoint_every=1000, eval_episodes=1, td3=TINY_TD3)
    train_online(domain, tmp_path / "run", OnlineRunConfig(stop_at_return=-1e9, **base), progress=False)
    assert [row["step"] for row in read_evals(tmp_path / "run")] == [1000]
    train_online(domain, tmp_path / "run", OnlineRunConfig(stop_at_return=-1e9, **base), progress=False)
    assert [row["step"] for row in read_evals(tmp_path / "run")] == [1000]
    train_online(domain, tmp_path / "run", OnlineRunConfig(stop_at_return=1e9, **base), progress=False)
    assert [row["step"] for row in read_evals(tmp_path / "run")] == [1000, 2000]


@pytest.mark.slow
def test_stop_above_pitch_ends_the_run_at_a_flipped_evaluation_and_a_larger_one_goes_on(tmp_path):
    domain = parse_domain("halfcheetah")
    base = dict(algo="td3", total_steps=2000, start_steps=500, checkpoint_every=1000, eval_episodes=1, td3=TINY_TD3)
    train_online(domain, tmp_path / "run", OnlineRunConfig(stop_above_pitch=1e-9, **base), progress=False)
    first = read_evals(tmp_path / "run")
    assert [row["step"] for row in first] == [1000] and first[0]["root_pitch_mean"] > 1e-9
    train_online(domain, tmp_path / "run", OnlineRunConfig(stop_above_pitch=1e9, **base), progress=False)
    assert [row["step"] for row in read_evals(tmp_path / "run")] == [1000, 2000]
    with pytest.raises(InputError, match="stop_above_pitch"):
        OnlineRunConfig(stop_above_pitch=0.0, **base)


@pytest.mark.slow
def test_terminate_above_pitch_ends_training_episodes_where_the_body_tips_and_is_part_of_the_run(tmp_path):
    domain = parse_domain("halfcheetah")
    base = dict(algo="td3", total_steps=300, start_steps=300, checkpoint_every=300, eval_episodes=1, td3=TINY_TD3)
    threshold, bonus = 0.05, 100.0  # a random cheetah's step rewards stay within a few units
    train_online(domain, tmp_path / "upright", OnlineRunConfig(terminate_above_pitch=threshold, upright_bonus=bonus,
                                                               **base), progress=False)
    train_online(domain, tmp_path / "plain", OnlineRunConfig(**base), progress=False)
    upright, plain = (np.load(tmp_path / name / "buffer.npz") for name in ("upright", "plain"))
    tipped = np.abs(upright["next_observations"][:, 1]) > threshold
    np.testing.assert_array_equal(upright["terminals"], tipped)
    assert tipped.any() and (~tipped).any() and not plain["terminals"].any()
    np.testing.assert_array_equal(upright["rewards"] > bonus / 2, ~tipped)
    assert np.abs(plain["rewards"]).max() < bonus / 2
    with pytest.raises(InputError, match="another run"):  # another training MDP: not the same run
        train_online(domain, tmp_path / "plain", OnlineRunConfig(terminate_above_pitch=threshold, **base),
                     progress=False)
    with pytest.raises(InputError, match="terminate_above_pitch"):
        OnlineRunConfig(terminate_above_pitch=-1.0, **base)


@pytest.mark.slow
def test_init_from_starts_from_the_runs_networks_and_is_part_of_the_run(tmp_path):
    base = dict(algo="td3", checkpoint_every=1000, eval_episodes=1, block=64, td3=TINY_TD3)
    train_online(parse_domain("halfcheetah"), tmp_path / "expert",
                 OnlineRunConfig(total_steps=1000, start_steps=200, **base), progress=False)
    other = train_online(parse_domain("halfcheetah"), tmp_path / "other",
                         OnlineRunConfig(total_steps=1000, start_steps=200, seed=1, **base), progress=False)
    # No update before --start-steps: the fine-tuned run's first actor is the expert's last one.
    tuned = OnlineRunConfig(total_steps=1000, start_steps=5000, init_from=str(tmp_path / "expert"), **base)
    train_online(parse_domain("halfcheetah", "gravity"), tmp_path / "tuned", tuned, progress=False)
    expert = Policy.load(actor_checkpoint(tmp_path / "expert", 1000))
    _params_equal(Policy.load(actor_checkpoint(tmp_path / "tuned", 1000)).params, expert.params)
    with np.load(tmp_path / "tuned" / "buffer.npz") as buffer:  # acted by the expert (plus noise), not uniformly
        greedy = expert.act(buffer["observations"][:20])
        assert np.abs(buffer["actions"][:20] - greedy).max() < 0.5  # noise std 0.1; uniform would stray by ~1
    with pytest.raises(InputError, match="holds another run .init_sha256"):  # another init is another run
        train_online(parse_domain("halfcheetah", "gravity"), tmp_path / "tuned",
                     dataclasses.replace(tuned, init_from=str(other), total_steps=2000), progress=False)
    with pytest.raises(InputError, match="a td3 run, but this run trains sac"):
        train_online(parse_domain("halfcheetah"), tmp_path / "sac",
                     OnlineRunConfig(algo="sac", total_steps=100, init_from=str(tmp_path / "expert"), sac=TINY),
                     progress=False)
    with pytest.raises(InputError, match="other shapes"):
        wide = dataclasses.replace(TINY_TD3, hidden=(16, 16))
        train_online(parse_domain("halfcheetah"), tmp_path / "wide",
                     dataclasses.replace(tuned, td3=wide), progress=False)
    with pytest.raises(InputError, match="not an online run folder"):
        train_online(parse_domain("halfcheetah"), tmp_path / "none",
                     dataclasses.replace(tuned, init_from=str(tmp_path / "missing")), progress=False)
