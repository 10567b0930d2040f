"""A user's own step function: named on the command line, measuring data as a simulator replay does,
and projecting an edit."""

from __future__ import annotations

import json

import numpy as np
import pytest

from xted.cli.main import main
from xted.data import Dataset, save
from xted.envs.step_function import is_step_function_spec, load_step_function, step_function_error
from xted.errors import InputError

STEP_FILE = '''
import numpy as np


def step(observations, actions):
    return 0.9 * observations + 0.1 * np.concatenate([actions, actions[:, :1]], axis=1)


def wrong_shape(observations, actions):
    return observations[:, :2]
'''


def _step(observations, actions):
    return 0.9 * observations + 0.1 * np.concatenate([actions, actions[:, :1]], axis=1)


def _data(noise: float, seed: int = 0) -> Dataset:
    rng = np.random.default_rng(seed)
    observations = rng.normal(size=(40, 3)).astype(np.float32)
    actions = rng.uniform(-1, 1, size=(40, 2)).astype(np.float32)
    next_observations = _step(observations, actions) + noise * rng.normal(size=(40, 3))
    return Dataset(observations=observations, actions=actions, rewards=np.zeros(40, np.float32),
                   timeouts=np.arange(40) % 20 == 19, next_observations=next_observations.astype(np.float32))


@pytest.fixture
def step_file(tmp_path):
    path = tmp_path / "my_robot.py"
    path.write_text(STEP_FILE)
    return path


@pytest.mark.parametrize("text, expected", [("my_robot:step", True), ("pkg.sub:step_fn", True),
                                            ("robots/my_robot.py:step", True), ("minari:hop/test-v0", False),
                                            ("minari:xted/tiny-v0", False), ("halfcheetah", False),
                                            ("Hopper-v5", False), ("thigh=3", False)])
def test_a_step_function_is_told_from_envs_and_datasets(text, expected):
    assert is_step_function_spec(text) is expected


def test_step_function_from_a_file_measures_data_as_a_replay(step_file):
    step = load_step_function(f"{step_file}:step")
    assert step_function_error(step, _data(0.0)).mae < 1e-6
    assert step_function_error(step, _data(0.5)).mae == pytest.approx(0.5 * np.sqrt(2 / np.pi), rel=0.3)
    with pytest.raises(InputError, match=r"returned shape \(40, 2\)"):
        step_function_error(load_step_function(f"{step_file}:wrong_shape"), _data(0.0))


@pytest.mark.parametrize("spec, needle", [("no/such/file.py:step", "no file"), ("xted_no_such_module:step", "cannot import"),
                                          ("numpy:no_such_function", "has no function"), ("not a spec", "module:function")])
def test_a_bad_step_function_is_refused(spec, needle):
    with pytest.raises(InputError, match=needle):
        load_step_function(spec)


def test_measure_edit_takes_a_step_function_and_a_velocity_column():
    from xted.api import measure_edit

    source, edited = _data(0.0), _data(0.3)
    report = measure_edit(source, edited, env=_step, velocity_index=0)
    assert report["simulator"]["source"]["mae"] < 1e-6 < 0.1 < report["simulator"]["edited"]["mae"]
    assert report["simulator"]["edited"]["reward_mae"] is None
    assert "forward_velocity_corr" in json.dumps(report["content"])
    assert "forward_velocity_corr" not in json.dumps(measure_edit(source, edited)["content"])


def test_analyze_dynamics_with_a_step_function(step_file, tmp_path, capsys):
    save(_data(0.0), tmp_path / "exact.npz")
    save(_data(0.5), tmp_path / "noisy.npz")
    args = ["analyze", "dynamics", str(tmp_path / "exact.npz"), str(tmp_path / "noisy.npz"), "--env", f"{step_file}:step"]
    assert main([*args, "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)["datasets"]
    assert rows[0]["mae"] < 1e-6 < 0.1 < rows[1]["mae"] and rows[0]["reward"] is None
    assert main(args) == 0
    assert "rew MAE" in capsys.readouterr().out
    assert main([*args, "--gap", "gravity"]) == 2
    assert "--gap" in capsys.readouterr().err


def test_analyze_content_takes_the_velocity_column(tmp_path, capsys):
    save(_data(0.0), tmp_path / "source.npz")
    save(_data(0.3), tmp_path / "edited.npz")
    args = ["analyze", "content", str(tmp_path / "source.npz"), str(tmp_path / "edited.npz"), "--json"]
    assert main([*args, "--velocity-index", "2"]) == 0
    assert "forward_velocity_correlation" in json.loads(capsys.readouterr().out)["matched"]
    assert main(args) == 0
    assert "forward_velocity_correlation" not in json.loads(capsys.readouterr().out)["matched"]
    assert main([*args, "--velocity-index", "7"]) == 2
    assert "outside the 3-d observations" in capsys.readouterr().err
