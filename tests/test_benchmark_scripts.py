"""Every benchmark and maintainers' script still imports and parses its options (a renamed library
name breaks a script silently otherwise: they run by hand, weeks apart); the cheapest runs end to end."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).parent.parent
HELPERS = {"timing.py"}  # imported by the scripts, not run
SCRIPTS = sorted(p for folder in ("benchmarks", "tools") for p in (ROOT / folder).glob("*.py") if p.name not in HELPERS)


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, cwd=ROOT, timeout=300)


@pytest.mark.slow  # 20 interpreters starting, ~30 s in all
@pytest.mark.parametrize("script", SCRIPTS, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_script_imports_and_shows_its_usage(script):
    result = _run(str(script), "--help")
    assert result.returncode == 0, result.stderr[-2000:]
    assert "usage:" in result.stdout


def test_state_stats_runs_on_shipped_data():
    result = _run("benchmarks/state_stats.py", "halfcheetah-thigh")
    assert result.returncode == 0, result.stderr[-2000:]
    assert "halfcheetah-thigh" in result.stdout and "%" in result.stdout


def _git(repo: Path, *args: str) -> str:
    return subprocess.run(["git", *args], cwd=repo, capture_output=True, text=True, check=True).stdout


@pytest.fixture
def unattended(tmp_path, monkeypatch):
    """tools/bench_unattended.py as a module, working on a git repository in ``tmp_path`` that holds a
    committed result and a BENCHMARKS.md with one stale report block."""
    import importlib.util

    for variable in ("GIT_AUTHOR_NAME", "GIT_AUTHOR_EMAIL", "GIT_COMMITTER_NAME", "GIT_COMMITTER_EMAIL"):
        monkeypatch.setenv(variable, "t")
    (tmp_path / "benchmarks" / "results" / "bench").mkdir(parents=True)
    (tmp_path / "benchmarks" / "results" / "bench" / "old.json").write_text("{}\n")
    (tmp_path / "BENCHMARKS.md").write_text("# Results\n\n<!-- xted bench report --envs halfcheetah --gaps thigh "
                                            "--columns Tgt --compact -->\na stale table\n<!-- end of the report -->\n")
    _git(tmp_path, "init", "-q")
    _git(tmp_path, "add", ".")
    _git(tmp_path, "commit", "-qm", "start")
    spec = importlib.util.spec_from_file_location("bench_unattended", ROOT / "tools" / "bench_unattended.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    monkeypatch.setattr(module, "ROOT", tmp_path)
    return module


def test_the_unattended_runner_commits_new_results_with_the_report_blocks_refreshed(tmp_path, unattended):
    assert not unattended.commit_results("nothing new", ["BENCHMARKS.md"])
    (tmp_path / "benchmarks" / "results" / "bench" / "new.json").write_text("{}\n")
    (tmp_path / "notes.txt").write_text("not the runner's\n")
    assert unattended.commit_results("run 1 ended", ["BENCHMARKS.md"])
    committed = _git(tmp_path, "show", "--name-only", "--format=%s", "HEAD").split()
    assert "benchmarks/results/bench/new.json" in committed and "BENCHMARKS.md" in committed
    assert "notes.txt" not in committed and "(run 1 ended;" in _git(tmp_path, "log", "-1", "--format=%s")
    assert "a stale table" not in (tmp_path / "BENCHMARKS.md").read_text()
    assert "| halfcheetah medium-replay thigh | not run (26.2) |" in (tmp_path / "BENCHMARKS.md").read_text()


def test_the_unattended_runner_never_commits_a_document_with_edits_of_its_own(tmp_path, unattended):
    edited = (tmp_path / "BENCHMARKS.md").read_text() + "\nA paragraph being written.\n"
    (tmp_path / "BENCHMARKS.md").write_text(edited)
    (tmp_path / "benchmarks" / "results" / "bench" / "new.json").write_text("{}\n")
    assert unattended.commit_results("periodic", ["BENCHMARKS.md"])
    assert _git(tmp_path, "show", "--name-only", "--format=", "HEAD").split() == ["benchmarks/results/bench/new.json"]
    assert (tmp_path / "BENCHMARKS.md").read_text() == edited
    assert _git(tmp_path, "status", "--porcelain").split() == ["M", "BENCHMARKS.md"]


def test_edit_rules_scores_each_rule_s_picks(tmp_path):
    measured = {"simulator_mae": 1.0, "target_distance": 3.0, "forward_velocity": 9.0, "return_per_1000_steps": 9000.0}
    rows = [{"env": "halfcheetah", "target": "medium-replay", "gap": "thigh", "variant": "Tgt+Src", "score": 20.0,
             **measured},
            # the edit is worse in the simulator, slower (nearer the target's speed) and scores higher
            {"env": "halfcheetah", "target": "medium-replay", "gap": "thigh", "variant": "Tgt+Edited", "score": 30.0,
             **measured, "simulator_mae": 2.0, "forward_velocity": 4.0},
            {"env": "halfcheetah", "target": "medium-replay", "gap": "gravity", "variant": "Tgt+Src", "score": None,
             **measured}]
    path = tmp_path / "rows.jsonl"
    path.write_text("".join(json.dumps(row) + "\n" for row in rows))
    result = _run("benchmarks/edit_rules.py", str(path))
    assert result.returncode == 0, result.stderr[-2000:]
    assert "| halfcheetah medium-replay thigh | 20.0 | 30.0 | no | yes | no | no |" in result.stdout
    assert "over 1 tasks" in result.stdout
    assert "| simulator | 20.0 | +0.0% | 0 of 1 |" in result.stdout
    assert "| speed | 30.0 | +50.0% | 1 of 1 |" in result.stdout
    empty = tmp_path / "empty.jsonl"
    empty.write_text(json.dumps(rows[0]) + "\n")
    refused = _run("benchmarks/edit_rules.py", str(empty))
    assert refused.returncode == 2 and "no task with both" in refused.stderr
