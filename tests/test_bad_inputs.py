"""The bad-input table (docs/bad_inputs.md): every misuse tried, each a row here and a test.

A row builds its inputs in an empty workspace and runs one ``xted`` command. It holds when the
command exits with the row's code, the message names what is wrong (the row's phrase), no
traceback is printed, and the workspace afterwards holds exactly the files it held before, each
unchanged: inputs are never modified and nothing partial is left.

``python tests/test_bad_inputs.py`` runs every row and prints the markdown table of the answers.
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import dataclasses
import hashlib
import io
import os
import resource
import signal
import subprocess
import sys
import tempfile
import traceback
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from conftest import build_dataset

import xted
from xted.cli.main import main
from xted.data import formats, shipped
from xted.diffusion.guard import ENSEMBLE_FILE, TARGET_MODEL_FILE

DOC = Path(__file__).parent.parent / "docs" / "bad_inputs.md"
HC_PRIOR = "halfcheetah-medium-replay-cpu"
CLONE_NEWUSER = 0x10000000


@dataclasses.dataclass(frozen=True)
class Case:
    name: str
    what: str  # the misuse, in words
    build: Callable[[Path], list[str]]  # makes the inputs in the workspace; returns the xted arguments
    says: str  # a phrase the answer must contain (case-insensitive)
    limit: str | None = None  # run in a subprocess as an unprivileged user ("read_only") or with a file-size cap
    code: int = 2


def _tiny(ws: Path, name: str = "tiny.npz", **kwargs) -> str:
    path = ws / name
    formats.save(build_dataset(**kwargs), path)
    return str(path)


def _document(ws: Path, text: str, name: str = "notes.md") -> str:
    (ws / name).write_text(text)
    return str(ws / name)


def _block(ws: Path, options: str) -> str:
    """A report block over an empty store in the workspace, holding a stale table."""
    return f"<!-- xted bench report --store {ws / 'store'} {options} -->\nold table\n<!-- end of the report -->\n"


def _step_file(ws: Path, returns: str) -> str:
    """A user's step function file ``robot.py`` whose ``step`` returns ``returns``; its ``FILE:step`` name."""
    (ws / "robot.py").write_text(f"def step(observations, actions):\n    return {returns}\n")
    return f"{ws / 'robot.py'}:step"


def _arrays(ws: Path, name: str, **changes) -> str:
    data = build_dataset(lengths=(30, 30))
    arrays = {k: getattr(data, k) for k in ("observations", "actions", "rewards", "terminals", "timeouts")}
    np.savez(ws / name, **{k: changes[k](v) if k in changes else v for k, v in arrays.items()})
    return str(ws / name)


def _next_equal_to_observations(ws: Path) -> str:
    data = build_dataset(lengths=(30, 30))
    arrays = {k: getattr(data, k) for k in ("observations", "actions", "rewards", "terminals", "timeouts")}
    np.savez(ws / "same.npz", next_observations=data.observations, **arrays)
    return str(ws / "same.npz")


def _with(array: np.ndarray, index: tuple, value: float) -> np.ndarray:
    array = array.copy()
    array[index] = value
    return array


def _halfcheetah_like(ws: Path, name: str, steps: int = 5000, env: str = "HalfCheetah-v5") -> str:
    data = build_dataset(lengths=(steps,), obs_dim=17, act_dim=6)
    formats.save(data.with_metadata(env=env), ws / name)
    return str(ws / name)


def _nested_hdf5(ws: Path) -> str:
    import h5py

    with h5py.File(ws / "nested.hdf5", "w") as file:
        group = file.create_group("data")
        group["observations"], group["actions"] = np.zeros((5, 3)), np.zeros((5, 2))
    return str(ws / "nested.hdf5")


def _reward_free(ws: Path, name: str, obs_dim: int = 3, act_dim: int = 2) -> str:
    data = build_dataset(lengths=(30, 30), obs_dim=obs_dim, act_dim=act_dim)
    formats.save(dataclasses.replace(data, rewards=None, metadata={}), ws / name)
    return str(ws / name)


def _rewards_flagged_absent(ws: Path) -> str:
    data = build_dataset(lengths=(30, 30))
    arrays = {k: getattr(data, k) for k in ("observations", "actions", "rewards", "terminals", "timeouts")}
    np.savez(ws / "flagged.npz", **arrays, metadata=np.array('{"reward_free": true}'))
    return str(ws / "flagged.npz")


def _hdf5_text(ws: Path) -> str:
    (ws / "notes.hdf5").write_text("these are my notes, not an HDF5 file\n")
    return str(ws / "notes.hdf5")


def _truncated_hdf5(ws: Path) -> str:
    path = ws / "cut.hdf5"
    formats.save(build_dataset(lengths=(200, 200)), path)
    path.write_bytes(path.read_bytes()[:3000])
    return str(path)


def _online_run(ws: Path) -> Path:
    run = ws / "run"
    code = main(["online", "train", "--env", "halfcheetah", "--out", str(run), "--steps", "50", "--start-steps", "50",
                 "--checkpoint-every", "50", "--eval-episodes", "1"])
    assert code == 0
    return run


def _fake_prior(ws: Path, corrupt: str | None) -> str:
    """A copy of the shipped prior, with one file spoiled: ``record`` (prior.json), ``params``,
    ``target_model`` (the guard's), ``no_target_model`` (it removed: a prior from before the guard),
    ``ensemble`` (the guard's ensemble), ``no_ensemble`` (it removed: a prior from before it) or None."""
    import shutil

    folder = ws / "prior"
    shutil.copytree(shipped.prior_dir(HC_PRIOR), folder)
    if corrupt == "record":
        (folder / "prior.json").write_text("{ not json")
    elif corrupt == "params":
        params = sorted(p for p in folder.rglob("*")
                        if p.is_file() and p.name not in ("prior.json", TARGET_MODEL_FILE, ENSEMBLE_FILE))
        biggest = max(params, key=lambda p: p.stat().st_size)
        biggest.write_bytes(biggest.read_bytes()[:100])
    elif corrupt == "target_model":
        (folder / TARGET_MODEL_FILE).write_bytes((folder / TARGET_MODEL_FILE).read_bytes()[:100])
    elif corrupt == "no_target_model":
        (folder / TARGET_MODEL_FILE).unlink()
    elif corrupt == "ensemble":
        (folder / ENSEMBLE_FILE).write_bytes((folder / ENSEMBLE_FILE).read_bytes()[:100])
    elif corrupt == "no_ensemble":
        (folder / ENSEMBLE_FILE).unlink()
    return str(folder)


POLICY_QUICK = ["--env", "halfcheetah", "--steps", "10", "--eval-every", "10", "--eval-episodes", "1"]


def _results_of_other_data(ws: Path) -> str:
    """A --out folder holding a finished seed of a policy trained on another dataset."""
    out = ws / "results"
    assert main(["policy", "--target", _halfcheetah_like(ws, "other.npz", 1000), *POLICY_QUICK, "--out", str(out)]) == 0
    return str(out)


def _policies_of_other_data(ws: Path) -> str:
    """A --save folder holding a saved policy trained on another dataset."""
    out = ws / "policies"
    assert main(["policy", "--target", _halfcheetah_like(ws, "other.npz", 1000), *POLICY_QUICK, "--save", str(out)]) == 0
    return str(out)


def _not_a_run(ws: Path) -> str:
    folder = ws / "my-notes"
    folder.mkdir()
    (folder / "thesis.tex").write_text("chapter 1")
    return str(folder)


def _shipped_prior() -> str:
    return str(shipped.prior_dir(HC_PRIOR))


CASES = [
    Case("missing-file", "a dataset path that does not exist", lambda ws: ["data", "info", str(ws / "nope.npz")],
         "no such file"),
    Case("csv-file", "a .csv file given as a dataset", lambda ws: (ws / "d.csv").write_text("a,b\n1,2\n") and
         ["data", "info", str(ws / "d.csv")], "unknown extension"),
    Case("text-as-hdf5", "a text file named .hdf5", lambda ws: ["data", "info", _hdf5_text(ws)], "hdf5"),
    Case("hdf5-arrays-in-a-group", "an HDF5 file whose arrays sit under a /data/ group, not at the root",
         lambda ws: ["data", "info", _nested_hdf5(ws)], "the file holds /data/observations"),
    Case("truncated-hdf5", "an HDF5 file cut short", lambda ws: ["data", "info", _truncated_hdf5(ws)], "cut.hdf5"),
    Case("empty-npz", "an .npz holding no arrays", lambda ws: np.savez(ws / "e.npz") or
         ["data", "info", str(ws / "e.npz")], "e.npz"),
    Case("zero-steps", "a dataset of zero steps", lambda ws: ["data", "info", _arrays(
        ws, "z.npz", **{k: (lambda a: a[:0]) for k in ("observations", "actions", "rewards", "terminals", "timeouts")})],
        "z.npz"),
    Case("nan-observation", "NaN in the observations", lambda ws: ["data", "info", _arrays(
        ws, "nan.npz", observations=lambda a: _with(a, (7, 1), np.nan))], "observations"),
    Case("inf-reward", "an infinite reward", lambda ws: ["data", "info", _arrays(
        ws, "inf.npz", rewards=lambda a: _with(a, (3,), np.inf))], "rewards"),
    Case("next-equals-observations", "next_observations equal to observations in every row (a logging off-by-one)",
         lambda ws: ["data", "info", _next_equal_to_observations(ws)], "next_observations equals observations"),
    Case("length-mismatch", "actions one row shorter than observations", lambda ws: ["data", "info", _arrays(
        ws, "short.npz", actions=lambda a: a[:-1])], "actions"),
    Case("unknown-shipped-name", "a dataset name that is neither a file nor shipped",
         lambda ws: ["data", "info", "halfcheetah-mediun"], "halfcheetah-mediun"),
    Case("output-is-input", "convert a file onto itself", lambda ws: ["data", "convert", _tiny(ws), _tiny(ws)],
         "is the source input"),
    Case("output-inside-input", "convert a Minari dataset into a file inside its own folder",
         lambda ws: formats.save(build_dataset(), ws / "mds") and ["data", "convert", str(ws / "mds"),
                                                                    str(ws / "mds" / "copy.npz")], "inside"),
    Case("edit-output-in-prior", "write the edit into the prior's folder",
         lambda ws: ["edit", "--prior", _fake_prior(ws, None), "--source", _halfcheetah_like(ws, "s.npz", 100),
                     "--out", str(ws / "prior" / "edited.npz")], "inside"),
    Case("output-exists", "an existing output without --force",
         lambda ws: ["data", "convert", _tiny(ws), _tiny(ws, "old.npz", seed=1)], "exists"),
    Case("output-folder-is-a-file", "an output path under a regular file",
         lambda ws: ["data", "convert", _tiny(ws), str(Path(_tiny(ws, "f.npz")) / "out.npz")], "f.npz"),
    Case("read-only-folder", "an output folder the user may not write",
         lambda ws: (ws / "locked").mkdir(mode=0o555) or ["data", "convert", _tiny(ws), str(ws / "locked" / "o.npz")],
         "permission denied", limit="read_only"),
    Case("full-disk-npz", "the disk fills while an .npz is written (a file-size cap)",
         lambda ws: ["data", "convert", _halfcheetah_like(ws, "big.hdf5", 20_000), str(ws / "copy.npz")],
         "file too large", limit="file_size"),
    Case("full-disk-hdf5", "the disk fills while an HDF5 file is written (a file-size cap)",
         lambda ws: ["data", "convert", _halfcheetah_like(ws, "big.npz", 20_000), str(ws / "copy.hdf5")],
         "file too large", limit="file_size"),
    Case("edit-wrong-dims", "edit a 3-d source with a 17-d prior",
         lambda ws: ["edit", "--prior", _shipped_prior(), "--source", _tiny(ws), "--out", str(ws / "o.npz"),
                     "--allow-env-mismatch"], "3-d observations and 2-d actions"),
    Case("edit-other-env", "edit walker2d data with a halfcheetah prior (same dimensions)",
         lambda ws: ["edit", "--prior", _shipped_prior(), "--source", _halfcheetah_like(ws, "w.npz", 100, "Walker2d-v5"),
                     "--out", str(ws / "o.npz")], "walker2d"),
    Case("edit-overwrites-input", "--out names the --relabel-rewards input, with --force",
         lambda ws: ["edit", "--prior", _shipped_prior(), "--source", _halfcheetah_like(ws, "s.npz", 100), "--out",
                     _halfcheetah_like(ws, "t.npz", 100), "--relabel-rewards", str(ws / "t.npz"), "--force"],
         "inputs are never overwritten"),
    Case("edit-project-dynamics-wrong-dims", "--project-dynamics names 3-d data for a 17-d source",
         lambda ws: ["edit", "--prior", _shipped_prior(), "--source", _halfcheetah_like(ws, "s.npz", 100), "--out",
                     str(ws / "o.npz"), "--project-dynamics", _tiny(ws)], "--project-dynamics"),
    Case("edit-project-dynamics-is-output", "--out names the --project-dynamics input, with --force",
         lambda ws: ["edit", "--prior", _shipped_prior(), "--source", _halfcheetah_like(ws, "s.npz", 100), "--out",
                     _halfcheetah_like(ws, "t.npz", 100), "--project-dynamics", str(ws / "t.npz"), "--force"],
         "inputs are never overwritten"),
    Case("edit-step-function-missing", "--project-dynamics names a step function in a file that does not exist",
         lambda ws: ["edit", "--prior", _shipped_prior(), "--source", _halfcheetah_like(ws, "s.npz", 100), "--out",
                     str(ws / "o.npz"), "--project-dynamics", f"{ws / 'robot.py'}:step"], "no file"),
    Case("edit-step-function-wrong-shape", "a step function returning next observations of another shape",
         lambda ws: ["edit", "--prior", _shipped_prior(), "--source", _halfcheetah_like(ws, "s.npz", 100), "--out",
                     str(ws / "o.npz"), "--no-guard", "--project-dynamics", _step_file(ws, "observations[:, :3]")],
         "it must return next observations"),
    Case("edit-kappa-range", "--kappa 1.5", lambda ws: ["edit", "--prior", _shipped_prior(), "--source", _tiny(ws),
                                                         "--out", str(ws / "o.npz"), "--kappa", "1.5"],
         "kappa must be in [0, 1]"),
    Case("edit-ddpm-sampler-steps", "--sampler-steps with the DDPM sampler",
         lambda ws: ["edit", "--prior", _shipped_prior(), "--source", _halfcheetah_like(ws, "s.npz", 100),
                     "--out", str(ws / "o.npz"), "--sampler-steps", "10"], "sampler_steps"),
    Case("edit-ddpm-eta", "--eta with the DDPM sampler",
         lambda ws: ["edit", "--prior", _shipped_prior(), "--source", _halfcheetah_like(ws, "s.npz", 100),
                     "--out", str(ws / "o.npz"), "--eta", "0.5"], "eta is for the ddim sampler only"),
    Case("edit-negative-temperature", "--temperature -1",
         lambda ws: ["edit", "--prior", _shipped_prior(), "--source", _halfcheetah_like(ws, "s.npz", 100),
                     "--out", str(ws / "o.npz"), "--temperature", "-1"], "temperature must be >= 0"),
    Case("missing-prior", "--prior names no folder", lambda ws: ["edit", "--prior", str(ws / "no-prior"), "--source",
                                                               _tiny(ws), "--out", str(ws / "o.npz")], "no-prior"),
    Case("corrupt-prior-record", "a prior whose prior.json is not JSON",
         lambda ws: ["edit", "--prior", _fake_prior(ws, "record"), "--source", _halfcheetah_like(ws, "s.npz", 100),
                     "--out", str(ws / "o.npz")], "prior.json"),
    Case("corrupt-prior-params", "a prior whose parameters file is truncated",
         lambda ws: ["edit", "--prior", _fake_prior(ws, "params"), "--source", _halfcheetah_like(ws, "s.npz", 100),
                     "--out", str(ws / "o.npz")], "prior"),
    Case("edit-corrupt-target-model", "a prior whose guard model file is truncated",
         lambda ws: ["edit", "--prior", _fake_prior(ws, "target_model"), "--source", _halfcheetah_like(ws, "s.npz", 100),
                     "--out", str(ws / "o.npz")], "unreadable target model"),
    Case("edit-guard-without-target-model", "the guarded edit with a prior that holds no target model",
         lambda ws: ["edit", "--prior", _fake_prior(ws, "no_target_model"), "--source",
                     _halfcheetah_like(ws, "s.npz", 100), "--out", str(ws / "o.npz")], "--target"),
    Case("edit-only-short-episodes", "edit a source whose every episode is shorter than the prior's windows",
         lambda ws: ["edit", "--prior", _shipped_prior(), "--source", _halfcheetah_like(ws, "s.npz", 10),
                     "--out", str(ws / "o.npz")], "shorter than the prior's windows"),
    Case("edit-outside-support-value", "--outside-support sideways",
         lambda ws: ["edit", "--prior", _shipped_prior(), "--source", _halfcheetah_like(ws, "s.npz", 100),
                     "--out", str(ws / "o.npz"), "--outside-support", "sideways"], "outside_support must be one of"),
    Case("edit-negative-guard-margin", "--guard-margin -1",
         lambda ws: ["edit", "--prior", _shipped_prior(), "--source", _halfcheetah_like(ws, "s.npz", 100),
                     "--out", str(ws / "o.npz"), "--guard-margin", "-1"], "guard_margin must be >= 0"),
    Case("edit-negative-guard-disagreement", "--guard-disagreement -1",
         lambda ws: ["edit", "--prior", _shipped_prior(), "--source", _halfcheetah_like(ws, "s.npz", 100),
                     "--out", str(ws / "o.npz"), "--guard-disagreement", "-1"], "guard_disagreement must be >= 0"),
    Case("edit-disagreement-without-ensemble", "--guard-disagreement 0.5 with a prior that holds no ensemble",
         lambda ws: ["edit", "--prior", _fake_prior(ws, "no_ensemble"), "--source", _halfcheetah_like(ws, "s.npz", 100),
                     "--out", str(ws / "o.npz"), "--guard-disagreement", "0.5"], "ensemble"),
    Case("edit-plan-negative-guard-disagreement", "xted analyze edit-plan --guard-disagreement -1",
         lambda ws: ["analyze", "edit-plan", "--prior", _shipped_prior(), "--guard-disagreement", "-1",
                     _halfcheetah_like(ws, "s.npz", 100)], "guard_disagreement must be >= 0"),
    Case("edit-plan-disagreement-without-ensemble",
         "xted analyze edit-plan --guard-disagreement 0.5 with a prior that holds no ensemble, without --target",
         lambda ws: ["analyze", "edit-plan", "--prior", _fake_prior(ws, "no_ensemble"), "--guard-disagreement", "0.5",
                     _halfcheetah_like(ws, "s.npz", 100)], "ensemble"),
    Case("edit-corrupt-ensemble", "a prior whose guard ensemble file is truncated",
         lambda ws: ["edit", "--prior", _fake_prior(ws, "ensemble"), "--source", _halfcheetah_like(ws, "s.npz", 100),
                     "--out", str(ws / "o.npz")], "unreadable target model ensemble"),
    Case("train-one-step-episodes", "train a prior on one-step episodes",
         lambda ws: ["train", "--target", _tiny(ws, lengths=(1,) * 40), "--out", str(ws / "p"), "--steps", "1"],
         "horizon"),
    Case("train-short-episodes", "train a prior on episodes shorter than the horizon (H = 20)",
         lambda ws: ["train", "--target", _tiny(ws, lengths=(12, 15, 19)), "--out", str(ws / "p"), "--steps", "1"],
         "horizon"),
    Case("train-bool-override", "--set return_condition=tru (not a boolean)",
         lambda ws: ["train", "--target", _tiny(ws), "--out", str(ws / "p"), "--set", "return_condition=tru"],
         "not a boolean"),
    Case("train-kappa-max-range", "--set train_kappa_max=0 (no noise level to train on)",
         lambda ws: ["train", "--target", _tiny(ws), "--out", str(ws / "p"), "--set", "train_kappa_max=0"],
         "train_kappa_max must be in (0, 1]"),
    Case("train-cross-blocks-zero", "--set cross_blocks=0 (no cross-attention round)",
         lambda ws: ["train", "--target", _tiny(ws), "--out", str(ws / "p"), "--set", "cross_blocks=0"],
         "cross_blocks must be >= 1"),
    Case("train-unknown-field", "--set a field the config does not have",
         lambda ws: ["train", "--target", _tiny(ws), "--out", str(ws / "p"), "--set", "widht=3"], "widht"),
    Case("train-zero-steps", "--steps 0", lambda ws: ["train", "--target", _tiny(ws), "--out", str(ws / "p"),
                                                     "--steps", "0"], "--steps"),
    Case("policy-other-env", "a halfcheetah target evaluated in walker2d",
         lambda ws: ["policy", "--target", "halfcheetah-medium", "--env", "walker2d", "--steps", "10"], "walker2d"),
    Case("policy-bad-seeds", "--seeds a,b", lambda ws: ["policy", "--target", _tiny(ws), "--env", "halfcheetah",
                                                       "--seeds", "a,b"], "--seeds"),
    Case("policy-other-results", "--out holds results of other data",
         lambda ws: ["policy", "--target", _halfcheetah_like(ws, "t.npz", 900), *POLICY_QUICK,
                     "--out", _results_of_other_data(ws)], "data:"),
    Case("policy-force-not-a-run", "--force on a folder that holds no results",
         lambda ws: ["policy", "--target", _halfcheetah_like(ws, "t.npz", 1000), *POLICY_QUICK,
                     "--out", _not_a_run(ws), "--force"], "refusing to delete"),
    Case("analyze-step-function-no-function", "--env names a function its file does not define",
         lambda ws: ["analyze", "dynamics", _tiny(ws), "--env", f"{_step_file(ws, 'observations')[:-5]}:stepp"],
         "has no function stepp"),
    Case("analyze-step-function-with-gap", "--gap with a step function",
         lambda ws: ["analyze", "dynamics", _tiny(ws), "--env", _step_file(ws, "observations"), "--gap", "gravity"],
         "--gap names a domain"),
    Case("analyze-ant-contact-forces", "Ant-v5 data recorded with its contact forces (105-d observations)",
         lambda ws: ["analyze", "dynamics", _tiny(ws, obs_dim=105, act_dim=8), "--env", "Ant-v5"],
         "include_cfrc_ext_in_observation=False"),
    Case("analyze-ant-thigh-gap", "--gap thigh for ant, whose legs have no thigh",
         lambda ws: ["analyze", "dynamics", _tiny(ws, obs_dim=27, act_dim=8), "--env", "ant", "--gap", "thigh"],
         "ant has no thigh gap"),
    Case("content-target-other-dims", "analyze content --target with data of other observation dims than the source",
         lambda ws: ["analyze", "content", _tiny(ws), _tiny(ws), "--target", _tiny(ws, "t.npz", obs_dim=5)],
         "5-d observations, the source 3-d"),
    Case("policy-no-env-no-save", "data of no known env, trained without --save (nothing would be kept)",
         lambda ws: ["policy", "--target", _tiny(ws), "--steps", "10"], "give --save DIR"),
    Case("policy-env-none-no-save", "--env none without --save",
         lambda ws: ["policy", "--target", _halfcheetah_like(ws, "t.npz", 100), "--env", "none", "--steps", "10"],
         "give --save DIR"),
    Case("policy-gap-without-env", "--gap with --env none",
         lambda ws: ["policy", "--target", _halfcheetah_like(ws, "t.npz", 100), "--env", "none", "--gap", "thigh",
                     "--save", str(ws / "p")], "give --env too"),
    Case("policy-save-other-run", "--save holds policies of other data",
         lambda ws: ["policy", "--target", _halfcheetah_like(ws, "t.npz", 900), *POLICY_QUICK,
                     "--save", _policies_of_other_data(ws)], "data:"),
    Case("policy-save-is-a-file", "--save names a file",
         lambda ws: ["policy", "--target", _halfcheetah_like(ws, "t.npz", 100), *POLICY_QUICK,
                     "--save", _tiny(ws)], "not a folder"),
    Case("policy-rl-without-rewards", "IQL on reward-free data",
         lambda ws: ["policy", "--algo", "iql", "--target", _reward_free(ws, "demos.npz"), "--env", "none",
                     "--save", str(ws / "p")], "iql needs rewards"),
    Case("policy-filter-without-source", "IGDF (a source filter) with no source dataset",
         lambda ws: ["policy", "--algo", "igdf", "--target", _halfcheetah_like(ws, "t.npz", 100), *POLICY_QUICK],
         "give at least one source"),
    Case("policy-filter-keep-share", "OTDF keeping a share above 1 of each batch's source",
         lambda ws: ["policy", "--algo", "otdf", "--target", _halfcheetah_like(ws, "t.npz", 100), *POLICY_QUICK,
                     "--set", "keep_fraction=1.5"], "keep_fraction"),
    Case("bench-prior-set-shipped-prior", "bench --prior-set where each target of the env has a shipped prior (never trained)",
         lambda ws: ["bench", "run", "--envs", "walker2d", "--columns", "Tgt+Edited", "--prior-set",
                     "walker2d:cross_blocks=2", "--store", str(ws / "s")], "changes only the priors it trains"),
    Case("bench-filter-unknown-field", "bench --set igdf.FIELD=VALUE with a field IGDF does not have",
         lambda ws: ["bench", "run", "--columns", "Tgt+Src IGDF", "--set", "igdf.xi=0.3", "--store", str(ws / "s")],
         "xi"),
    Case("train-reward-stream-without-rewards", "a prior with a reward stream on reward-free data",
         lambda ws: ["train", "--target", _reward_free(ws, "demos.npz"), "--out", str(ws / "p"),
                     "--set", "use_reward=true"], "needs rewards"),
    Case("edit-reward-prior-reward-free-source", "a reward-modelling prior editing a reward-free source",
         lambda ws: ["edit", "--prior", HC_PRIOR, "--source", _reward_free(ws, "demos.npz", 17, 6),
                     "--out", str(ws / "e.npz")], "needs rewards"),
    Case("reward-free-flag-with-rewards", "metadata says reward-free, the file holds nonzero rewards",
         lambda ws: ["data", "info", _rewards_flagged_absent(ws)], "nonzero entries"),
    Case("render-unknown-format", "render to a .avi file",
         lambda ws: ["render", "--env", "halfcheetah", _halfcheetah_like(ws, "s.npz", 100), "--out", str(ws / "v.avi")],
         ".avi"),
    Case("render-episode-range", "render episode 5 of a one-episode dataset",
         lambda ws: ["render", "--env", "halfcheetah", _halfcheetah_like(ws, "s.npz", 100), "--episode", "5",
                     "--out", str(ws / "v.gif")], "episode"),
    Case("plot-other-episodes", "plot the spectrum of a source against an edit of other episodes",
         lambda ws: ["plot", "spectrum", _halfcheetah_like(ws, "s.npz", 300), _halfcheetah_like(ws, "e.npz", 200),
                     "--out", str(ws / "s.png")], "episode"),
    Case("online-zero-steps", "online --steps 0", lambda ws: ["online", "train", "--env", "halfcheetah", "--out",
                                                             str(ws / "run"), "--steps", "0"], "--steps"),
    Case("online-zero-checkpoint", "online --checkpoint-every 0",
         lambda ws: ["online", "train", "--env", "halfcheetah", "--out", str(ws / "run"), "--checkpoint-every", "0"],
         "checkpoint_every must be positive"),
    Case("online-unknown-gap", "--gap gravty", lambda ws: ["online", "train", "--env", "halfcheetah", "--gap", "gravty",
                                                          "--out", str(ws / "run")], "gravty"),
    Case("online-shorter-resume", "resume an online run with a lower --steps",
         lambda ws: ["online", "train", "--env", "halfcheetah", "--out", str(_online_run(ws)), "--steps", "10",
                     "--start-steps", "50", "--checkpoint-every", "50", "--eval-episodes", "1"], "beyond --steps"),
    Case("online-init-not-a-run", "online --init-from a folder that holds no online run",
         lambda ws: ["online", "train", "--env", "halfcheetah", "--out", str(ws / "run"),
                     "--init-from", _tiny(ws)], "not an online run folder"),
    Case("bench-address-without-ray", "bench run --address without --executor ray",
         lambda ws: ["bench", "run", "--address", "head:6379", "--store", str(ws / "store")], "only with --executor ray"),
    Case("bench-zero-dynamics-proxy-steps", "bench run --project-dynamics --dynamics-proxy-steps 0",
         lambda ws: ["bench", "run", "--project-dynamics", "--dynamics-proxy-steps", "0", "--store", str(ws / "store")],
         "--dynamics-proxy-steps"),
    Case("bench-old-one-command-form", "the one-command bench of before: bench --report --cost",
         lambda ws: ["bench", "--report", "--cost", "--store", str(ws / "store")], "xted bench report --cost"),
    Case("bench-prior-set-unknown-env", "bench --prior-set ENV:FIELD=VALUE with an env not in the grid",
         lambda ws: ["bench", "report", "--envs", "halfcheetah", "--prior-set", "walker2d:cross_blocks=2",
                     "--store", str(ws / "store")], "is not an env in the grid"),
    Case("bench-prior-set-unknown-field", "bench --prior-set with a field PriorConfig does not have",
         lambda ws: ["bench", "report", "--prior-set", "wings=2", "--store", str(ws / "store")], "wings"),
    Case("bench-refresh-no-block", "bench refresh of a markdown file without a report block",
         lambda ws: ["bench", "refresh", _document(ws, "a table I wrote by hand\n")], "no report block"),
    Case("bench-refresh-unclosed-block", "bench refresh of a report block with no end marker",
         lambda ws: ["bench", "refresh", _document(ws, "<!-- xted bench report --compact -->\nold table\n")],
         "not closed"),
    Case("bench-refresh-json-block", "bench refresh of a report block whose options print JSON",
         lambda ws: ["bench", "refresh", _document(ws, _block(ws, "--json"))], "--json in a report block"),
    Case("bench-refresh-bad-block-options", "bench refresh of a report block with an unknown column",
         lambda ws: ["bench", "refresh", _document(ws, _block(ws, "--columns Tgt+Wings"))], "unknown column"),
    Case("bench-refresh-missing-file", "bench refresh of a file that does not exist",
         lambda ws: ["bench", "refresh", str(ws / "notes.md")], "no such file"),
    Case("bench-refresh-second-document-bad", "bench refresh of two files, the second without a report block "
         "(the first, though renderable, is not written)",
         lambda ws: ["bench", "refresh", _document(ws, _block(ws, "--columns Tgt"), "first.md"),
                     _document(ws, "no block\n", "second.md")], "second.md: no report block"),
    Case("bench-zero-ser-steps", "bench --ser-steps 0 (the Tgt SER column's model)",
         lambda ws: ["bench", "run", "--columns", "Tgt SER", "--ser-steps", "0", "--store", str(ws / "store")],
         "--ser-steps"),
    Case("data-medium-step-without-run", "data make --medium-step without --run",
         lambda ws: ["data", "make", "--env", "halfcheetah", "--level", "medium", "--medium-step", "100",
                     "--out", str(ws / "m.npz")], "--medium-step goes with --run"),
    Case("data-medium-step-not-evaluated", "data make --run RUN --medium-step at a step the run never evaluated",
         lambda ws: ["data", "make", "--env", "halfcheetah", "--level", "medium-replay", "--run", str(_online_run(ws)),
                     "--medium-step", "49", "--transitions", "10", "--out", str(ws / "m.npz")],
         "no evaluated checkpoint at that step"),
    Case("online-other-settings", "resume an online run with other settings",
         lambda ws: ["online", "train", "--env", "halfcheetah", "--out", str(_online_run(ws)), "--steps", "100",
                     "--start-steps", "40", "--checkpoint-every", "50", "--eval-episodes", "1"], "start_steps"),
]


def _snapshot(ws: Path) -> dict[str, str]:
    return {str(p.relative_to(ws)): (hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "dir")
            for p in sorted(ws.rglob("*"))}


def _limited(kind: str) -> Callable[[], None]:
    def apply() -> None:
        if kind == "file_size":
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the cap fails with EFBIG instead
            resource.setrlimit(resource.RLIMIT_FSIZE, (256 * 1024, 256 * 1024))
        elif os.geteuid() == 0:
            # Root writes anywhere. In a new user namespace it keeps its files but loses the power to
            # override their permission bits, so a folder of mode 0o555 is read-only to it too.
            libc = ctypes.CDLL(ctypes.util.find_library("c"), use_errno=True)
            if libc.unshare(CLONE_NEWUSER) != 0:
                raise OSError(ctypes.get_errno(), "unshare(CLONE_NEWUSER)")
    return apply


def _read_only_is_possible() -> bool:
    """Whether a folder can be made read-only to xted: as a user, always; as root, only where a
    process may enter a new user namespace (some containers forbid it)."""
    if os.geteuid() != 0:
        return True
    try:
        subprocess.run([sys.executable, "-c", "pass"], preexec_fn=_limited("read_only"), check=True)
    except (subprocess.SubprocessError, OSError):
        return False
    return True


def run_case(case: Case, ws: Path) -> tuple[int, str, dict[str, str], dict[str, str]]:
    """Build the row's inputs in ``ws``, run it; ``(exit code, what xted printed, files before, after)``."""
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        argv = case.build(ws)
    before = _snapshot(ws)
    if case.limit is None:
        out, err = io.StringIO(), io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = main(argv)
            except Exception:  # what the console script does with an internal error
                traceback.print_exc()
                code = 1
        text = out.getvalue() + err.getvalue()
    else:
        script = "import sys; from xted.cli.main import run; sys.argv[0] = 'xted'; run()"
        done = subprocess.run([sys.executable, "-c", script, *argv], capture_output=True, text=True,
                              preexec_fn=_limited(case.limit), cwd=ws,
                              env={**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, (
                                  str(Path(xted.__file__).parent.parent), os.environ.get("PYTHONPATH"))))})
        code, text = done.returncode, done.stdout + done.stderr
    return code, text, before, _snapshot(ws)


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_bad_input(case: Case, tmp_path: Path) -> None:
    if case.limit == "read_only" and not _read_only_is_possible():
        pytest.skip("root without user namespaces: no folder is read-only to this process")
    code, text, before, after = run_case(case, tmp_path)
    assert code == case.code, text
    assert case.says.lower() in text.lower(), text
    assert "Traceback" not in text, text
    assert after == before, "files changed or left behind"


def test_the_table_in_docs_lists_every_row():
    rows = {line.split("|")[1].strip().strip("`") for line in DOC.read_text().splitlines()
            if line.startswith("| `")}
    assert rows == {case.name for case in CASES}


def _answer(text: str) -> str:
    lines = [line.strip(" │╭╰─╮╯") for line in text.strip().splitlines()]
    lines = [line for line in lines if line and not line.startswith(("Usage:", "Try ", "Error"))]
    return " ".join(lines)[:220].replace("|", "\\|") if lines else "(nothing)"


def markdown_table() -> str:
    rows = ["| row | misuse | xted's answer | exit | nothing partial, inputs unchanged |", "|---|---|---|---|---|"]
    for case in CASES:
        with tempfile.TemporaryDirectory() as folder:
            code, text, before, after = run_case(case, Path(folder))
            text = text.replace(str(Path(folder).resolve()), "WS").replace(folder, "WS")
        rows.append(f"| `{case.name}` | {case.what} | {_answer(text)} | {code} | {'yes' if after == before else 'NO'} |")
    return "\n".join(rows)


if __name__ == "__main__":
    print(markdown_table())
