"""IGDF and OTDF: each ranks source transitions of the target's dynamics above shifted ones, the
per-batch filter keeps and weights as specified, and both train IQL end to end."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from xted.data import Dataset
from xted.errors import InputError
from xted.rl import igdf, otdf
from xted.rl.config import IGDFConfig, IQLConfig, OTDFConfig
from xted.rl.offline_train import train_offline
from xted.rl.source_weighting import weigh_batch

TINY_IQL = IQLConfig(hidden=(32, 32), batch_size=64)
IGDF_TINY = IGDFConfig(encoder_hidden=(64, 64), embedding_dim=16, encoder_steps=1500, encoder_lr=1e-3, iql=TINY_IQL)
OTDF_TINY = OTDFConfig(vae_hidden=(32, 32), vae_steps=200, chunk=300, iql=TINY_IQL)


def transitions(n: int, shift: float, seed: int) -> dict[str, np.ndarray]:
    """Linear dynamics s' = 0.9 s + 0.3 a (+ shift on every coordinate) on 4-d states, 2-d actions."""
    rng = np.random.default_rng(seed)
    obs = rng.normal(size=(n, 4))
    actions = rng.uniform(-1, 1, size=(n, 2))
    next_obs = 0.9 * obs + 0.3 * np.concatenate([actions, actions], axis=1) + shift
    return {"observations": obs.astype(np.float32), "actions": actions.astype(np.float32),
            "next_observations": next_obs.astype(np.float32)}


def mixed_source(n: int = 600) -> tuple[dict, dict, np.ndarray]:
    """The target, and a source whose first half follows the target's dynamics and second half a shifted one."""
    target = transitions(1000, 0.0, 0)
    same, shifted = transitions(n // 2, 0.0, 1), transitions(n // 2, 1.5, 2)
    source = {k: np.concatenate([same[k], shifted[k]]) for k in same}
    return target, source, np.repeat([1, 0], n // 2)


def auc(scores: np.ndarray, positive: np.ndarray) -> float:
    """P(score of a positive > score of a negative)."""
    pos, neg = scores[positive == 1], scores[positive == 0]
    return float((pos[:, None] > neg[None, :]).mean())


def test_igdf_scores_rank_the_targets_dynamics_first():
    target, source, same = mixed_source()
    scores, losses = igdf.source_scores(jax.random.split(jax.random.PRNGKey(0), 2), target, source, IGDF_TINY)
    assert scores.shape == (2, len(same))
    assert losses[:, -100:].mean() < losses[:, :100].mean()
    for seed_scores in scores:
        assert auc(seed_scores, same) >= 0.9


def test_otdf_deviation_ranks_the_targets_dynamics_first():
    target, source, same = mixed_source()
    deviations = otdf.source_deviations(target, source, OTDF_TINY)
    assert deviations.shape == (len(same),) and np.all(deviations >= 0)
    assert auc(-deviations, same) >= 0.9


def reference_deviation(x: np.ndarray, y: np.ndarray, epsilon: float, iterations: int = 2000) -> np.ndarray:
    """Log-domain Sinkhorn in float64, by the definition: the same problem as transport_deviation's."""
    x = x / np.linalg.norm(x, axis=1, keepdims=True)
    y = y / np.linalg.norm(y, axis=1, keepdims=True)
    raw = 1.0 - x @ y.T
    cost = raw / raw.max()
    eps = epsilon * cost.mean()
    log_a, log_b = -np.log(len(x)), -np.log(len(y))
    f, g = np.zeros(len(x)), np.zeros(len(y))
    for _ in range(iterations):
        f = eps * (log_a - np.logaddexp.reduce((g[None] - cost) / eps, axis=1))
        g = eps * (log_b - np.logaddexp.reduce((f[:, None] - cost) / eps, axis=0))
    plan = np.exp((f[:, None] + g[None] - cost) / eps)
    return (plan * raw).sum(1) / plan.sum(1)


@pytest.mark.parametrize("epsilon", [0.05, 0.005])  # the scaled kernel, and the log domain (1 / eps above 80)
def test_sinkhorn_agrees_with_a_float64_reference(epsilon):
    rng = np.random.default_rng(0)
    x, y = rng.normal(size=(40, 3)), rng.normal(size=(60, 3))
    ours = np.asarray(otdf.transport_deviation(jnp.asarray(x, jnp.float32), jnp.asarray(y, jnp.float32), epsilon,
                                               2000, 1e-7))
    assert np.allclose(ours, reference_deviation(x, y, epsilon), atol=2e-3)


def test_a_deviation_lies_between_the_nearest_and_the_farthest_cost():
    rng = np.random.default_rng(0)
    x, y = jnp.asarray(rng.normal(size=(50, 3))), jnp.asarray(rng.normal(size=(70, 3)))
    # The deviation of a point is a convex mix of its costs: between the nearest and the farthest.
    deviation = np.asarray(otdf.transport_deviation(x, y, 0.05, 500, 1e-7))
    cost = np.asarray(otdf.cosine_cost(x, y))
    assert np.all(deviation >= cost.min(axis=1) - 1e-5) and np.all(deviation <= cost.max(axis=1) + 1e-5)
    # A point identical to one of y's is matched near it: far cheaper than its average cost.
    same = np.asarray(otdf.transport_deviation(y[:50], y, 0.01, 500, 1e-7))
    assert np.median(same) < 0.5 * np.median(np.asarray(otdf.cosine_cost(y[:50], y)).mean(axis=1))


def test_behaviour_vae_prefers_the_targets_actions():
    target = transitions(3000, 0.0, 0)
    target["actions"] = np.tanh(target["observations"][:, :2]).astype(np.float32)  # actions a function of s
    config = OTDFConfig(vae_hidden=(64, 64), vae_steps=1500, iql=TINY_IQL)
    params, losses = otdf.train_behaviour(jax.random.PRNGKey(0), target, config)
    assert losses[-100:].mean() < losses[:100].mean()
    obs = jnp.asarray(target["observations"][:2500])  # more states than one decoding chunk
    decoded = otdf.decode_behaviour(params, obs, jax.random.PRNGKey(1), config, action_dim=2)
    assert decoded.shape == (2500, config.behaviour_samples, 2)
    own = otdf.behaviour_log_prob(decoded[:200], jnp.asarray(target["actions"][:200]), config)
    flipped = otdf.behaviour_log_prob(decoded[:200], -jnp.asarray(target["actions"][:200]), config)
    assert float(own.mean()) > float(flipped.mean()) + 1.0
    # Seeds decode apart, each with its own CVAE and key; a state's draws do not depend on its chunk.
    stacked = jax.tree.map(lambda x: jnp.stack([x, x]), params)
    both = otdf.decode_behaviours(stacked, obs, jax.random.split(jax.random.PRNGKey(1), 2), config, 2)
    assert both.shape == (2, 2500, config.behaviour_samples, 2) and not np.allclose(both[0], both[1])


def test_otdf_redraws_must_fall_on_training_segments():
    with pytest.raises(InputError, match="multiple of 1,000"):
        OTDFConfig(behaviour_redraw_every=1500)


@pytest.mark.parametrize("method", [IGDFConfig(keep_fraction=0.25, weight_scale=1.0), OTDFConfig(keep_fraction=0.8)])
def test_batch_filter_keeps_the_best_source_share_and_every_target(method):
    is_source = np.r_[np.zeros(20), np.ones(100)].astype(np.float32)
    score = np.r_[np.zeros(20), np.linspace(-1.0, 1.0, 100)].astype(np.float32)
    batch = weigh_batch({"is_source": jnp.asarray(is_source), "source_score": jnp.asarray(score)}, method)
    keep, q_weight = np.asarray(batch["sample_weight"]), np.asarray(batch["q_weight"])
    assert np.all(keep[:20] == 1) and np.all(q_weight[:20] == 1)
    kept = keep[20:] == 1
    assert abs(kept.sum() - method.keep_fraction * 100) <= 1
    assert score[20:][kept].min() >= score[20:][~kept].max()  # the best-scored ones
    assert np.all(q_weight[20:][~kept] == 0) and np.all(q_weight[20:][kept] > 0)
    if isinstance(method, OTDFConfig):  # rescaled onto [-1, 0]: the best source weighs exp(0)
        assert np.isclose(q_weight[20:].max(), 1.0) and q_weight[20:][kept].min() >= np.exp(-1.0) - 1e-6
    else:
        assert np.isclose(q_weight[20:].max(), np.e, rtol=1e-5)


def dataset(arrays: dict, rewards: np.ndarray) -> Dataset:
    n = len(rewards)
    return Dataset(observations=arrays["observations"], actions=arrays["actions"], rewards=rewards.astype(np.float32),
                   terminals=np.zeros(n, bool), timeouts=np.r_[np.zeros(n - 1, bool), True],
                   next_observations=arrays["next_observations"])


@pytest.mark.parametrize("config", [IGDFConfig(encoder_steps=50, iql=TINY_IQL),
                                    OTDFConfig(vae_steps=50, vae_hidden=(16,), chunk=200, iql=TINY_IQL)])
def test_filtered_iql_trains_seeds_deterministically(config):
    target_arrays, source_arrays, _ = mixed_source(400)
    target_arrays = {k: v[:300] for k, v in target_arrays.items()}
    target = dataset(target_arrays, target_arrays["observations"][:, 0])
    source = dataset(source_arrays, source_arrays["observations"][:, 0])
    first = train_offline(config, target, [source], None, 200, [0, 1], eval_every=100, progress=False)
    again = train_offline(config, target, [source], None, 200, [0], eval_every=100, progress=False)
    leaves = [jax.tree.leaves(result["policy"].params) for result in (first[0], again[0])]
    assert all(np.allclose(a, b, atol=1e-5) for a, b in zip(*leaves))
    assert not all(np.allclose(a, b) for a, b in zip(leaves[0], jax.tree.leaves(first[1]["policy"].params)))
    with pytest.raises(InputError, match="source"):
        train_offline(config, target, [], None, 10, [0], progress=False)


def test_filter_fields_are_checked():
    with pytest.raises(InputError, match="keep_fraction"):
        IGDFConfig(keep_fraction=1.5)
    with pytest.raises(InputError, match="epsilon"):
        OTDFConfig(epsilon=0.0)
