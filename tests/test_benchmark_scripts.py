"""Every benchmark and maintainers' script still imports and parses its options (a renamed library
name breaks a script silently otherwise: they run by hand, weeks apart); the cheapest runs end to end."""

from __future__ import annotations

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
