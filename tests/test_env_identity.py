"""Data of another env is refused by name (edit, policy) unless the user allows it."""

import h5py
import pytest

from xted.cli.main import main
from xted.data import load, save
from xted.data.shipped import prior_dir
from xted.envs import check_same_env, dataset_env
from xted.errors import InputError


@pytest.mark.parametrize("metadata, env", [
    ({"env": "halfcheetah"}, "halfcheetah"), ({"env": "HalfCheetah-v5"}, "halfcheetah"),
    ({"env_name": "halfcheetah-medium-v2"}, "halfcheetah"), ({"env_name": "Walker2d-v5"}, "walker2d"),
    ({"env": "Hopper-v5"}, "hopper"), ({"env": "Ant-v5"}, "ant"), ({"env": "Humanoid-v5"}, "Humanoid-v5"),
    ({}, None), ({"env": ""}, None),
])
def test_dataset_env_reads_ours_d4rls_and_minaris_names(metadata, env):
    assert dataset_env(metadata) == env


def test_check_same_env_allows_unknown_and_names_both():
    check_same_env("halfcheetah", None, "x")
    check_same_env(None, "walker2d", "x")
    check_same_env("halfcheetah", "walker2d", "x", allow_mismatch=True)
    with pytest.raises(InputError, match="'walker2d', not 'halfcheetah'"):
        check_same_env("halfcheetah", "walker2d", "--source x")


@pytest.fixture(scope="module")
def walker_labelled(tmp_path_factory):
    """Halfcheetah-shaped data (same dims as walker2d) in a D4RL file whose attributes say walker2d."""
    data = load("halfcheetah-gravity").select_episodes([0])
    path = tmp_path_factory.mktemp("d4rl") / "walker.hdf5"
    with h5py.File(path, "w") as f:
        for name in ("observations", "actions", "rewards", "terminals", "timeouts", "next_observations"):
            f[name] = getattr(data, name)
        f.attrs["env_name"] = "Walker2d-v5"
    return path


def test_edit_refuses_a_source_of_another_env(walker_labelled, tmp_path, capsys):
    out = tmp_path / "edited.npz"
    args = ["edit", "--prior", str(prior_dir("halfcheetah-medium-replay-cpu")), "--source", str(walker_labelled),
            "--out", str(out)]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "walker2d" in err and "halfcheetah" in err and "--allow-env-mismatch" in err
    assert not out.exists()


def test_policy_refuses_data_of_another_env_unless_allowed(walker_labelled, capsys):
    args = ["policy", "--algo", "bc", "--target", str(walker_labelled), "--env", "halfcheetah", "--steps", "2",
            "--eval-episodes", "1", "--eval-every", "2"]
    assert main(args) == 2 and "walker2d" in capsys.readouterr().err
    assert main([*args, "--allow-env-mismatch"]) == 0


def test_unlabelled_data_stays_allowed(tmp_path, capsys):
    data = load("halfcheetah-gravity").select_episodes([0])
    save(data.with_metadata(env=None, domain=None, gap=None), tmp_path / "plain.npz")
    assert dataset_env(load(tmp_path / "plain.npz").metadata) is None
    assert main(["policy", "--algo", "bc", "--target", str(tmp_path / "plain.npz"), "--env", "walker2d",
                 "--steps", "2", "--eval-episodes", "1", "--eval-every", "2"]) == 0
    assert "bc in walker2d" in capsys.readouterr().out
