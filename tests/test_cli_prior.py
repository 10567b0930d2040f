import json

import jax
import numpy as np
import pytest
from conftest import build_dataset

from xted.cli.main import main
from xted.data import load, save
from xted.diffusion.prior import export_prior, load_prior

TINY = ["--set", "width_override=8", "--set", "state_blocks=1", "--set", "action_blocks=1", "--set", "cond_dim=16",
        "--set", "horizon=5", "--set", "batch_size=8", "--set", "num_timesteps=10", "--set", "warmup_steps=0"]


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("prior")
    target = build_dataset(lengths=(12, 9, 15), obs_dim=3, act_dim=2, seed=0)
    source = build_dataset(lengths=(10, 8), obs_dim=3, act_dim=2, seed=1)
    save(target, folder / "target.npz")
    save(source, folder / "source.hdf5")
    rc = main(["train", "--target", str(folder / "target.npz"), "--out", str(folder / "prior"), "--steps", "4",
               "--checkpoint-every", "2", *TINY])
    assert rc == 0
    return folder


def test_train_writes_config_log_and_checkpoints(files):
    meta = json.loads((files / "prior" / "prior.json").read_text())
    assert meta["config"]["width_override"] == 8 and meta["config"]["horizon"] == 5
    assert "normalizer" in meta
    assert load_prior(files / "prior").step == 4
    assert (files / "prior" / "log.csv").read_text().count("\n") >= 2


def test_rerunning_a_finished_train_says_so(files, capsys):
    args = ["train", "--target", str(files / "target.npz"), "--out", str(files / "prior"), "--checkpoint-every", "2",
            *TINY]
    assert main([*args, "--steps", "2"]) == 0
    assert "already trained to step 4" in capsys.readouterr().out
    assert load_prior(files / "prior").step == 4


def test_edit_cli_writes_the_named_format(files, capsys):
    out = files / "edited.npz"
    assert main(["edit", "--prior", str(files / "prior"), "--source", str(files / "source.hdf5"),
                 "--out", str(out), "--kappa", "0.5", "--seed", "3", "--no-guard", "--json"]) == 0
    report = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    edited, source = load(out), load(files / "source.hdf5")
    assert report["transitions"] == len(source) == len(edited)
    np.testing.assert_array_equal(edited.terminals, source.terminals)
    assert edited.metadata["edit"]["config"]["kappa"] == 0.5
    assert not np.array_equal(edited.observations, source.observations)
    assert main(["edit", "--prior", str(files / "prior"), "--source", str(files / "source.hdf5"),
                 "--out", str(files / "summarised.npz"), "--seed", "3", "--no-guard"]) == 0
    printed = capsys.readouterr().out  # for a person: one summary line, no JSON
    assert f"edited {len(source)} of {len(source)} transitions in " in printed and "{" not in printed


def test_edit_cli_projects_onto_a_user_step_function(files, tmp_path, capsys):
    """--project-dynamics file.py:function: with weight 1 every edited next state is the function's
    prediction from the state before it (here: the state itself)."""
    (tmp_path / "still.py").write_text("def step(observations, actions):\n    return observations\n")
    out = files / "projected.npz"
    assert main(["edit", "--prior", str(files / "prior"), "--source", str(files / "source.hdf5"), "--out", str(out),
                 "--kappa", "0.5", "--no-guard", "--dynamics-weight", "1.0",
                 "--project-dynamics", f"{tmp_path / 'still.py'}:step", "--json"]) == 0
    report = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert report["dynamics_projected"] and report["dynamics_projected_by_step_function"].endswith("still.py:step")
    edited, source = load(out), load(files / "source.hdf5")
    np.testing.assert_allclose(edited.next_observations, edited.observations, atol=1e-5)
    assert not np.allclose(source.next_observations, source.observations)


@pytest.mark.slow
def test_edit_cli_relabels_rewards_with_a_target_reward_proxy(files, capsys):
    edit = ["edit", "--prior", str(files / "prior"), "--source", str(files / "source.hdf5"), "--seed", "3", "--no-guard"]
    assert main([*edit, "--out", str(files / "plain.npz")]) == 0
    out = files / "relabelled.npz"
    assert main([*edit, "--json", "--out", str(out), "--relabel-rewards", str(files / "target.npz"),
                 "--reward-proxy-steps", "200"]) == 0
    report = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert report["rewards_relabelled_from"] == str(files / "target.npz")
    relabelled, plain = load(out), load(files / "plain.npz")
    np.testing.assert_array_equal(relabelled.observations, plain.observations)
    assert not np.allclose(relabelled.rewards, plain.rewards)


def test_edit_cli_refuses_reward_data_of_other_dims(files, capsys):
    save(build_dataset(lengths=(10,), obs_dim=4, act_dim=2, seed=2), files / "wide_rewards.npz")
    out = files / "never.npz"
    rc = main(["edit", "--prior", str(files / "prior"), "--source", str(files / "source.hdf5"), "--out", str(out),
               "--relabel-rewards", str(files / "wide_rewards.npz")])
    assert rc == 2 and "--relabel-rewards" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize("args,needle", [
    (["--kappa", "1.5"], "kappa"),
    (["--sampler", "euler"], "sampler"),
])
def test_edit_cli_refuses_bad_options(files, args, needle, capsys):
    out = files / "bad.npz"
    rc = main(["edit", "--prior", str(files / "prior"), "--source", str(files / "source.hdf5"), "--out", str(out), *args])
    assert rc == 2 and needle in capsys.readouterr().err
    assert not out.exists()


def test_edit_cli_refuses_mismatched_dims(files, capsys):
    other = build_dataset(lengths=(10,), obs_dim=4, act_dim=2, seed=2)
    save(other, files / "wide.npz")
    rc = main(["edit", "--prior", str(files / "prior"), "--source", str(files / "wide.npz"), "--out",
               str(files / "x.npz")])
    assert rc == 2 and "4-d observations" in capsys.readouterr().err
    assert not (files / "x.npz").exists()


@pytest.mark.parametrize("role", ["--source", "--relabel-rewards"])
def test_edit_cli_never_overwrites_an_input(files, capsys, role):
    save(load(files / "target.npz"), files / "input.npz")
    before = (files / "input.npz").read_bytes()
    inputs = {"--source": str(files / "source.hdf5"), "--relabel-rewards": str(files / "target.npz"),
              role: str(files / "input.npz")}
    rc = main(["edit", "--prior", str(files / "prior"), *[x for pair in inputs.items() for x in pair],
               "--out", str(files / "input.npz"), "--force"])
    assert rc == 2 and role in capsys.readouterr().err
    assert (files / "input.npz").read_bytes() == before


def test_train_refuses_unknown_fields(files, capsys):
    rc = main(["train", "--target", str(files / "target.npz"), "--out", str(files / "p2"), "--set", "widht=3"])
    assert rc == 2 and "widht" in capsys.readouterr().err


def test_exported_prior_equals_the_checkpoint(files, tmp_path):
    exported = export_prior(files / "prior", tmp_path / "exported")
    assert not (exported / "checkpoints").exists()
    a, b = load_prior(files / "prior"), load_prior(exported)
    assert a.step == b.step
    for x, y in zip(jax.tree.leaves(a.params), jax.tree.leaves(b.params)):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))


def test_heldout_episodes_are_left_out_of_training(files):
    from xted.data import split_heldout

    target = load(files / "target.npz")
    train, heldout = split_heldout(target, 1, seed=0)
    assert train.num_episodes + heldout.num_episodes == target.num_episodes
    assert len(train) + len(heldout) == len(target)
    assert split_heldout(target, 0) == (target, None)


@pytest.mark.slow
def test_demo_on_shipped_data(tmp_path, capsys):
    from xted.pipelines.bench import store
    from xted.pipelines.bench.config import BenchConfig
    from xted.pipelines.bench.grid import plan

    bench_store = tmp_path / "bench"  # one row of the task's lite table, as `xted bench` stores it
    grid = plan(BenchConfig(envs=("halfcheetah",), gaps=("thigh",), columns=("Tgt",), store=str(bench_store)))
    for score, cell in zip((40.0, 44.0), grid.rows[0].cells):
        store.write_result(bench_store, cell, {"final_score": score})
    assert main(["demo", "--out", str(tmp_path / "demo"), "--proxy-steps", "300", "--bench-store",
                 str(bench_store)]) == 0
    out = capsys.readouterr().out
    assert "  Tgt          42.0 ± 2.0 (2 seeds)" in out and "  Tgt+Edited   not computed" in out
    edited = load(tmp_path / "demo" / "halfcheetah-thigh-edited.npz")
    source = load("halfcheetah-thigh")
    assert len(edited) == len(source)
    np.testing.assert_array_equal(edited.actions[0], source.actions[0])  # the held first transition
    maes = {line.split()[0]: float(line.split("MAE=")[1].split()[0]) for line in out.splitlines() if "MAE=" in line
            and line.startswith("  ")}
    assert maes["target"] < 1e-5 < maes["source"]
    reward_maes = {line.split()[0]: float(line.split("reward MAE=")[1].split()[0]) for line in out.splitlines()
                   if "reward MAE=" in line}
    assert reward_maes["target"] < 1e-5 < reward_maes["edited"]
    assert "edited / source MAE" in out and "learned proxy" in out and "forward-velocity correlation" in out
    assert "task content against the target's: forward velocity source 6.20 -> edited" in out
    assert main(["demo", "--out", str(tmp_path / "bad"), "--proxy-steps", "-1"]) == 2
    assert main(["demo", "--out", str(tmp_path / "bad"), "--gap", "mass"]) == 2
    assert not (tmp_path / "bad").exists()


def test_edit_source_composes_the_prior_s_edit_the_projection_and_the_relabelling(files):
    """One function performs the whole edit: without options it is the prior's own edit; asked, it
    projects onto a model of the target and relabels rewards by one, and its report says which."""
    from xted.analysis import ProxyConfig
    from xted.diffusion.config import EditConfig
    from xted.diffusion.editor import edit_dataset
    from xted.pipelines.edit import edit_source

    prior, source, target = load_prior(files / "prior"), load(files / "source.hdf5"), load(files / "target.npz")
    config = EditConfig(kappa=0.5, seed=3, guard=False)
    plain, report = edit_source(prior, source, config)
    np.testing.assert_array_equal(plain.observations, edit_dataset(prior, source, config)[0].observations)
    assert not report["dynamics_projected"] and not report["rewards_relabelled"]
    quick = ProxyConfig(steps=50, seed=3)
    both, report = edit_source(prior, source, config, project_onto=target, dynamics_proxy=quick, relabel_from=target,
                               reward_proxy=quick)
    assert report["dynamics_projected"] and report["rewards_relabelled"]
    assert not np.allclose(both.observations, plain.observations) and not np.allclose(both.rewards, plain.rewards)
