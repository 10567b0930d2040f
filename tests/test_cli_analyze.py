import json

import pytest

from xted.cli.main import main
from xted.data import save
from xted.pipelines.behaviour_data import build_dataset
from xted.envs import parse_domain


@pytest.fixture(scope="module")
def target_and_source(tmp_path_factory):
    folder = tmp_path_factory.mktemp("dyn")
    paths = []
    for gap in (None, "gravity"):
        data = build_dataset(parse_domain("halfcheetah", gap), "random", 300, None, seed=0, progress=False)
        paths.append(str(folder / f"{gap}.npz"))
        save(data, paths[-1])
    return paths


def test_dynamics_json_scores_target_zero_and_source_above(target_and_source, capsys):
    assert main(["analyze", "dynamics", "--env", "halfcheetah", "--json", *target_and_source]) == 0
    report = json.loads(capsys.readouterr().out)
    target, source = report["datasets"]
    assert {"path", "n", "mae", "mse"} <= set(target)
    assert target["n"] == 300 and target["mae"] < 1e-6
    assert source["mae"] > 0.05
    assert target["reward"]["n"] == 300 and target["reward"]["mae"] < 1e-6


def test_dynamics_in_the_source_domain_flips(target_and_source, capsys):
    assert main(["analyze", "dynamics", "--env", "halfcheetah", "--gap", "gravity", "--json", *target_and_source]) == 0
    target, source = json.loads(capsys.readouterr().out)["datasets"]
    assert source["mae"] < 1e-6 < target["mae"]


@pytest.mark.parametrize("args", [["--env", "humanoid"], ["--env", "halfcheetah", "--gap", "wind"], ["--env", "ant"]])
def test_bad_domain_exits_2(target_and_source, args, capsys):
    assert main(["analyze", "dynamics", *args, target_and_source[0]]) == 2
    assert "error" in capsys.readouterr().err


def test_proxy_json_measures_each_dataset(target_and_source, capsys):
    target, source = target_and_source
    assert main(["analyze", "proxy", "--target", target, "--steps", "300", "--json", target, source]) == 0
    report = json.loads(capsys.readouterr().out)
    assert [row["path"] for row in report["datasets"]] == [target, source]
    fitted, other = report["datasets"]
    assert fitted["n"] == 300 and fitted["mae"] < other["mae"]


def test_content_json_and_mismatch_exit_2(target_and_source, capsys):
    target, source = target_and_source
    assert main(["analyze", "content", "--env", "halfcheetah", "--json", target, target]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["matched"]["low_pass_difference"] == 0.0
    assert report["matched"]["forward_velocity_correlation"] == pytest.approx(1.0)
    assert main(["analyze", "content", target, "halfcheetah-medium"]) == 2
    assert "must have the source's episodes" in capsys.readouterr().err


def test_content_with_a_target_reports_the_shift_against_it(target_and_source, capsys):
    target, source = target_and_source
    assert main(["analyze", "content", "--env", "halfcheetah", "--target", source, "--json", target, target]) == 0
    shift = json.loads(capsys.readouterr().out)["shift"]
    assert set(shift) == {"forward_velocity", "return_per_1000_steps"}
    assert shift["forward_velocity"]["source"] == shift["forward_velocity"]["edited"]  # an unchanged edit
    assert not shift["forward_velocity"]["nearer_target"]
    assert main(["analyze", "content", "--env", "halfcheetah", "--target", source, target, target]) == 0
    assert "shift      forward velocity source" in capsys.readouterr().out


def test_edit_plan_weighs_the_ensembles_disagreement_where_asked(target_and_source, capsys):
    """The shipped prior holds the guard's ensemble: a heavy disagreement weight keeps the source
    (it is far from the target data there), weight 0 reports no disagreement and edits."""
    source = target_and_source[1]
    common = ["analyze", "edit-plan", "--prior", "halfcheetah-medium-replay-cpu", "--kappas", "0.5", "--transitions", "100",
              "--json", source]
    assert main(common) == 0
    plain = json.loads(capsys.readouterr().out)["sources"][source]["kappas"][0]
    assert plain["disagreement"] is None and plain["edited_share"] > 0
    assert main([*common, "--guard-disagreement", "1000"]) == 0
    weighed = json.loads(capsys.readouterr().out)["sources"][source]
    assert weighed["kappas"][0]["disagreement"] > 0 and weighed["kappas"][0]["edited_share"] == 0
    assert weighed["kappa"] is None and "keep the source" in weighed["verdict"]
