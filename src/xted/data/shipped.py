"""Datasets shipped with xted, addressable by name (``halfcheetah-medium-replay``).

The files live in ``xted/assets/datasets`` next to ``manifest.json``, which records each
file's checksum, size, returns, normalised score and the command that regenerates it.
"""

from __future__ import annotations

import json
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Any

MANIFEST_NAME = "manifest.json"

# D4RL's (v2) behaviour scores as published, normalised, for the levels we ship: what ours are made to match.
D4RL_BEHAVIOUR_SCORES = {
    "halfcheetah": {"medium-replay": 27.0, "medium": 40.0, "medium-expert": 64.0},
    "walker2d": {"medium-replay": 15.0, "medium": 62.0, "medium-expert": 82.0},
}


def d4rl_behaviour_score(name: str) -> float | None:
    """D4RL's behaviour score of the dataset of that name (``walker2d-medium``), None where D4RL has no such level."""
    env, _, level = name.partition("-")
    return D4RL_BEHAVIOUR_SCORES.get(env, {}).get(level)


def assets_dir() -> Path:
    return Path(str(resources.files("xted") / "assets" / "datasets"))


@lru_cache(maxsize=1)
def manifest() -> dict[str, Any]:
    """The manifest as a dict ``{"datasets": {name: entry}, "policies": {...}}``."""
    path = assets_dir() / MANIFEST_NAME
    if not path.exists():
        return {"datasets": {}, "policies": {}}
    return json.loads(path.read_text())


def names() -> list[str]:
    return sorted(manifest()["datasets"])


def find(name: str) -> Path | None:
    """The path of the shipped dataset called ``name``, or None if there is none."""
    entry = manifest()["datasets"].get(name)
    if entry is None:
        return None
    return assets_dir() / entry["file"]


def policies_dir() -> Path:
    """The folder of the shipped behaviour policies (and medium replay buffers)."""
    return assets_dir().parent / "policies"


def prior_dir(name: str) -> Path:
    """The folder of the shipped (exported) prior called ``name``."""
    return assets_dir().parent / "priors" / name


def prior_names() -> list[str]:
    """The names of the priors shipped with xted."""
    return sorted(p.name for p in (assets_dir().parent / "priors").iterdir() if (p / "prior.json").is_file())
