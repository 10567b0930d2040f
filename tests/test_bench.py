"""``xted bench``: cells keyed by their inputs (skipped when unchanged, recomputed exactly when
changed), seeds trained together, the oracle relabelling, the report and bad input."""

from __future__ import annotations

import dataclasses
import json
import os
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from xted.cli.main import main
from xted.data import load
from xted.envs import parse_domain
from xted.envs.make import forward_velocity_index, observation_velocity_clip
from xted.errors import InputError
from xted.pipelines.bench import cells, grid, ray_executor, report, run, store
from xted.diffusion.config import EditConfig
from xted.pipelines.bench.columns import TABLE_COLUMNS
from xted.pipelines.bench.config import BenchConfig
from xted.pipelines.bench.edit_quality import edit_label
from xted.pipelines.bench.grid import first_transitions, plan
from xted.pipelines.bench.run import CellsFailed, run_bench

TINY = dict(envs=("halfcheetah",), gaps=("thigh", "gravity"), seeds=(0, 1), steps=10, eval_every=10,
            eval_episodes=1, transitions=200)


def tiny_config(tmp_path, **changes) -> BenchConfig:
    return BenchConfig(**{**TINY, "store": str(tmp_path / "store"), "cache": str(tmp_path / "cache"), **changes})


class FakeTraining:
    """Stands in for ``train_offline``: records each call's seeds, scores by the data's size."""

    def __init__(self):
        self.calls = []

    def __call__(self, config, target, sources, domain, steps, seeds, **settings):
        self.calls.append(list(seeds))
        size = len(target) + sum(len(s) for s in sources)
        return [{"seed": seed, "final_score": size / 100 + seed, "best_score": size / 100 + seed,
                 "evals": [{"step": steps, "normalized_score": size / 100 + seed}], "updates_per_second": 1.0}
                for seed in seeds]


def refuse_training(*args, **kwargs):
    raise AssertionError("a finished cell was trained again")


def shifted_edit(cell, source):
    """A stand-in edit that depends on the edit settings (kappa) like a real one does."""
    return dataclasses.replace(source, rewards=source.rewards + np.float32(cell.edit.kappa))


@pytest.fixture
def fake(monkeypatch):
    training = FakeTraining()
    monkeypatch.setattr(cells, "train_offline", training)
    monkeypatch.setattr(cells, "edited", shifted_edit)
    return training


def run_quietly(config):
    return run_bench(config, progress=False, echo=lambda message: None)


def test_unchanged_cells_are_skipped_and_changed_inputs_recompute_exactly_their_cells(tmp_path, fake, monkeypatch):
    config = tiny_config(tmp_path)
    first = run_quietly(config)
    # 2 gaps x (Src, Tgt+Src, Tgt+Edited, Tgt+Oracle, Tgt+Src DARA, Tgt+Edited DARA) + Tgt once, x 2 seeds;
    # 2 edits, 2 oracles
    assert len(first) == (2 * 6 + 1) * 2 + 4
    assert len(fake.calls) == 13 and all(seeds == [0, 1] for seeds in fake.calls)  # seeds trained together

    monkeypatch.setattr(cells, "train_offline", refuse_training)
    assert run_quietly(config) == []

    monkeypatch.setattr(cells, "train_offline", fake)
    recomputed = run_quietly(dataclasses.replace(config, kappa=0.3))
    edits = [name for name in recomputed if name.startswith("edit-")]
    learners = [name for name in recomputed if name not in edits]
    assert len(edits) == 2 and len(learners) == 8 and all("-tgt+edited-" in name for name in learners)
    assert sum("-tgt+edited-dara-" in name for name in learners) == 4  # DARA on the edit: the paper's Table 2

    real_load = grid.load

    def other_gravity_data(name):
        data = real_load(name)
        return dataclasses.replace(data, rewards=data.rewards * 2) if name == "halfcheetah-gravity" else data

    monkeypatch.setattr(grid, "load", other_gravity_data)
    recomputed = run_quietly(dataclasses.replace(config, kappa=0.3))
    assert len(recomputed) == 6 * 2 + 2 and all("gravity" in name for name in recomputed)

    recomputed = run_quietly(dataclasses.replace(config, kappa=0.3, seeds=(0, 1, 2)))
    assert len(recomputed) == (2 * 6 + 1) and all("seed2" in name for name in recomputed)
    assert fake.calls[-1] == [2]


def test_a_second_process_skips_claimed_groups_and_waits_for_claimed_data(tmp_path, fake, monkeypatch):
    import socket

    from xted.pipelines.bench import claims

    config = tiny_config(tmp_path, gaps=("thigh",), columns=("Tgt", "Tgt+Edited"))
    tgt_group, edited_group = run.pending(plan(config))
    other = {"host": socket.gethostname(), "pid": os.getppid(), "since": 0.0}  # a live process, not this one
    held = claims.claim_path(config.store, run.group_claim(tgt_group))
    held.parent.mkdir(parents=True)
    held.write_text(json.dumps(other))
    messages = []
    computed = run_bench(config, progress=False, echo=messages.append)
    assert not any("-tgt-iql-" in name for name in computed) and any("-tgt+edited-" in name for name in computed)
    assert any("another process is training it" in message for message in messages)
    held.unlink()  # the other process ended without storing them: a rerun trains exactly that group
    assert sorted(run_quietly(config)) == sorted(cell.name for cell in tgt_group)

    # A data cell another process is making: wait, then (it stopped without a result) make it here.
    config = tiny_config(tmp_path, gaps=("gravity",), columns=("Tgt+Edited",))
    (group,) = run.pending(plan(config))
    edit = group[0].data_cell
    held = claims.claim_path(config.store, edit.name)
    held.write_text(json.dumps(other))
    waits = []
    monkeypatch.setattr(claims.time, "sleep", lambda seconds: (waits.append(seconds), held.unlink()))
    computed = run_quietly(config)
    assert waits == [5.0] and edit.name in computed and not list(held.parent.iterdir())  # no claim left behind


def test_claims_are_exclusive_and_stale_ones_are_taken_over(tmp_path):
    import socket
    import subprocess

    from xted.pipelines.bench import claims

    with claims.claim(tmp_path, "cell") as first:
        with claims.claim(tmp_path, "cell") as second:
            assert first and not second
    with claims.claim(tmp_path, "cell") as again:
        assert again  # released on exit
    gone = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    claims.claim_path(tmp_path, "cell").write_text(json.dumps(
        {"host": socket.gethostname(), "pid": int(gone.stdout), "since": 0.0}))
    with claims.claim(tmp_path, "cell") as taken:
        assert taken  # its holder is not running
    claims.claim_path(tmp_path, "cell").write_text(json.dumps({"host": "elsewhere", "pid": 1, "since": 0.0}))
    with claims.claim(tmp_path, "cell") as honoured:
        assert not honoured  # another host's process cannot be checked: honoured


def test_learner_results_record_the_edited_data(tmp_path, fake):
    config = tiny_config(tmp_path, columns=("Tgt+Edited",), seeds=(0,))
    run_quietly(config)
    cell = next(iter(plan(config).learners.values()))
    result = store.read_result(config.store, cell)
    edit = store.read_result(config.store, cell.data_cell)
    assert result["training_data"][1] == edit["data_fingerprint"]
    assert result["edit_key"] == cell.data_cell.key and result["column"] == "Tgt+Edited"
    assert store.data_path(config.cache, cell.data_cell).is_file()


AUGMENTED = ("Tgt (Edit)", "Tgt (Gen)", "Tgt S4RL", "Tgt SER")


@pytest.mark.slow
def test_augmentation_columns_are_made_from_the_target_once_per_target(tmp_path, fake, capsys):
    config = tiny_config(tmp_path, columns=("Tgt", "Tgt+Edited", *AUGMENTED), ser_steps=3)
    planned = plan(config)
    rows = {(row.gap, row.column): row for row in planned.rows}
    assert {gap for gap, column in rows if column in AUGMENTED} == {None}  # one row per target, not per gap
    made = {}
    for column in AUGMENTED:
        (cell, _) = rows[None, column].cells
        data = made[column] = cell.data_cell
        assert (data.source, data.gap, cell.gap, cell.training[0]) == (
            "halfcheetah-medium-replay", None, None, "halfcheetah-medium-replay")
    assert (made["Tgt (Edit)"].edit.kappa, made["Tgt (Edit)"].edit.hold_first) == (1.0, True)
    assert (made["Tgt (Gen)"].edit.kappa, made["Tgt (Gen)"].edit.hold_first) == (1.0, False)
    assert made["Tgt (Edit)"].edit.clip_denoised == made["Tgt (Gen)"].edit.clip_denoised == 5.0
    assert made["Tgt (Edit)"].key != plan(dataclasses.replace(config, edit=("clip_denoised=3",))).rows[-4].cells[0].data_cell.key
    assert (made["Tgt S4RL"].kind, made["Tgt SER"].kind) == ("s4rl", "ser") and len({c.key for c in made.values()}) == 4
    assert plan(dataclasses.replace(config, ser_steps=4)).rows[-1].cells[0].data_cell.key != made["Tgt SER"].key
    lite = plan(dataclasses.replace(config, columns=("Tgt", "Tgt+Edited")))
    assert {c.key for c in lite.learners.values()} < {c.key for c in planned.learners.values()}

    computed = run_quietly(config)
    # 4 data cells made from the target, 2 edits of the sources; Tgt, the 4 augmentations and 2 Tgt+Edited, x 2 seeds
    assert len(computed) == 4 + 2 + (1 + 4 + 2) * 2 and len(fake.calls) == 7
    target = planned.datasets["halfcheetah-medium-replay"]
    copy = load(store.data_path(config.cache, made["Tgt S4RL"]))
    noise = copy.observations - target.observations
    assert 2e-4 < noise.std() < 4e-4 and np.abs(noise).max() < 3e-3
    np.testing.assert_array_equal(copy.actions, target.actions)
    result = store.read_result(config.store, rows[None, "Tgt S4RL"].cells[0])
    assert result["final_score"] == (len(target) + len(copy)) / 100  # the fake scores by size: target + its copy
    generated = load(store.data_path(config.cache, made["Tgt SER"]))
    assert len(generated) == len(target) and generated.metadata["generated"]["config"]["steps"] == 3

    options = ["--envs", "halfcheetah", "--gaps", "thigh,gravity", "--columns", ",".join(("Tgt", *AUGMENTED)),
               "--seeds", "0,1", "--steps", "10", "--eval-every", "10", "--eval-episodes", "1", "--transitions", "200",
               "--ser-steps", "3", "--store", config.store, "--cache", config.cache]
    assert main(["bench", "report", *options]) == 0
    table = capsys.readouterr().out
    assert "| env | target | algo | Tgt | Tgt (Edit) | Tgt (Gen) | Tgt S4RL | Tgt SER |" in table
    assert "| halfcheetah | medium-replay | iql | 2.5 ± 0.5 [-3.9, 8.9] | 4.5 ± 0.5 [-1.9, 10.9] (+80.0%) |" in table
    assert "| iql | P(improvement) | Tgt (Edit) > Tgt | 1.00 | [1.00, 1.00] | 1 | 1/1 |" in table


def test_the_multi_source_columns_read_every_gap_s_source_at_once(tmp_path, fake):
    config = tiny_config(tmp_path, columns=("Tgt+Edited", "Tgt+All Src", "Tgt+All Edited"))
    planned = plan(config)
    rows = {(row.gap, row.column): row for row in planned.rows}
    every_source, every_edit = rows[None, "Tgt+All Src"].cells[0], rows[None, "Tgt+All Edited"].cells[0]
    assert every_source.training == ("halfcheetah-medium-replay", "halfcheetah-thigh", "halfcheetah-gravity")
    edits = [rows[gap, "Tgt+Edited"].cells[0].data_cell.key for gap in ("thigh", "gravity")]
    assert [ref.key for ref in every_edit.training[1:]] == edits  # the single-source columns' edits, shared
    run_quietly(config)
    assert store.read_result(config.store, every_edit)["final_score"] == 600 / 100  # target + both edits


def test_oracle_leaves_target_data_unchanged():
    """The target simulator relabelling target data gives back its rewards within 1e-5 and its next
    states within 1e-5 but for a few transitions where a contact amplifies the float32 rounding of
    the stored state (to 1e-4 at most)."""
    target = first_transitions(load("halfcheetah-medium-replay"), 300)
    relabelled = cells.oracle("halfcheetah", "none", target)
    state_error = np.abs(relabelled.next_observations - target.next_observations).max(axis=1)
    reward_error = np.abs(relabelled.rewards - target.rewards)
    assert np.mean(state_error < 1e-5) >= 0.98 and state_error.max() < 1e-3
    assert np.abs(relabelled.next_observations - target.next_observations).mean() < 1e-6
    assert reward_error.max() < 1e-5
    np.testing.assert_array_equal(relabelled.observations, target.observations)
    np.testing.assert_array_equal(relabelled.actions, target.actions)


def test_walker_oracle_is_exact_where_velocities_are_at_the_observation_clip_too():
    """Walker2d observations clip velocities to +-10, so such an s does not fix the simulator state;
    the oracle recovers it by replaying the source's episode, and the relabelled target data is
    the target data on both kinds of transition."""
    target = first_transitions(load("walker2d-medium-replay"), 500)
    relabelled = cells.oracle("walker2d", "none", target)
    domain = parse_domain("walker2d")
    velocities, clip = slice(forward_velocity_index(domain), None), observation_velocity_clip(domain)
    at_clip = np.any(np.abs(target.observations[:, velocities]) >= clip - 1e-6, axis=1)
    state_error = np.abs(relabelled.next_observations - target.next_observations).max(axis=1)
    assert 0.2 < at_clip.mean() < 0.9  # both kinds are in the sample
    assert state_error[at_clip].max() < 1e-3 and state_error[~at_clip].max() < 1e-3
    assert np.abs(relabelled.rewards - target.rewards).max() < 1e-4
    assert relabelled.metadata["states_at_velocity_clip"] == {"observations": int(at_clip.sum()), "left_clipped": 0}


def test_only_a_clipping_env_s_oracle_key_names_the_state_recovery(tmp_path):
    """Recovery changes nothing where observations are not clipped, so halfcheetah oracle cells keep their keys."""
    config = tiny_config(tmp_path, envs=("halfcheetah", "walker2d"), gaps=("thigh",), columns=("Tgt+Oracle",))
    oracles = {cell.data_cell.env: cell.data_cell.inputs for cell in plan(config).learners.values()}
    assert "states_at_velocity_clip" in oracles["walker2d"]
    assert "states_at_velocity_clip" not in oracles["halfcheetah"]


@pytest.mark.slow
def test_a_real_tiny_grid_edits_once_and_trains(tmp_path, capsys):
    """The shipped prior edits a 200-transition source (kappa 0.05: 10 reverse steps); IQL trains 10 steps."""
    options = ["--envs", "halfcheetah", "--gaps", "thigh", "--columns", "Tgt,Tgt+Edited", "--seeds", "0,1",
               "--steps", "10", "--eval-every", "10", "--eval-episodes", "1", "--transitions", "200",
               "--kappa", "0.05", "--store", str(tmp_path / "store"), "--cache", str(tmp_path / "cache")]
    assert main(["bench", "run", *options]) == 0
    assert "5 cells computed" in capsys.readouterr().out  # 2 x Tgt, 2 x Tgt+Edited, the edit
    assert main(["bench", "report", *options, "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)["rows"]
    assert [(row["column"], row["n_seeds"]) for row in rows] == [("Tgt", 2), ("Tgt+Edited", 2)]


@pytest.mark.slow
def test_a_target_without_a_prior_gets_one_trained_once(tmp_path, capsys):
    """No prior is shipped for halfcheetah-medium: the bench trains one (3 steps here) into its cache,
    records it, edits with it and trains the learner; a rerun computes nothing; more prior steps
    make another prior, edit and learner."""
    options = ["--envs", "halfcheetah", "--targets", "medium", "--gaps", "thigh", "--columns", "Tgt+Edited",
               "--seeds", "0", "--steps", "10", "--eval-every", "10", "--eval-episodes", "1", "--transitions", "2500",
               "--kappa", "0.05", "--prior-steps", "3", "--store", str(tmp_path / "store"),
               "--cache", str(tmp_path / "cache")]
    config = tiny_config(tmp_path, targets=("medium",), gaps=("thigh",), columns=("Tgt+Edited",), seeds=(0,),
                         transitions=2500, kappa=0.05, prior_steps=3)
    (cell,) = plan(config).learners.values()
    prior = cell.data_cell.prior_cell
    assert prior is not None and cell.data_cell.inputs["prior"] == {"kind": "prior", "key": prior.key}
    assert prior.heldout_episodes == 2 and prior.steps == 3 and cell.data_cell.prior == prior.folder
    assert main(["bench", "run", *options]) == 0
    assert "3 cells computed" in capsys.readouterr().out  # the prior, the edit, the learner
    record = store.read_result(config.store, prior)
    assert record["steps"] == 3 and (tmp_path / "cache" / "halfcheetah" / prior.name / "prior.json").is_file()
    assert store.read_result(config.store, cell) is not None
    assert main(["bench", "run", *options]) == 0
    assert "0 cells computed" in capsys.readouterr().out
    kept = tmp_path / "priors" / "halfcheetah" / prior.name  # the exported copy, committed beside the store
    assert (kept / "prior.json").is_file() and (kept / "target_model.msgpack").is_file()
    shutil.rmtree(tmp_path / "cache")  # a fresh checkout: a new learner needs the edit, the edit the prior
    steps = options.index("--steps") + 1
    assert main(["bench", "run", *options[:steps], "11", *options[steps + 1:]]) == 0
    assert "2 cells computed" in capsys.readouterr().out  # the edit and the learner: the prior was restored
    (longer,) = plan(dataclasses.replace(config, prior_steps=4)).learners.values()
    assert longer.data_cell.prior_cell.key != prior.key and longer.data_cell.key != cell.data_cell.key
    assert longer.key != cell.key
    shipped_prior = plan(dataclasses.replace(config, targets=("medium-replay",)))
    assert all(c.data_cell.prior_cell is None for c in shipped_prior.learners.values())


def test_prior_set_changes_the_trained_prior_of_its_env_only():
    config = BenchConfig(envs=("halfcheetah", "walker2d"), targets=("medium",), gaps=("thigh",), columns=("Tgt+Edited",),
                         seeds=(0,))
    def priors(**changes):
        return {cell.env: cell.data_cell.prior_cell for cell in plan(dataclasses.replace(config, **changes)).learners.values()}

    default = priors()
    scoped = priors(prior_overrides=("walker2d:cross_blocks=2",))
    assert scoped["halfcheetah"].key == default["halfcheetah"].key
    assert scoped["walker2d"].key != default["walker2d"].key
    assert (scoped["walker2d"].config.cross_blocks, default["walker2d"].config.cross_blocks) == (2, 1)
    both = priors(prior_overrides=("cross_blocks=2",))
    assert both["walker2d"].key == scoped["walker2d"].key and both["halfcheetah"].key != default["halfcheetah"].key
    assert {c.data_cell.key for c in plan(config).learners.values()} != {
        c.data_cell.key for c in plan(dataclasses.replace(config, prior_overrides=("cross_blocks=2",))).learners.values()}
    # Beside a target whose prior is shipped, the override changes the trained ones and leaves the shipped one.
    mixed = plan(dataclasses.replace(config, envs=("walker2d",), targets=("medium-replay", "medium"),
                                     prior_overrides=("walker2d:cross_blocks=2",)))
    by_target = {c.target: c.data_cell for c in mixed.learners.values()}
    assert by_target["medium-replay"].prior_cell is None and by_target["medium-replay"].prior.endswith("-cpu")
    assert by_target["medium"].prior_cell.key == scoped["walker2d"].key


def test_projected_edits_are_keyed_apart_and_projected_onto_a_model_of_the_row_s_target(tmp_path, monkeypatch):
    """--project-dynamics: the edit cell names the dynamics model (the row's target, the proxy's
    settings) and the weight; the plain edit's key is unchanged by the weight. The cell's edit is
    the editor's projection onto a proxy fitted to the target's first transitions."""
    config = tiny_config(tmp_path, gaps=("thigh",), columns=("Tgt+Edited",), seeds=(0,), kappa=0.05)
    (plain,) = plan(config).learners.values()
    (reweighted,) = plan(dataclasses.replace(config, edit=("dynamics_weight=0.25",))).learners.values()
    assert reweighted.data_cell.key == plain.data_cell.key and plain.data_cell.dynamics is None
    projected_config = dataclasses.replace(config, project_dynamics=True, dynamics_proxy_steps=3)
    (projected,) = plan(projected_config).learners.values()
    cell = projected.data_cell
    assert cell.dynamics == grid.DynamicsModel("halfcheetah-medium-replay", 200, cell.dynamics.proxy)
    assert cell.dynamics.proxy.steps == 3 and cell.inputs["edit"]["dynamics_weight"] == 0.5
    assert cell.key != plain.data_cell.key and projected.key != plain.key
    (heavier,) = plan(dataclasses.replace(projected_config, edit=("dynamics_weight=0.25",))).learners.values()
    assert heavier.data_cell.key != cell.key

    from xted.pipelines import edit as whole_edit

    fitted, projections = [], []
    real_fit, real_edit = whole_edit.fit_proxy, whole_edit.edit_dataset

    def fit_proxy(target, proxy_config, progress):
        fitted.append((len(target), proxy_config.steps))
        return real_fit(target, proxy_config, progress)

    def edit_dataset(prior, source, edit, **settings):
        projections.append(settings["dynamics"])
        return real_edit(prior, source, edit, **settings)

    monkeypatch.setattr(whole_edit, "fit_proxy", fit_proxy)
    monkeypatch.setattr(whole_edit, "edit_dataset", edit_dataset)
    grid_plan = plan(projected_config)
    data = cells.make_data(cell, grid_plan.datasets[cell.source])
    assert fitted == [(200, 3)] and callable(projections[0])
    assert np.array_equal(data.next_observations[:-1][~(data.terminals | data.timeouts)[:-1]],
                          data.observations[1:][~(data.terminals | data.timeouts)[:-1]])
    assert not np.allclose(data.observations, cells.edited(plain.data_cell, grid_plan.datasets[cell.source]).observations)


def write_hand_made_results(config, scores):
    """Results of the grid's cells with the given final scores per column (one per seed)."""
    for row in plan(config).rows:
        for cell, score in zip(row.cells, scores.get(row.column, [])):
            store.write_result(config.store, cell, {"final_score": score})


def test_report_rows_and_markdown(tmp_path, capsys):
    config = tiny_config(tmp_path, gaps=("thigh",), columns=("Tgt", "Tgt+Src", "Tgt+Edited"))
    write_hand_made_results(config, {"Tgt": [10.0, 20.0], "Tgt+Edited": [30.0]})
    options = ["--envs", "halfcheetah", "--gaps", "thigh", "--columns", "Tgt,Tgt+Src,Tgt+Edited", "--seeds", "0,1",
               "--steps", "10", "--eval-every", "10", "--eval-episodes", "1", "--transitions", "200",
               "--store", config.store, "--cache", config.cache]
    assert main(["bench", "report", *options, "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    rows = printed["rows"]
    assert [row["column"] for row in rows] == ["Tgt", "Tgt+Src", "Tgt+Edited"]
    for row in rows:
        assert {"env", "target", "gap", "column", "algo", "mean", "std", "n_seeds"} <= set(row)
        assert (row["env"], row["target"], row["gap"], row["algo"]) == ("halfcheetah", "medium-replay", "thigh", "iql")
    assert (rows[0]["mean"], rows[0]["std"], rows[0]["n_seeds"]) == (15.0, 5.0, 2)
    assert rows[0]["ci95"] == pytest.approx([15 - 63.53, 15 + 63.53], abs=0.01)  # t(0.975, 1) = 12.706
    assert (rows[1]["mean"], rows[1]["n_seeds"], rows[1]["ci95"]) == (None, 0, None)
    assert (rows[2]["mean"], rows[2]["std"], rows[2]["n_seeds"], rows[2]["ci95"]) == (30.0, 0.0, 1, None)
    measures = {(row["measure"], row["column"]): row for row in printed["aggregate"]}
    assert set(measures) == {("IQM", "Tgt"), ("IQM", "Tgt+Edited"), ("P(improvement)", "Tgt+Edited > Tgt")}
    assert measures["IQM", "Tgt"]["value"] == 15.0 and measures["IQM", "Tgt"]["tasks"] == 1
    assert measures["P(improvement)", "Tgt+Edited > Tgt"]["value"] == 1.0  # 30 beats both seeds
    assert measures["P(improvement)", "Tgt+Edited > Tgt"]["ahead"] == 1
    assert measures["P(improvement)", "Tgt+Edited > Tgt"]["total_gain"] == 100.0  # 30 against a mean of 15

    png = tmp_path / "table.png"
    assert main(["bench", "report", *options, "--png", str(png)]) == 0
    table = capsys.readouterr().out
    assert "| 15.0 ± 5.0 [-48.5, 78.5] | — | 30.0 ± 0.0 (+100.0%) |" in table
    # beside it the paper's Table 1 on the same task: Tgt+Edited 33.0 against Tgt 26.2
    assert "| iql | P(improvement) | Tgt+Edited > Tgt | 1.00 | [1.00, 1.00] | 1 | 1/1 | +100.0% | 1/1, +26.0% |" in table
    assert png.is_file()


def test_mean_comparison_counts_ties_as_ahead_and_compares_totals_of_means():
    # task 1: 12 against 10 (ahead); task 2: 5 against 5 (a tie counts, as "Tgt+Edited >= Tgt+Src");
    # task 3: 1 against 15 (behind). Totals of means: 18 against 30.
    better, baseline = [[11.0, 13.0], [5.0], [1.0, 1.0]], [[10.0], [4.0, 6.0], [15.0]]
    assert report.mean_comparison(better, baseline) == {"ahead": 2, "total_gain": pytest.approx(-40.0)}
    assert report.mean_comparison([[1.0]], [[0.0]])["total_gain"] is None


def test_a_claim_on_part_of_the_grid_is_set_beside_the_paper_s_figure_on_the_same_part():
    a, b, c = ("hc", "mr", "thigh"), ("hc", "mr", "gravity"), ("hc", "me", "thigh")
    better, baseline = {a: 30.0, b: 10.0, c: 50.0}, {a: 20.0, b: 20.0}  # no printed baseline on c
    assert report.paper_comparison([a, b, c], better, baseline) == {
        "paper_tasks": 2, "paper_ahead": 1, "paper_total_gain": pytest.approx(0.0)}
    assert report.paper_comparison([c], better, baseline) == {}
    # a per-target column (gap None) is set against the target's Tgt, printed on each gap's line
    assert report.paper_comparison([("hc", "mr", None)], {("hc", "mr", None): 25.0}, baseline)["paper_total_gain"] == 25.0


def test_report_sets_the_paper_s_cells_under_each_line_and_its_total_over_the_same_rows(tmp_path, capsys):
    config = tiny_config(tmp_path, gaps=("thigh", "friction"), columns=("Tgt", "Tgt+Edited", "Tgt+Oracle"))
    write_hand_made_results(config, {"Tgt": [10.0, 20.0]})
    options = ["--envs", "halfcheetah", "--gaps", "thigh,friction", "--columns", "Tgt,Tgt+Edited,Tgt+Oracle",
               "--seeds", "0,1", "--steps", "10", "--eval-every", "10", "--eval-episodes", "1",
               "--transitions", "200", "--store", config.store, "--cache", config.cache]
    assert main(["bench", "report", *options, "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)["rows"]
    assert [row["paper"] for row in rows[:3]] == [{"mean": 26.2, "std": 3.5}, {"mean": 33.0, "std": 3.0}, None]
    assert main(["bench", "report", *options, "--paper"]) == 0
    table = capsys.readouterr().out
    assert "| | | | paper | 26.2 ± 3.5 | 33.0 ± 3.0 (+26.0%) | — |" in table  # HC-MR thigh, Table 1
    assert "| | | | paper | 26.2 ± 3.5 | 31.8 ± 3.1 (+21.4%) | — |" in table  # HC-MR friction
    assert "| Total | | | paper | 52.4 | 64.8 (+23.7%) | — |" in table
    assert main(["bench", "report", *options]) == 0
    assert "| paper |" not in capsys.readouterr().out


def test_compact_report_is_one_line_per_task_with_the_paper_s_mean_and_a_repeated_cell_shortened(tmp_path, capsys):
    config = tiny_config(tmp_path, gaps=("thigh", "friction"), columns=("Tgt", "Tgt+Edited", "Tgt+Oracle"))
    write_hand_made_results(config, {"Tgt": [10.0, 20.0], "Tgt+Oracle": [7.0, 9.0]})
    options = ["--envs", "halfcheetah", "--gaps", "thigh,friction", "--columns", "Tgt,Tgt+Edited,Tgt+Oracle",
               "--seeds", "0,1", "--steps", "10", "--eval-every", "10", "--eval-episodes", "1",
               "--transitions", "200", "--store", config.store, "--cache", config.cache, "--compact"]
    assert main(["bench", "report", *options]) == 0
    table = capsys.readouterr().out.split("\n\n")[0].splitlines()
    assert table[0] == "| task | Tgt | Tgt+Edited | Tgt+Oracle |"
    # Tgt is one cell per target: in full on the first line, its mean on the next; the paper prints no oracle.
    assert table[2] == ("| halfcheetah medium-replay thigh | 15.0 ± 5.0 [-48.5, 78.5] (26.2) | not run (33.0) "
                        "| 8.0 ± 1.0 [-4.7, 20.7] |")
    assert table[3] == "| halfcheetah medium-replay friction | 15.0 (26.2) | not run (31.8) | 8.0 ± 1.0 [-4.7, 20.7] |"
    assert len(table) == 4


def test_refresh_rewrites_each_report_block_as_the_report_prints_it_and_nothing_else(tmp_path, capsys):
    config = tiny_config(tmp_path, gaps=("thigh",), columns=("Tgt", "Tgt+Oracle"))
    write_hand_made_results(config, {"Tgt": [10.0, 20.0], "Tgt+Oracle": [7.0, 9.0]})
    options = ["--envs", "halfcheetah", "--gaps", "thigh", "--columns", "Tgt,Tgt+Oracle", "--seeds", "0,1", "--steps",
               "10", "--eval-every", "10", "--eval-episodes", "1", "--transitions", "200", "--store", config.store,
               "--cache", config.cache, "--compact"]
    assert main(["bench", "report", *options]) == 0
    printed = capsys.readouterr().out.rstrip("\n")
    marker = "<!-- xted bench report " + " ".join(shlex.quote(option) for option in options) + " -->"
    document = tmp_path / "notes.md"
    document.write_text(f"# Notes\n\n{marker}\nan old table\n<!-- end of the report -->\n\nkept\n")
    assert main(["bench", "refresh", str(document)]) == 0
    assert document.read_text() == f"# Notes\n\n{marker}\n{printed}\n<!-- end of the report -->\n\nkept\n"
    assert "1 report block refreshed" in capsys.readouterr().out
    before = document.stat().st_mtime_ns
    assert main(["bench", "refresh", str(document)]) == 0
    assert "1 report block unchanged" in capsys.readouterr().out and document.stat().st_mtime_ns == before


def test_benchmarks_md_s_report_blocks_are_current_with_the_committed_store(tmp_path, monkeypatch):
    """The tables BENCHMARKS.md shows are what the committed store holds (the unattended grid refreshes them with
    each commit); results a running grid has not committed yet are left out, as a clean clone has none."""
    root = Path(__file__).resolve().parent.parent
    committed = subprocess.run(f"git archive HEAD BENCHMARKS.md benchmarks/results | tar -x -C {shlex.quote(str(tmp_path))}",
                               shell=True, cwd=root, capture_output=True, text=True)
    assert committed.returncode == 0, committed.stderr
    shown = (tmp_path / "BENCHMARKS.md").read_text()
    monkeypatch.chdir(tmp_path)
    assert main(["bench", "refresh", "BENCHMARKS.md"]) == 0
    assert (tmp_path / "BENCHMARKS.md").read_text() == shown, "run `xted bench refresh BENCHMARKS.md` and commit it"


def test_the_paper_s_cells_sum_to_its_printed_totals():
    from xted.pipelines.bench.paper import _TABLES, PAPER_COLUMNS, PRINTED_TOTALS, paper_cell

    sums = {column: round(sum(cells[i][0] for cells in _TABLES.values()), 1) for i, column in enumerate(PAPER_COLUMNS)}
    assert len(_TABLES) == 18
    assert {c: sums[c] for c in PAPER_COLUMNS[:4]} == {c: PRINTED_TOTALS[c] for c in PAPER_COLUMNS[:4]}
    # Table 2 prints totals 2.2 and 1.0 above what its cells sum to (734.2, 824.2).
    assert (sums["Tgt+Src DARA"], sums["Tgt+Edited DARA"]) == (732.0, 823.2)
    multi = [paper_cell(env, target, None, column, "iql")["mean"] for column in ("Tgt+All Src", "Tgt+All Edited")
             for env in ("halfcheetah", "walker2d") for target in ("medium", "medium-replay", "medium-expert")]
    assert (round(sum(multi[:6]), 1), round(sum(multi[6:]), 1)) == (235.3, 271.7)
    assert paper_cell("walker2d", "medium", "thigh", "Tgt+All Src", "iql") is None


def test_report_cost_shares_each_group_s_time_among_its_seeds_and_counts_a_shared_edit_once(tmp_path, capsys):
    config = tiny_config(tmp_path, gaps=("thigh",), columns=("Tgt", "Tgt+Edited", "Tgt+Edited DARA"))
    rows = plan(config).rows
    for row, group_seconds in zip(rows, (3600.0, 7200.0, None)):
        for cell in row.cells:
            timing = {} if group_seconds is None else {"group_seconds": group_seconds, "group_size": 2}
            store.write_result(config.store, cell, {"final_score": 1.0, **timing})
    edit = rows[1].cells[0].data_cell
    assert rows[2].cells[0].data_cell.key == edit.key  # Tgt+Edited and its DARA column read one edit
    store.write_result(config.store, edit, {"kind": "edit", "seconds": 1800.0})
    options = ["--envs", "halfcheetah", "--gaps", "thigh", "--columns", "Tgt,Tgt+Edited,Tgt+Edited DARA",
               "--seeds", "0,1", "--steps", "10", "--eval-every", "10", "--eval-episodes", "1", "--transitions", "200",
               "--store", config.store, "--cache", config.cache]
    assert main(["bench", "report", *options, "--json"]) == 0
    cost = json.loads(capsys.readouterr().out)["cost"]
    assert [(row["kind"], row["cells"], row["unrecorded"]) for row in cost] == [
        ("learner", 2, 0), ("learner", 2, 0), ("learner", 2, 2), ("edit", 1, 0)]
    assert [row["hours"] for row in cost] == pytest.approx([1.0, 2.0, 0.0, 0.5])  # 2 seeds of a 1 h group: 1 h
    assert main(["bench", "report", *options, "--cost"]) == 0
    printed = capsys.readouterr().out
    assert "| Total | | 7 | 3.50 | 2 |" in printed
    assert "| Tgt | 2 | 1.00 | 0.00 | 0.500 |" in printed and "| Tgt+Edited | 2 | 2.00 | 0.50 | 1.250 |" in printed
    assert "| Tgt+Edited DARA | 2 | 0.00 | 0.00 | - |" in printed


def test_report_curves_average_the_steps_every_seed_evaluated(tmp_path, capsys):
    config = tiny_config(tmp_path, gaps=("thigh",), columns=("Tgt",))
    (cell_0, cell_1), = [row.cells for row in plan(config).rows]
    store.write_result(config.store, cell_0, {"final_score": 3.0, "evals": [
        {"step": 5, "normalized_score": 1.0}, {"step": 10, "normalized_score": 3.0}]})
    store.write_result(config.store, cell_1, {"final_score": 5.0, "evals": [
        {"step": 2, "normalized_score": 9.0}, {"step": 5, "normalized_score": 2.0},
        {"step": 10, "normalized_score": 5.0}]})
    options = ["--envs", "halfcheetah", "--gaps", "thigh", "--columns", "Tgt", "--seeds", "0,1", "--steps", "10",
               "--eval-every", "10", "--eval-episodes", "1", "--transitions", "200", "--store", config.store,
               "--cache", config.cache]
    assert main(["bench", "report", *options, "--json"]) == 0
    (row,) = json.loads(capsys.readouterr().out)["rows"]
    assert [(p["step"], p["mean"], p["std"], p["n_seeds"]) for p in row["curve"]] == [
        (5, 1.5, 0.5, 2), (10, 4.0, 1.0, 2)]  # step 2: one seed only
    assert main(["bench", "report", *options, "--curves"]) == 0
    printed = capsys.readouterr().out
    assert "| env | target | gap | column | algo | 5 | 10 |" in printed
    assert "| halfcheetah | medium-replay | thigh | Tgt | iql | 1.5 ± 0.5 | 4.0 ± 1.0 |" in printed
    assert main(["bench", "run", *options, "--curves"]) == 2  # an option of the report only
    assert "--curves" in capsys.readouterr().err


def edit_quality_row(gap, sim_source, sim_edited, proxy_source=1.0, proxy_edited=0.5, matched=0.9, mismatched=0.2):
    return {"env": "halfcheetah", "gap": gap, "kappa": 0.5, "edit": [], "sim_source": sim_source,
            "sim_edited": sim_edited, "proxy_source": proxy_source, "proxy_edited": proxy_edited,
            "floor": {"sim": 0.4, "proxy": 0.4},
            "content": {"matched": {"forward_velocity_correlation": matched},
                        "mismatched": {"forward_velocity_correlation": mismatched}}}


def test_report_checks_edit_quality_rows_against_the_edit_targets(tmp_path, capsys):
    """A large gap halved and landing within 1.5x the floor meets every target; a small gap is not
    held to halving; rows of gaps outside the grid are left out; a bad file exits 2."""
    rows = tmp_path / "quality.jsonl"
    rows.write_text("\n".join(json.dumps(row) for row in [
        edit_quality_row("thigh", sim_source=1.2, sim_edited=0.6),
        edit_quality_row("gravity", sim_source=0.2, sim_edited=0.7, proxy_edited=0.6, matched=0.5),
        edit_quality_row("friction", sim_source=0.2, sim_edited=0.1)]) + "\n")
    options = ["bench", "report", "--envs", "halfcheetah", "--gaps", "thigh,gravity", "--columns", "Tgt", "--seeds", "0",
               "--store", str(tmp_path / "store")]
    assert main([*options, "--json", "--edit-quality", str(rows)]) == 0
    quality = json.loads(capsys.readouterr().out)["edit_quality"]
    assert [(row["gap"], row["targets"]) for row in quality] == [
        ("thigh", {"large gap halved": True, "lands at the floor": True, "proxy": True, "content kept": True}),
        ("gravity", {"large gap halved": None, "lands at the floor": False, "proxy": False, "content kept": False})]
    assert main([*options, "--edit-quality", str(rows)]) == 0
    printed = capsys.readouterr().out
    assert "| halfcheetah | gravity | 0.5 | default | 0.200 -> 0.700 (3.50) | 1.75 |" in printed
    assert "met by 1 of 1 rows" in printed and "met by 1 of 2 rows" in printed
    rows.write_text('{"env": "halfcheetah"}\n')
    assert main([*options, "--edit-quality", str(rows)]) == 2
    assert "quality.jsonl:1: a row of benchmarks/edit_quality.py --out needs gap, kappa" in capsys.readouterr().err
    assert main(["bench", "run", *options[2:], "--edit-quality", str(rows)]) == 2


def test_edit_quality_rows_are_labelled_by_what_differs_from_today_s_edit_defaults():
    defaults = dataclasses.asdict(EditConfig())
    row = edit_quality_row("thigh", 1.2, 0.6)
    assert edit_label(row) == "default"  # a row from before edit configs were recorded: its --edit list
    assert edit_label({**row, "edit_config": {**defaults, "kappa": 0.7, "seed": 3}}) == "default"
    assert edit_label({**row, "edit_config": {**defaults, "temperature": 1.0, "sampler": "ddim"}}) == (
        "sampler=ddim temperature=1.0")


@pytest.mark.parametrize("option, value, message", [
    ("--columns", "Tgt,Tgt+Magic", "unknown column 'Tgt+Magic'"),
    ("--gaps", "thigh,moon", "unknown gap 'moon'"),
    ("--envs", "humanoid", "unknown env 'humanoid'"),
    ("--seeds", "0,0", "--seeds"),
    ("--prior-preset", "huge", "unknown prior preset 'huge'"),
    ("--prior-set", "hopper:cross_blocks=2", "'hopper' is not an env in the grid"),
    ("--envs", "hopper", "no shipped dataset 'hopper-medium-replay'"),
    ("--prior-set", "cross_blocks", "expected FIELD=VALUE or ENV:FIELD=VALUE"),
    ("--prior-set", "walker2d:wings=2", "wings"),
])
def test_bad_input_exits_2(tmp_path, capsys, option, value, message):
    assert main(["bench", "report", option, value, "--store", str(tmp_path / "store")]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "store").exists()


@pytest.mark.parametrize("options, message", [
    (["--address", "head:6379"], "--address: only with --executor ray"),
    (["--retries", "3", "--cpus-per-task", "2"], "--retries, --cpus-per-task: only with --executor ray"),
    (["--executor", "spark"], "--executor 'spark': expected local or ray"),
])
def test_bad_executor_options_exit_2(tmp_path, capsys, options, message):
    assert main(["bench", "report", "--executor", "ray", "--store", str(tmp_path / "store")]) == 2
    assert "--executor" in capsys.readouterr().err  # the report computes nothing: it has no executor
    assert main(["bench", "run", *options, "--store", str(tmp_path / "store")]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "store").exists()


def test_the_ray_executor_without_ray_names_the_fix(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray fails as where it is not installed
    assert main(["bench", "run", "--executor", "ray", "--store", str(tmp_path / "store")]) == 2
    assert "pip install 'xted[ray]'" in capsys.readouterr().err
    assert not (tmp_path / "store").exists()


def test_failed_cells_are_named_and_exit_1(tmp_path, capsys, monkeypatch):
    def failing(config, echo, ray, priors_only):
        assert ray.retries == 4 and ray.address is None
        raise CellsFailed([("tgt-iql-seed0-abc", "its worker died, 5 times")], ["src-iql-seed0-def"])

    monkeypatch.setattr(run, "run_bench", failing)
    assert main(["bench", "run", "--executor", "ray", "--retries", "4", "--store", str(tmp_path / "store")]) == 1
    out, err = capsys.readouterr()
    assert "1 cells computed" in out
    assert "failed: tgt-iql-seed0-abc: its worker died, 5 times" in err and "1 cells failed" in err


def test_an_edit_task_refuses_a_prior_folder_other_than_the_planned_one(tmp_path):
    """A Ray worker reads the prior at the driver's path: a different folder there is refused, not used."""
    config = tiny_config(tmp_path, gaps=("thigh",), columns=("Tgt+Edited",), seeds=(0,))
    cell = next(iter(plan(config).learners.values())).data_cell
    other = dataclasses.replace(cell, inputs={**cell.inputs, "prior": "0" * 64})
    with pytest.raises(InputError, match="differs from the driver's"):
        ray_executor._make(other, None, refuse_training)


def test_default_grid_is_the_lite_table():
    config = BenchConfig()
    assert (config.envs, config.targets, config.gaps, config.columns, config.algos, config.seeds, config.steps) == (
        ("halfcheetah", "walker2d"), ("medium-replay",), ("thigh", "gravity", "friction"), TABLE_COLUMNS, ("iql",),
        (0, 1, 2, 3, 4), 30_000)


@pytest.mark.parametrize("env", ["halfcheetah", "walker2d"])
def test_the_committed_lite_table_is_found_under_today_s_cell_keys(env):
    """A change to a config's fields must not orphan the committed results (their keys hash the configs)."""
    from pathlib import Path

    from xted.pipelines.bench.columns import SRC, TGT, TGT_EDITED, TGT_ORACLE, TGT_SRC
    from xted.pipelines.bench.report import task_rows

    store = Path(__file__).parent.parent / BenchConfig.store
    columns = (SRC, TGT, TGT_SRC, TGT_EDITED, TGT_ORACLE)
    rows = task_rows(env, "medium-replay", "thigh", columns, str(store))
    assert [row["n_seeds"] for row in rows] == [5] * len(columns), rows


def test_the_guarded_columns_edit_with_the_guard_and_are_keyed_apart_from_the_plain_edit(tmp_path):
    config = tiny_config(tmp_path, gaps=("thigh",), columns=("Tgt+Edited", "Tgt+Guarded", "Tgt+Guarded DARA"),
                         seeds=(0,))
    by_column = {cell.column: cell for cell in plan(config).learners.values()}
    plain, guarded = by_column["Tgt+Edited"].data_cell, by_column["Tgt+Guarded"].data_cell
    assert not plain.edit.guard and guarded.edit.guard and guarded.key != plain.key
    assert by_column["Tgt+Guarded DARA"].data_cell.key == guarded.key
    assert "guard" not in plain.inputs["edit"] and "target_model" in guarded.inputs
    assert "guard_disagreement" not in guarded.inputs["edit"] and "target_ensemble" not in guarded.inputs
    # The disagreement test (opt-in) keys its guarded edit apart, by the ensemble too; the plain edit keeps its key.
    strict = {cell.column: cell.data_cell for cell in plan(dataclasses.replace(
        config, edit=("guard_disagreement=0.5",))).learners.values()}
    assert strict["Tgt+Edited"].key == plain.key and strict["Tgt+Guarded"].key != guarded.key
    assert strict["Tgt+Guarded"].inputs["edit"]["guard_disagreement"] == 0.5
    assert "target_ensemble" in strict["Tgt+Guarded"].inputs


def test_the_committed_guarded_cells_keep_their_keys():
    committed = BenchConfig(columns=("Tgt+Guarded",), seeds=(0, 1, 2, 3, 4),
                            store=str(Path(__file__).resolve().parents[1] / "benchmarks" / "results" / "bench"))
    cells = plan(committed).learners.values()
    assert len(cells) == 30 and all(store.current_result(committed.store, cell) is not None for cell in cells)


def test_the_filter_columns_wrap_iql_with_each_env_s_keep_share_and_are_keyed_by_their_own_settings(tmp_path):
    from xted.rl.config import IGDFConfig, OTDFConfig

    columns = ("Tgt+Src", "Tgt+Src DARA", "Tgt+Src IGDF", "Tgt+Src OTDF")
    config = tiny_config(tmp_path, envs=("halfcheetah", "walker2d"), gaps=("thigh",), columns=columns, seeds=(0,),
                         algos=("iql", "td3bc"))
    learners = plan(config).learners.values()
    by = {(cell.env, cell.column, cell.algo): cell for cell in learners}
    assert isinstance(by["halfcheetah", "Tgt+Src IGDF", "iql"].config, IGDFConfig)
    assert by["halfcheetah", "Tgt+Src IGDF", "iql"].config.keep_fraction == 0.25
    assert by["walker2d", "Tgt+Src IGDF", "iql"].config.keep_fraction == 0.75
    assert isinstance(by["walker2d", "Tgt+Src OTDF", "iql"].config, OTDFConfig)
    assert ("halfcheetah", "Tgt+Src IGDF", "td3bc") not in by  # a wrapper of the IQL backbone only
    # The filters train on what Tgt+Src trains on.
    assert by["halfcheetah", "Tgt+Src IGDF", "iql"].training == by["halfcheetah", "Tgt+Src", "iql"].training

    def keys(*overrides, algos=("iql", "td3bc")):
        changed = plan(dataclasses.replace(config, overrides=overrides, algos=algos)).learners.values()
        return {(cell.env, cell.column, cell.algo): cell.key for cell in changed}

    before = keys()
    for pair, column in (("igdf.keep_fraction=0.5", "Tgt+Src IGDF"), ("otdf.epsilon=0.1", "Tgt+Src OTDF")):
        after = keys(pair)
        assert {name for name in before if before[name] != after[name]} == {
            (env, column, "iql") for env in ("halfcheetah", "walker2d")}, pair
    # The backbone's settings reach every IQL column, the wrappers' too.
    after = keys("expectile=0.8", algos=("iql",))
    assert after["halfcheetah", "Tgt+Src IGDF", "iql"] != before["halfcheetah", "Tgt+Src IGDF", "iql"]


def test_every_column_s_comparisons_name_declared_columns_and_the_report_compares_them():
    from xted.pipelines.bench.columns import COLUMNS, DATA_KINDS
    from xted.pipelines.bench.report import IMPROVEMENTS

    for column in COLUMNS.values():
        assert all(kind in DATA_KINDS for kind in column.data), column
        assert all(other in COLUMNS and other != column.name for other in column.compared_with), column
    assert ("Tgt+Guarded", "Tgt+Src IGDF") in IMPROVEMENTS and ("Tgt+Src OTDF", "Tgt+Src") in IMPROVEMENTS
    assert COLUMNS["Tgt (Edit)"].per_target and not COLUMNS["Tgt"].per_target and not COLUMNS["Src"].per_target


def test_two_processes_needing_one_untrained_prior_train_it_once(tmp_path, monkeypatch):
    """Two edits of one bench-trained prior, made by two processes at once: the prior is trained by
    the first to claim it; the second waits for that claim and uses the prior it finished."""
    import socket
    import threading
    from pathlib import Path

    from xted.pipelines.bench import claims

    config = tiny_config(tmp_path, targets=("medium",), gaps=("thigh", "gravity"), columns=("Tgt+Edited",),
                         seeds=(0,), transitions=2500, prior_steps=3)
    grid = plan(config)
    prior = next(iter(grid.learners.values())).data_cell.prior_cell
    trainings = []
    training, release = threading.Event(), threading.Event()

    def slow_training(data, folder, prior_config, steps, progress=False):
        trainings.append(folder)
        training.set()
        release.wait(10)  # the other "process" tries meanwhile
        Path(folder).mkdir(parents=True)
        (Path(folder) / "prior.json").write_text("{}")

    monkeypatch.setattr(run, "train_prior_folder", slow_training)
    monkeypatch.setattr(run, "export_prior", lambda folder, kept, provenance: None)
    first = threading.Thread(target=run.prior_of, args=(grid, prior))
    first.start()
    assert training.wait(30)  # the first holds the claim and trains
    # A second process (another pid on this host) finds the claim: it must wait, then not train.
    record = json.loads(claims.claim_path(config.store, prior.name).read_text())
    assert record["host"] == socket.gethostname()
    waits = []
    monkeypatch.setattr(claims.time, "sleep", lambda seconds: (waits.append(seconds), release.set(), first.join()))
    assert run.prior_of(grid, prior) is False
    assert len(trainings) == 1 and waits and store.read_result(config.store, prior) is not None


def test_a_learner_trained_on_data_its_data_cell_no_longer_records_is_flagged_and_recomputed(tmp_path, fake):
    from xted.pipelines.bench.report import markdown, table_rows

    config = tiny_config(tmp_path, gaps=("thigh",), columns=("Tgt+Edited",), seeds=(0,))
    run_quietly(config)
    (cell,) = plan(config).learners.values()
    assert run.pending(plan(config)) == [] and store.read_result(config.store, cell)["versions"]["jax"]
    record = store.read_result(config.store, cell.data_cell)
    store.write_result(config.store, cell.data_cell, {**record, "data_fingerprint": "remade-differently"})
    (row,) = table_rows(plan(config))
    assert row["trained_on_other_data"] == 1 and "trained on other data" in markdown([row])
    assert [[c.key for c in group] for group in run.pending(plan(config))] == [[cell.key]]


def test_an_edit_remade_in_other_bytes_is_one_more_make_and_its_learners_stay_current(tmp_path, fake, monkeypatch):
    from xted.pipelines.bench.report import table_rows

    config = tiny_config(tmp_path, gaps=("thigh",), columns=("Tgt+Edited",), seeds=(0,))
    run_quietly(config)
    (cell,) = plan(config).learners.values()
    first = store.read_result(config.store, cell.data_cell)
    # A fresh checkout (no cache) remakes the edit; another CPU rounds differently.
    shutil.rmtree(config.cache)
    monkeypatch.setattr(cells, "edited", lambda cell, source: dataclasses.replace(
        source, rewards=shifted_edit(cell, source).rewards + np.float32(1e-3)))
    computed = run_quietly(dataclasses.replace(config, seeds=(0, 1)))  # seed 1 reads the edit: remade
    assert [name.startswith("edit-") for name in computed] == [True, False] and fake.calls[-1] == [1]
    record = store.read_result(config.store, cell.data_cell)
    assert record["data_fingerprint"] == first["data_fingerprint"] and len(record["remade"]) == 1
    assert record["remade"][0]["data_fingerprint"] != first["data_fingerprint"] and record["remade"][0]["machine"]
    assert store.current_result(config.store, cell) is not None
    (row,) = table_rows(plan(config))
    assert not row["trained_on_other_data"]
    # The cache now holds the remake, which is one of the record's makes: used, not made a third time.
    assert run.cached_data(plan(config), cell.data_cell).fingerprint() == record["remade"][0]["data_fingerprint"]


@pytest.mark.parametrize("old, new", [
    (["--envs", "walker2d", "--report", "--json"], "`xted bench report --envs walker2d --json`"),
    (["--envs", "walker2d", "--columns", "Tgt"], "`xted bench run --envs walker2d --columns Tgt`"),
])
def test_the_one_command_form_is_refused_with_its_new_spelling(tmp_path, capsys, old, new):
    assert main(["bench", *old]) == 2
    assert new in capsys.readouterr().err


def test_prune_lists_and_removes_the_stored_files_of_no_cell_of_the_grid(tmp_path, fake, capsys):
    from pathlib import Path

    config = tiny_config(tmp_path, gaps=("thigh",), columns=("Tgt", "Tgt+Edited"), seeds=(0,))
    run_quietly(config)
    kept = sorted(Path(config.store).glob("*/*.json"))
    assert len(kept) == 3  # Tgt, Tgt+Edited and the edit they read
    old = Path(config.store) / "halfcheetah" / "medium-replay-tgt-iql-seed0-000000000000.json"
    old.write_text("{}")  # a cell of settings no longer planned
    options = ["--envs", "halfcheetah", "--gaps", "thigh", "--columns", "Tgt,Tgt+Edited", "--seeds", "0", "--steps",
               "10", "--eval-every", "10", "--eval-episodes", "1", "--transitions", "200", "--store", config.store,
               "--cache", config.cache]
    assert main(["bench", "prune", *options]) == 0
    assert f"stale: {old}" in capsys.readouterr().out and old.exists()
    assert main(["bench", "prune", *options, "--remove"]) == 0
    assert "1 stored files match no cell of this grid; removed" in capsys.readouterr().out
    assert sorted(Path(config.store).glob("*/*.json")) == kept


def test_priors_only_trains_the_grid_s_priors_and_nothing_else(tmp_path, monkeypatch):
    from pathlib import Path

    config = tiny_config(tmp_path, targets=("medium",), gaps=("thigh", "gravity"), columns=("Tgt", "Tgt+Edited"),
                         seeds=(0,), transitions=2500, prior_steps=3)
    trained = []

    def training(data, folder, prior_config, steps, progress=False):
        trained.append(folder)
        Path(folder).mkdir(parents=True)
        (Path(folder) / "prior.json").write_text("{}")

    monkeypatch.setattr(run, "train_prior_folder", training)
    monkeypatch.setattr(run, "export_prior", lambda folder, kept, provenance: None)
    names = run.run_bench(config, progress=False, echo=lambda line: None, priors_only=True)
    (prior,) = {cell.name for cell in plan(config).cells() if isinstance(cell, run.PriorCell)}
    assert names == [prior] and len(trained) == 1
    assert len(run.pending(plan(config))) == 3  # no learner trained (Tgt; Tgt+Edited per gap)
    assert all(store.read_result(config.store, cell) is None for cell in plan(config).cells()
               if isinstance(cell, run.DataCell))  # and no edit made
    assert run.run_bench(config, progress=False, echo=lambda line: None, priors_only=True) == []


def test_a_column_set_name_stands_for_its_columns(tmp_path, capsys):
    from xted.pipelines.bench.columns import HEAD_TO_HEAD_COLUMNS, expand_column_sets

    assert expand_column_sets(("head-to-head",)) == HEAD_TO_HEAD_COLUMNS
    assert expand_column_sets(("Tgt", "table")).count("Tgt") == 1
    assert main(["bench", "report", "--envs", "halfcheetah", "--gaps", "thigh", "--columns", "head-to-head",
                 "--store", str(tmp_path / "store"), "--cache", str(tmp_path / "cache")]) == 0
    header = capsys.readouterr().out.splitlines()[0]
    assert all(f" {column} |" in header for column in HEAD_TO_HEAD_COLUMNS)
    assert main(["bench", "report", "--columns", "head-to-tail", "--store", str(tmp_path / "store")]) == 2
