import jax
import numpy as np

from xted.envs import parse_domain
from xted.rl.policy_io import GaussianActor
from xted.rl.sac import SACConfig, init_sac, sac_update
from xted.rl.sac_train import SACRunConfig, actor_checkpoint, read_evals, train_sac

TINY = SACConfig(hidden=(32, 32), batch_size=64)


def test_sac_update_fits_a_one_step_problem():
    rng = np.random.default_rng(0)
    obs = rng.normal(size=(256, 3)).astype(np.float32)
    actions = rng.uniform(-1, 1, (256, 2)).astype(np.float32)
    batch = {"observations": obs, "actions": actions, "rewards": -np.sum(actions**2, axis=1),
             "next_observations": obs, "terminals": np.ones(256, np.float32)}
    state = init_sac(jax.random.PRNGKey(0), 3, 2, TINY)
    losses = []
    for _ in range(300):
        state, info = sac_update(state, batch, TINY)
        losses.append(float(info["critic_loss"]))
    assert np.mean(losses[-20:]) < 0.2 * np.mean(losses[:20])


def test_sac_run_resumes_to_the_same_policy(tmp_path):
    domain = parse_domain("halfcheetah")
    config = SACRunConfig(total_steps=1500, start_steps=500, checkpoint_every=1000, eval_episodes=1, sac=TINY)
    train_sac(domain, tmp_path / "straight", config, progress=False)
    half = SACRunConfig(total_steps=1000, start_steps=500, checkpoint_every=1000, eval_episodes=1, sac=TINY)
    train_sac(domain, tmp_path / "resumed", half, progress=False)
    train_sac(domain, tmp_path / "resumed", config, progress=False)
    straight = GaussianActor.load(actor_checkpoint(tmp_path / "straight", 1500)).params
    resumed = GaussianActor.load(actor_checkpoint(tmp_path / "resumed", 1500)).params
    for a, b in zip(jax.tree_util.tree_leaves(straight), jax.tree_util.tree_leaves(resumed)):
        np.testing.assert_array_equal(a, b)
    assert [row["step"] for row in read_evals(tmp_path / "resumed")] == [1000, 1500]
    with np.load(tmp_path / "resumed" / "buffer.npz") as buffer:
        assert buffer["timeouts"][999] and buffer["timeouts"][1499]
