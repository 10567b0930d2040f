"""The shipped datasets and behaviour policies match their manifest."""

import hashlib

import pytest

from xted.data import load, shipped
from xted.data.shipped import policies_dir

MANIFEST = shipped.manifest()
EXPECTED = [f"{env}-{kind}" for env in ("halfcheetah", "walker2d")
            for kind in ("medium", "medium-replay", "medium-expert", "gravity", "friction", "thigh")]


def sha256(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_the_twelve_datasets_are_listed():
    assert sorted(MANIFEST["datasets"]) == sorted(EXPECTED)


@pytest.mark.parametrize("name", EXPECTED)
def test_dataset_matches_manifest(name):
    entry = MANIFEST["datasets"][name]
    path = shipped.find(name)
    assert path.stat().st_size == entry["bytes"]
    assert sha256(path) == entry["sha256"]
    data = load(name)
    assert len(data) == entry["transitions"] == 20_000
    assert data.num_episodes == entry["episodes"]
    assert data.metadata["normalized_score"] == pytest.approx(entry["normalized_score"])
    assert data.metadata["command"] == entry["command"] and entry["command"].startswith("xted data make")


@pytest.mark.parametrize("name", sorted(MANIFEST["policies"]))
def test_policy_files_match_manifest(name):
    entry = MANIFEST["policies"][name]
    path = policies_dir() / entry["file"]
    assert path.stat().st_size == entry["bytes"]
    assert sha256(path) == entry["sha256"]
