"""Schedule, denoiser and prior training (tiny configurations)."""

from __future__ import annotations

import csv
import dataclasses
import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from xted.data import Dataset
from xted.diffusion import (
    CROSS_WIRING,
    Denoiser,
    DenoiserConfig,
    EditConfig,
    PriorConfig,
    cosine_schedule,
    ddim_step,
    ddim_timesteps,
    ddpm_step,
    edit_dataset,
    load_prior,
    make_train_step,
    preset,
    q_sample,
    train_prior_folder,
)
from xted.diffusion.config import LOSS_WEIGHTINGS
from xted.diffusion.objective import LOSS_WEIGHTS
from xted.diffusion.objective import ema_decay, init_train_state, loss_fn
from xted.errors import InputError

TINY = PriorConfig(
    state_dim=3, action_dim=2, width_override=8, state_blocks=1, action_blocks=1, reward_blocks=1,
    num_heads=2, cond_dim=16, horizon=4, num_timesteps=10, batch_size=16, learning_rate=3e-3, return_condition=True,
)  # one config for all training tests: the train step compiles once


def random_params(shapes, scale: float = 0.3, seed: int = 1):
    """Random parameters of the given shapes (NumPy: no compilation), so every gate is active."""
    rng = np.random.default_rng(seed)
    return jax.tree.map(lambda x: (scale * rng.normal(size=x.shape)).astype(x.dtype), shapes)


def smooth_dataset(episodes: int = 6, length: int = 30, seed: int = 0) -> Dataset:
    """Sinusoidal trajectories: learnable structure for a tiny model."""
    rng = np.random.default_rng(seed)
    t = np.arange(length)[:, None]
    obs, act = [], []
    for _ in range(episodes):
        phase = rng.uniform(0, 2 * np.pi, size=3)
        obs.append(np.sin(0.3 * t + phase))
        act.append(np.cos(0.3 * t + phase[:2]))
    obs, act = np.concatenate(obs), np.concatenate(act)
    ends = np.zeros(len(obs), bool)
    ends[length - 1 :: length] = True
    return Dataset(
        observations=obs, actions=act, rewards=obs[:, 0] + act[:, 0], terminals=np.zeros_like(ends),
        timeouts=ends, next_observations=np.roll(obs, -1, axis=0),
    )


# ----------------------------------------------------------------------------------- schedule
def test_schedule_sanity():
    s = cosine_schedule(200)
    abar = np.asarray(s.alphas_cumprod)
    assert s.num_timesteps == 200
    assert np.all(np.diff(abar) < 0) and 0.99 < abar[0] < 1 and abar[-1] < 1e-3
    assert np.all(np.asarray(s.betas) <= 0.999)
    x0 = jnp.linspace(-2, 2, 12).reshape(2, 3, 2)
    noise = jax.random.normal(jax.random.key(0), x0.shape)
    np.testing.assert_allclose(q_sample(s, x0, jnp.zeros(2, int), noise), x0, atol=0.05)
    t = jnp.array([150, 150])
    x_t = q_sample(s, x0, t, noise)
    # With the true noise, DDIM to t_prev = -1 recovers x0; a DDPM step at t = 0 adds no noise.
    np.testing.assert_allclose(ddim_step(s, x_t, t, jnp.array([-1, -1]), noise), x0, atol=1e-4)
    zero = jnp.zeros(2, int)
    np.testing.assert_array_equal(ddpm_step(s, x0, zero, noise, noise), ddpm_step(s, x0, zero, noise, 5 * noise))
    clipped = ddpm_step(s, x_t, t, -noise * 50, jnp.zeros_like(x0), clip=1.0)
    assert np.all(np.isfinite(clipped))


def test_temperature_scales_the_noise_a_step_adds_and_ddim_at_eta_one_is_ddpm():
    s = cosine_schedule(200)
    x_t = jax.random.normal(jax.random.key(1), (2, 3, 2))
    eps = jax.random.normal(jax.random.key(2), x_t.shape)
    noise = jax.random.normal(jax.random.key(3), x_t.shape)
    t = jnp.array([80, 80])
    mean = ddpm_step(s, x_t, t, eps, jnp.zeros_like(noise))
    for temperature in (0.0, 0.5, 1.0):
        np.testing.assert_allclose(ddpm_step(s, x_t, t, eps, noise, temperature=temperature) - mean,
                                   temperature * (ddpm_step(s, x_t, t, eps, noise) - mean), atol=1e-5)
        # One DDIM step of eta = 1 between consecutive timesteps is the DDPM posterior (Song et al. 2021, Eq. 16).
        np.testing.assert_allclose(ddim_step(s, x_t, t, t - 1, eps, eta=1.0, noise=noise, temperature=temperature),
                                   ddpm_step(s, x_t, t, eps, noise, temperature=temperature), atol=1e-5)
    np.testing.assert_allclose(ddim_step(s, x_t, t, t - 1, eps, eta=0.0, noise=noise), ddim_step(s, x_t, t, t - 1, eps))


def test_ddim_timesteps():
    np.testing.assert_array_equal(ddim_timesteps(5, 5), [4, 3, 2, 1, 0])
    seq = ddim_timesteps(100, 10)
    assert seq[0] == 99 and seq[-1] == 0 and len(seq) == 10 and np.all(np.diff(seq) < 0)
    np.testing.assert_array_equal(ddim_timesteps(7, 1), [6])
    with pytest.raises(InputError):
        ddim_timesteps(5, 6)


# ----------------------------------------------------------------------------------- denoiser
def _inputs(cfg: DenoiserConfig, b: int = 2, h: int | None = None, seed: int = 0):
    h = h or cfg.horizon
    k1, k2, k3 = jax.random.split(jax.random.key(seed), 3)
    s = jax.random.normal(k1, (b, h, cfg.state_dim))
    a = jax.random.normal(k2, (b, h, cfg.action_dim))
    r = jax.random.normal(k3, (b, h, 1)) if cfg.use_reward else None
    return s, a, r, jnp.array([0, 7])[:b], jnp.full((b,), 0.5)


@pytest.fixture(scope="module")
def tiny_model():
    """The TINY return-conditioned denoiser, its inputs and (untrained) parameters."""
    cfg = TINY.denoiser
    model = Denoiser(cfg)
    inputs = _inputs(cfg) + (jnp.array([True, False]),)
    return jax.jit(model.apply), inputs, init_train_state(TINY, jax.random.key(0)).params


def test_denoiser_shapes_and_zero_init(tiny_model):
    apply, inputs, params = tiny_model
    s, a, r = inputs[:3]
    eps = apply(params, *inputs)
    for e, x in zip(eps, (s, a, r)):
        assert e.shape == x.shape
        np.testing.assert_array_equal(e, 0.0)  # adaLN-Zero / zero decoder: untrained model predicts 0
    assert {"state_encoder", "action_encoder", "reward_encoder", "condition"} <= set(params["params"])


def test_high_dimensional_states_reward_free():
    cfg = DenoiserConfig(state_dim=1024, action_dim=7, use_reward=False, width_override=16, horizon=5,
                         state_blocks=1, action_blocks=1, cond_dim=16)
    model = Denoiser(cfg)
    s, a, r, t, _ = _inputs(cfg)
    assert r is None
    shapes = jax.eval_shape(model.init, jax.random.key(0), s, a, None, t)
    assert "reward_encoder" not in shapes["params"] and "reward_cross" not in shapes["params"]
    eps_s, eps_a, eps_r = jax.jit(model.apply)(random_params(shapes, 0.05), s, a, None, t)
    assert eps_s.shape == (2, 5, 1024) and eps_a.shape == (2, 5, 7) and eps_r is None
    assert np.all(np.isfinite(eps_s)) and not np.allclose(eps_s, 0.0)


def test_width_and_heads():
    cfg = DenoiserConfig(state_dim=17, action_dim=6)
    assert [cfg.width(s) for s in cfg.streams] == [272, 96, 16]
    assert [cfg.heads(s) for s in cfg.streams] == [4, 4, 4]
    odd = DenoiserConfig(state_dim=3, action_dim=1, width_multiplier=2, min_width=5, num_heads=4)
    assert (odd.width("state"), odd.heads("state")) == (6, 2)
    assert (odd.width("reward"), odd.heads("reward")) == (5, 1)


def test_cross_wiring(tiny_model):
    assert CROSS_WIRING == (("state", ("action",)), ("action", ("state",)), ("reward", ("state", "action")))
    jitted, (s, a, r, *rest), params = tiny_model
    params = random_params(params)
    apply = lambda s, a, r: jitted(params, s, a, r, *rest)  # noqa: E731
    base = apply(s, a, r)
    bump = lambda x: x.at[:, 1:].add(1.0)  # noqa: E731
    out_r, out_a, out_s = apply(s, a, bump(r)), apply(s, bump(a), r), apply(bump(s), a, r)
    # Rewards never feed back into states or actions.
    np.testing.assert_array_equal(out_r[0], base[0])
    np.testing.assert_array_equal(out_r[1], base[1])
    assert not np.allclose(out_r[2], base[2])
    # State and action inform each other; the reward stream draws on both.
    assert not np.allclose(out_a[0], base[0]) and not np.allclose(out_s[1], base[1])
    assert not np.allclose(out_a[2], base[2]) and not np.allclose(out_s[2], base[2])
    # Reward-free models have no reward block at all.
    assert dataclasses.replace(TINY.denoiser, use_reward=False).cross_wiring == CROSS_WIRING[:2]


def test_more_cross_rounds_add_blocks_after_the_first_and_keep_rewards_out_of_states_and_actions():
    cfg = dataclasses.replace(TINY.denoiser, cross_blocks=2)
    model = Denoiser(cfg)
    s, a, r, t, returns = _inputs(cfg)
    shapes = jax.eval_shape(model.init, jax.random.key(0), s, a, r, t, returns)["params"]
    one_round = jax.eval_shape(Denoiser(TINY.denoiser).init, jax.random.key(0), s, a, r, t, returns)["params"]
    assert set(shapes) - set(one_round) == {"state_cross_1", "action_cross_1", "reward_cross_1"}
    # the first round keeps its names, so a one-round prior's parameters are a subtree of these
    assert jax.tree.structure(shapes["state_cross"]) == jax.tree.structure(one_round["state_cross"])
    params = random_params({"params": shapes})
    apply = jax.jit(lambda s, a, r: model.apply(params, s, a, r, t, returns))
    base, bumped = apply(s, a, r), apply(s, a, r.at[:, 1:].add(1.0))
    np.testing.assert_array_equal(bumped[0], base[0])
    np.testing.assert_array_equal(bumped[1], base[1])
    assert not np.allclose(bumped[2], base[2])
    with pytest.raises(InputError, match="cross_blocks"):
        dataclasses.replace(TINY, cross_blocks=0)


@pytest.mark.parametrize("architecture", ["causal", "feature_concat", "temporal_concat", "temporal_unet"])
def test_ablation_architectures(architecture):
    cfg = dataclasses.replace(TINY.denoiser, architecture=architecture)
    model = Denoiser(cfg)
    s, a, r, t, returns = _inputs(cfg)
    shapes = jax.eval_shape(model.init, jax.random.key(0), s, a, r, t, returns)
    apply = jax.jit(lambda s, a, r: model.apply(random_params(shapes), s, a, r, t, returns))
    base = apply(s, a, r)
    assert [e.shape for e in base] == [s.shape, a.shape, r.shape]
    short = apply(s[:, :3], a[:, :3], r[:, :3])  # a window shorter than the horizon (odd: U-Net pads)
    assert [e.shape for e in short] == [s[:, :3].shape, a[:, :3].shape, r[:, :3].shape]
    late = apply(s.at[:, 2:].add(1.0), a.at[:, 2:].add(1.0), r.at[:, 2:].add(1.0))
    if architecture == "causal":  # steps 0-1 cannot see steps 2+, in any stream
        for before, after in zip(base, late):
            np.testing.assert_array_equal(before[:, :2], after[:, :2])
            assert not np.allclose(before[:, 2:], after[:, 2:])
    else:  # one sequence: every element sees every step, rewards included
        for before, after in zip(base, late):
            assert not np.allclose(before[:, :2], after[:, :2])
    with pytest.raises(InputError, match="architecture must be one of"):
        dataclasses.replace(TINY, architecture="unet")


# ----------------------------------------------------------------------------------- training
def test_presets():
    paper = preset("paper", 17, 6)
    assert (paper.width_multiplier, paper.state_blocks, paper.action_blocks, paper.reward_blocks) == (16, 2, 2, 1)
    assert (paper.horizon, paper.num_timesteps, paper.return_condition) == (20, 200, True)
    assert preset("cpu", 17, 6, seed=3).seed == 3
    with pytest.raises(InputError, match="unknown prior preset"):
        preset("huge", 17, 6)
    with pytest.raises(InputError, match="loss_weighting"):
        PriorConfig(state_dim=3, action_dim=2, loss_weighting="bogus")


def test_loss_weights():
    snr = jnp.array([0.5, 5.0, 20.0])
    np.testing.assert_allclose(LOSS_WEIGHTS["uniform"](snr), 1.0)
    np.testing.assert_allclose(LOSS_WEIGHTS["min_snr"](snr), [1.0, 1.0, 0.25])
    assert tuple(LOSS_WEIGHTS) == LOSS_WEIGHTINGS  # the names the config accepts are the weightings there are


@pytest.mark.slow
def test_train_kappa_max_draws_only_the_low_noise_levels():
    """Zero-initialised decoders predict no noise, so each sample's loss is its Min-SNR weight times
    the noise's square: the lowest level's weight alone, or the mean weight over every level."""
    batch = _sine_batch(256, TINY.horizon, seed=0)
    losses = {}
    for kappa_max in (0.1, 1.0):  # K = 10: noise step 0 only, or all ten
        config = dataclasses.replace(TINY, loss_weighting="min_snr", train_kappa_max=kappa_max)
        params = init_train_state(config, jax.random.key(0)).params
        losses[kappa_max] = float(loss_fn(params, batch, jax.random.key(1), model=Denoiser(config.denoiser),
                                          schedule=cosine_schedule(config.num_timesteps), config=config)[0])
    abar = np.asarray(cosine_schedule(TINY.num_timesteps).alphas_cumprod)
    weights = np.minimum(abar / (1 - abar), 5.0) / (abar / (1 - abar))
    assert losses[0.1] == pytest.approx(weights[0], rel=0.05)
    assert losses[1.0] == pytest.approx(weights.mean(), rel=0.15) and weights.mean() > 2 * weights[0]
    with pytest.raises(InputError, match="train_kappa_max"):
        dataclasses.replace(TINY, train_kappa_max=0.01)


def _sine_batch(b: int, h: int, seed: int) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.arange(h)[None, :, None]
    phase = rng.uniform(0, 6, size=(b, 1, 3))
    return {
        "state": np.sin(0.3 * t + phase).astype(np.float32),
        "action": np.cos(0.3 * t + phase[..., :2]).astype(np.float32),
        "reward": np.sin(0.3 * t + phase[..., :1]).astype(np.float32),
        "loss_mask": np.broadcast_to(np.arange(h) > 0, (b, h)),
        "returns": rng.uniform(size=b).astype(np.float32),
    }


@pytest.mark.slow
def test_loss_decreases():
    config = TINY
    state = init_train_state(config, jax.random.key(0))
    step = make_train_step(config)
    key = jax.random.key(1)
    held_out = [_sine_batch(config.batch_size, config.horizon, seed=1000 + i) for i in range(4)]

    def held_out_loss(state) -> float:
        # The step's loss is computed before its update; at step 0 the noise is the same for every state.
        return float(np.mean([step(state.replace(step=jnp.zeros((), jnp.int32)), b, key)[1]["loss"] for b in held_out]))

    before = held_out_loss(state)
    for i in range(50):
        state, metrics = step(state, _sine_batch(config.batch_size, config.horizon, seed=i), key)
    assert np.isfinite(float(metrics["loss"]))
    assert int(state.step) == 50
    assert held_out_loss(state) < 0.8 * before


def test_the_ema_is_warmed_up_so_a_short_run_edits_with_trained_weights():
    """After 50 steps the EMA holds little of the random initial weights (a fixed 0.999 would keep 95%)."""
    config = TINY
    state = init_train_state(config, jax.random.key(0))
    initial = state.params
    step = make_train_step(config)
    for i in range(50):
        state, _ = step(state, _sine_batch(config.batch_size, config.horizon, seed=i), jax.random.key(1))

    def distance(a, b):
        return float(sum(jnp.sum((x - y) ** 2) for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b))) ** 0.5)

    assert distance(state.ema_params, state.params) < 0.5 * distance(state.ema_params, initial)
    assert float(ema_decay(0.999, jnp.asarray(0))) == pytest.approx(0.1)
    assert float(ema_decay(0.999, jnp.asarray(100_000))) == pytest.approx(0.999)


@pytest.mark.slow
def test_inverse_dynamics_prior_learns_its_inverse_models():
    config = dataclasses.replace(TINY, architecture="inverse_dynamics")
    state = init_train_state(config, jax.random.key(0))
    step = make_train_step(config)
    key = jax.random.key(1)
    history = []
    for i in range(150):
        state, metrics = step(state, _sine_batch(config.batch_size, config.horizon, seed=i), key)
        history.append(metrics)
    for name in ("mse_state", "mse_action", "mse_reward"):
        values = np.array([float(m[name]) for m in history])
        assert values[-10:].mean() < 0.8 * values[:10].mean(), name
    eps = Denoiser(config.denoiser).apply(state.params, *(_sine_batch(2, config.horizon, seed=0)[s]
                                                          for s in ("state", "action", "reward")),
                                          jnp.zeros(2, jnp.int32), None)
    assert eps[0].shape == (2, config.horizon, 3) and eps[1] is None and eps[2] is None


def _flat(tree) -> np.ndarray:
    return np.concatenate([np.ravel(x) for x in jax.tree.leaves(tree)])


@pytest.mark.slow
def test_train_prior_resume_and_refuse(tmp_path):
    data = smooth_dataset()
    config = TINY
    kw = dict(progress=False, log_every=5, checkpoint_every=5)
    train_prior_folder(data, tmp_path / "a", config, steps=10, **kw)
    train_prior_folder(data, tmp_path / "a", config, steps=20, **kw)  # resumes from step 10
    train_prior_folder(data, tmp_path / "b", config, steps=20, **kw)
    a, b = load_prior(tmp_path / "a"), load_prior(tmp_path / "b")
    assert a.step == b.step == 20 and a.config == config
    np.testing.assert_allclose(_flat(a.params), _flat(b.params), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(a.normalizer.mean["observations"], data.observations.mean(0), atol=1e-5)
    lo, hi = a.return_range
    assert lo < hi
    edited, report = edit_dataset(a, data, EditConfig(batch_size=8))  # the loaded prior edits
    assert len(edited) == len(data) and report["windows"] == 6 * 10
    assert edited.metadata["edit"]["prior"] == str((tmp_path / "a").resolve())
    with (tmp_path / "a" / "log.csv").open() as f:
        assert [int(r["step"]) for r in csv.DictReader(f)] == [5, 10, 15, 20]
    with pytest.raises(InputError, match=r"config.learning_rate: 0.003 -> 0.0001"):
        train_prior_folder(data, tmp_path / "a", dataclasses.replace(config, learning_rate=1e-4), steps=30, **kw)
    # A prior.json written before a field existed resumes: the missing field takes its default.
    meta = json.loads((tmp_path / "a" / "prior.json").read_text())
    del meta["config"]["architecture"]
    (tmp_path / "a" / "prior.json").write_text(json.dumps(meta))
    train_prior_folder(data, tmp_path / "a", config, steps=25, **kw)
    assert load_prior(tmp_path / "a").step == 25
    with pytest.raises(InputError, match="no prior folder or shipped prior of that name"):
        load_prior(tmp_path / "missing")
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="no prior.json"):
        load_prior(tmp_path / "empty")
