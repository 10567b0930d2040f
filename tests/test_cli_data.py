"""``xted data info | convert | list`` through the real CLI entry point."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from xted.cli.main import main
from xted.data import save, shipped

INFO_KEYS = {
    "format", "path", "episodes", "transitions", "observation_dim", "action_dim", "return_mean",
    "return_std", "return_min", "return_max", "episode_length_mean", "terminals", "timeouts",
    "extras", "metadata", "normalized_score",
}


@pytest.fixture(autouse=True)
def minari_root(tmp_path, monkeypatch):
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "minari-root"))


def _info(capsys, source) -> dict:
    capsys.readouterr()
    assert main(["data", "info", str(source), "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_info_json(tmp_path, capsys, tiny_dataset):
    save(tiny_dataset, tmp_path / "tiny.npz")
    info = _info(capsys, tmp_path / "tiny.npz")
    assert INFO_KEYS <= set(info)
    returns = tiny_dataset.episode_returns()
    assert (info["format"], info["path"]) == ("npz", str(tmp_path / "tiny.npz"))
    sizes = (info["episodes"], info["transitions"], info["observation_dim"], info["action_dim"])
    assert sizes == (3, 13, 3, 2)
    assert info["return_mean"] == pytest.approx(returns.mean())
    assert info["return_std"] == pytest.approx(returns.std())
    assert (info["return_min"], info["return_max"]) == pytest.approx((returns.min(), returns.max()))
    assert info["episode_length_mean"] == pytest.approx(13 / 3)
    assert (info["terminals"], info["timeouts"]) == (1, 2)
    assert info["extras"] == ["qpos", "sim/contact", "step"]
    assert info["metadata"] == tiny_dataset.metadata and info["normalized_score"] == 12.5


def test_info_readable(tmp_path, capsys, tiny_dataset):
    save(tiny_dataset, tmp_path / "tiny.hdf5")
    assert main(["data", "info", str(tmp_path / "tiny.hdf5")]) == 0
    out = capsys.readouterr().out
    assert "(hdf5)" in out and "transitions:       13" in out and "1 terminals, 2 timeouts" in out


FORMATS = {"npz": "d.npz", "hdf5": "d.hdf5", "minari": "d-minari-v0", "minari-id": "minari:cli/d-v0"}


@pytest.mark.parametrize("src", FORMATS)
def test_convert_between_all_formats(tmp_path, capsys, tiny_dataset, src):
    def where(kind):
        name = FORMATS[kind]
        return name if name.startswith("minari:") else str(tmp_path / name)

    save(tiny_dataset, where(src))
    expected = _info(capsys, where(src))
    for dst in FORMATS:
        if dst == src:
            continue
        assert main(["data", "convert", where(src), where(dst)]) == 0
        assert "wrote 13 transitions (3 episodes)" in capsys.readouterr().out
        info = _info(capsys, where(dst))
        assert {k: v for k, v in info.items() if k not in ("format", "path")} == {
            k: v for k, v in expected.items() if k not in ("format", "path")
        }


def test_convert_needs_force_to_replace(tmp_path, capsys, tiny_dataset):
    save(tiny_dataset, tmp_path / "a.npz")
    save(tiny_dataset.select_episodes([0]), tmp_path / "b.hdf5")
    assert main(["data", "convert", str(tmp_path / "a.npz"), str(tmp_path / "b.hdf5")]) == 2
    assert "exists" in capsys.readouterr().err
    assert main(["data", "convert", str(tmp_path / "a.npz"), str(tmp_path / "b.hdf5"), "--force"]) == 0
    assert _info(capsys, tmp_path / "b.hdf5")["transitions"] == 13


def _npz(path, dataset, **changes):
    arrays = {k: getattr(dataset, k) for k in ("observations", "actions", "rewards", "terminals", "timeouts")}
    arrays.update(changes)
    np.savez(path, **{k: v for k, v in arrays.items() if v is not None})


def _nan(dataset):
    observations = dataset.observations.copy()
    observations[2, 1] = np.nan
    return observations


def _inf(dataset):
    rewards = dataset.rewards.copy()
    rewards[5] = -np.inf
    return rewards


_EMPTY = {"observations": np.zeros((0, 3)), "actions": np.zeros((0, 2)), "rewards": np.zeros(0),
          "terminals": np.zeros(0), "timeouts": np.zeros(0)}


def _truncated_hdf5(path, dataset):
    save(dataset, path)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 3])


BAD_INPUTS = {
    "missing-key": ("x.npz", lambda p, d: _npz(p, d, actions=None), "missing required key 'actions'"),
    "wrong-dims": ("x.npz", lambda p, d: _npz(p, d, observations=d.rewards), "observations must be 2-D"),
    "nan": ("x.npz", lambda p, d: _npz(p, d, observations=_nan(d)), "observations[2, 1] is nan"),
    "inf": ("x.npz", lambda p, d: _npz(p, d, rewards=_inf(d)), "rewards[5] is -inf"),
    "empty": ("x.npz", lambda p, d: _npz(p, d, **_EMPTY), "empty dataset"),
    "truncated-hdf5": ("x.hdf5", _truncated_hdf5, "not a readable HDF5 file"),
    "unknown-extension": ("x.csv", lambda p, d: p.write_text("1,2,3"), "unknown extension '.csv'"),
}


@pytest.mark.parametrize("case", BAD_INPUTS)
def test_bad_input_exits_2_with_one_message_and_no_output(tmp_path, capsys, tiny_dataset, case):
    name, make, message = BAD_INPUTS[case]
    (tmp_path / "in").mkdir()
    (tmp_path / "out").mkdir()
    source = tmp_path / "in" / name
    make(source, tiny_dataset)
    for command in (["info", str(source)], ["convert", str(source), str(tmp_path / "out" / "y.hdf5")]):
        capsys.readouterr()
        assert main(["data", *command]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("xted: error: ") and message in err[0], err
        assert name in err[0]
    assert not list((tmp_path / "out").iterdir())
    assert [p.name for p in (tmp_path / "in").iterdir()] == [name]


@pytest.mark.parametrize("dst", ["x.npz", "./x.npz"])
def test_convert_refuses_output_equal_to_input(tmp_path, capsys, tiny_dataset, monkeypatch, dst):
    monkeypatch.chdir(tmp_path)
    save(tiny_dataset, tmp_path / "x.npz")
    before = (tmp_path / "x.npz").read_bytes()
    assert main(["data", "convert", str(tmp_path / "x.npz"), dst, "--force"]) == 2
    assert "is the source input" in capsys.readouterr().err
    assert (tmp_path / "x.npz").read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["x.npz"]


def test_list(capsys, monkeypatch):
    monkeypatch.setattr(shipped, "manifest", lambda: {"datasets": {}, "checkpoints": {}})
    assert main(["data", "list"]) == 0
    assert "no shipped datasets" in capsys.readouterr().out
    entry = {"file": "toy.npz", "transitions": 20000, "normalized_score": 41.2}
    monkeypatch.setattr(shipped, "manifest", lambda: {"datasets": {"toy-medium": entry, "walker2d-medium": entry}})
    assert main(["data", "list"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert "toy-medium" in out[0] and "transitions=20000" in out[0] and "normalized_score=41.2 file" in out[0]
    assert "normalized_score=41.2 (D4RL's: 62) file" in out[1]
    assert main(["data", "list", "--json"]) == 0
    assert json.loads(capsys.readouterr().out) == {"toy-medium": entry,
                                                   "walker2d-medium": {**entry, "d4rl_normalized_score": 62.0}}


@pytest.mark.parametrize("command", [[], ["info"], ["convert"], ["list"]])
def test_help(capsys, command):
    assert main(["data", *command, "--help"]) == 0
    assert "Usage" in capsys.readouterr().out


def test_usage_error_exits_2(capsys):
    assert main(["data", "info"]) == 2
    assert main(["data", "convert", "only-one"]) == 2


def test_real_process_exit_codes(tmp_path, tiny_dataset):
    save(tiny_dataset, tmp_path / "ok.h5")
    def run(*args: str) -> subprocess.CompletedProcess:
        command = [sys.executable, "-m", "xted.cli.main", "data", *args]
        return subprocess.run(command, capture_output=True, text=True, timeout=60)

    ok, bad = run("info", str(tmp_path / "ok.h5"), "--json"), run("info", str(tmp_path / "missing.h5"))
    assert ok.returncode == 0 and json.loads(ok.stdout)["transitions"] == 13
    assert bad.returncode == 2 and bad.stderr.startswith("xted: error: ") and "no such file" in bad.stderr


def test_version(capsys):
    import xted

    assert main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"xted {xted.__version__}"
