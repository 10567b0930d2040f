"""xted render: headless frames, the root x put back from the velocity, videos and bad input."""

import gymnasium as gym
import imageio.v3 as iio
import mujoco
import numpy as np
import pytest
from conftest import first_steps

from xted.cli.main import main
from xted.data import Dataset, save
from xted.envs import make, parse_domain, simulator
from xted.errors import InputError
from xted.viz import gl
from xted.viz.episode import episode_states, root_positions, set_state
from xted.viz.offscreen import OffscreenRenderer
from xted.viz.state_names import state_names


@pytest.fixture(scope="module")
def headless_gl():
    """Drawing needs EGL or OSMesa; a machine with neither gets the clear error, tested below."""
    try:
        gl.gl_context_class()
    except InputError as err:
        pytest.skip(f"this machine offers no headless OpenGL: {err}")


@pytest.mark.parametrize("env", ["halfcheetah", "walker2d"])
def test_frames_are_drawn_and_change_with_the_state(env, headless_gl):
    model, frame_skip = simulator(parse_domain(env))
    observations = first_steps(f"{env}-medium", 40, 1).observations[[0, 20, 39]]
    qpos, qvel = episode_states(model, observations, model.opt.timestep * frame_skip)
    data = mujoco.MjData(model)
    frames = []
    with OffscreenRenderer(model, 64, 48) as renderer:
        for t in range(len(observations)):
            set_state(model, data, qpos[t], qvel[t])
            frames.append(renderer.render(data).astype(float))
    for frame in frames:
        assert frame.shape == (48, 64, 3)
        assert frame.std() > 10, "a blank frame"
    assert np.abs(frames[0] - frames[1]).mean() > 1 and np.abs(frames[1] - frames[2]).mean() > 1


def test_the_floor_is_drawn_under_a_body_far_from_the_start(headless_gl):
    """The envs' floor ends 40 m out; a runner passes that in half a minute."""
    model, _ = simulator(parse_domain("halfcheetah"))
    data = mujoco.MjData(model)
    bottoms = []
    with OffscreenRenderer(model, 64, 48) as renderer:
        for x in (0.0, 500.0):
            set_state(model, data, np.r_[x, np.zeros(model.nq - 1)], np.zeros(model.nv))
            bottoms.append(renderer.render(data)[36:].astype(float))
    assert bottoms[0].std() > 30 and bottoms[1].std() > 30, "the checker floor should fill the bottom of the frame"


def test_root_positions_integrate_the_velocity_by_the_trapezoid_rule():
    np.testing.assert_allclose(root_positions(np.full(5, 2.0), 0.05), [0.0, 0.1, 0.2, 0.3, 0.4], atol=1e-12)
    np.testing.assert_allclose(root_positions(np.array([0.0, 2.0, 2.0]), 0.5), [0.0, 0.5, 1.5], atol=1e-12)


def test_the_reconstructed_root_x_follows_the_simulator():
    """100 steps of random actions in the target env: observations and the true x.

    Not to float precision: the simulator takes five substeps per env step, whose velocities an
    observation does not hold. Measured: 2.8 cm at most over 1.47 m; integrating the end-of-step
    velocity alone (the rule one would write first) is off by 5.0 cm, and the substep's time step
    instead of the env's by 1.2 m."""
    env = gym.make("HalfCheetah-v5")
    observation, _ = env.reset(seed=0)
    actions = np.random.default_rng(0).uniform(-1, 1, size=(100, 6))
    observations, true_x = [observation], [env.unwrapped.data.qpos[0]]
    for action in actions:
        observation, *_ = env.step(action)
        observations.append(observation)
        true_x.append(env.unwrapped.data.qpos[0])
    env.close()
    observations, true_x = np.array(observations), np.array(true_x)
    qpos, qvel = episode_states(env.unwrapped.model, observations, env.unwrapped.dt)
    np.testing.assert_array_equal(qpos[:, 1:], observations[:, :8])
    np.testing.assert_array_equal(qvel, observations[:, 8:])
    assert abs(true_x[-1] - true_x[0]) > 0.5, "the body should travel"
    assert np.abs(qpos[:, 0] + true_x[0] - true_x).max() < 0.04


def test_the_reconstructed_ant_root_follows_the_simulator_in_x_and_y():
    """Ant observes neither x nor y; both come back from the velocities (world-frame for its free joint)."""
    env = make("ant")
    observation, _ = env.reset(seed=0)
    observations, true_xy = [observation], [env.unwrapped.data.qpos[:2].copy()]
    for action in np.random.default_rng(0).uniform(-1, 1, size=(60, 8)):
        observation, *_ = env.step(action)
        observations.append(observation)
        true_xy.append(env.unwrapped.data.qpos[:2].copy())
    model, dt = env.unwrapped.model, env.unwrapped.dt
    env.close()
    qpos, qvel = episode_states(model, np.array(observations), dt)
    travelled = np.array(true_xy) - true_xy[0]
    np.testing.assert_array_equal(qpos[:, 2:], np.array(observations)[:, :13])
    assert qvel.shape == (61, 14) and np.abs(travelled[-1]).max() > 0.05, "the body should travel"
    assert np.abs(qpos[:, :2] - travelled).max() < 0.05 * max(np.abs(travelled).max(), 1.0)


def test_state_names_follow_the_observation_layout():
    names = [name for name, _ in state_names(simulator(parse_domain("ant"))[0])]
    assert len(names) == 27 and names[0] == "root z position" and names[13] == "root x velocity"
    assert [name for name, _ in state_names(simulator(parse_domain("walker2d"))[0])][8] == "rootx velocity"


@pytest.fixture(scope="module")
def short_data(tmp_path_factory):
    folder = tmp_path_factory.mktemp("render")
    source, edited = first_steps("halfcheetah-thigh", 6), first_steps("halfcheetah-thigh", 6)
    edited = Dataset(observations=edited.observations + 0.05, actions=edited.actions, rewards=edited.rewards,
                     terminals=edited.terminals, timeouts=edited.timeouts)
    paths = str(folder / "source.npz"), str(folder / "edited.npz")
    save(source, paths[0])
    save(edited, paths[1])
    return paths


def test_render_side_by_side_mp4_and_gif(short_data, tmp_path, headless_gl):
    source, edited = short_data
    base = ["render", "--env", "halfcheetah", "--gap", "thigh", source, "--episode", "1", "--compare", edited,
            "--width", "96", "--height", "64"]
    assert main([*base, "--out", str(tmp_path / "side.mp4")]) == 0
    frames = list(iio.imiter(tmp_path / "side.mp4"))
    assert len(frames) == 6 and frames[0].shape == (64, 192, 3)
    assert main([*base, "--steps", "3", "--out", str(tmp_path / "side.gif")]) == 0
    gif = iio.imread(tmp_path / "side.gif", index=None)
    assert gif.shape[:3] == (3, 64, 192)
    assert main(["render", "--env", "halfcheetah", source, "--width", "96", "--height", "64", "--out",
                 str(tmp_path / "one.gif")]) == 0
    assert iio.imread(tmp_path / "one.gif", index=None).shape[:3] == (6, 64, 96)


@pytest.mark.parametrize("args, message", [
    (["--out", "{tmp}/video.avi"], "unknown video extension"),
    (["--episode", "2", "--out", "{tmp}/video.mp4"], "episode 2 is out of range"),
    (["--compare", "{tmp}/missing.npz", "--out", "{tmp}/video.mp4"], "missing.npz"),
    (["--compare", "halfcheetah-thigh", "--out", "{tmp}/video.mp4"], "must have the source's episodes"),
    (["--width", "100", "--out", "{tmp}/video.mp4"], "multiple of 16"),
])
def test_bad_input_exits_2_and_writes_nothing(short_data, tmp_path, capsys, args, message):
    args = [arg.replace("{tmp}", str(tmp_path)) for arg in args]
    assert main(["render", "--env", "halfcheetah", short_data[0], *args]) == 2
    assert message in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_a_missing_dataset_exits_2(tmp_path, capsys):
    assert main(["render", "--env", "halfcheetah", str(tmp_path / "nothing.npz"), "--out", str(tmp_path / "v.mp4")]) == 2
    assert "nothing.npz" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_no_headless_opengl_is_a_clear_input_error(monkeypatch):
    monkeypatch.delenv("MUJOCO_GL", raising=False)
    monkeypatch.setattr(gl, "probe", lambda backend: f"cannot open {backend}")
    gl.gl_context_class.cache_clear()
    try:
        with pytest.raises(InputError, match="no headless OpenGL.*egl: cannot open egl; osmesa: cannot open osmesa"):
            gl.gl_context_class()
        monkeypatch.setenv("MUJOCO_GL", "glfw")
        with pytest.raises(InputError, match="MUJOCO_GL=glfw"):
            gl.gl_context_class()
    finally:
        gl.gl_context_class.cache_clear()
