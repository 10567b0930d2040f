"""The shipped datasets and behaviour policies match their manifest."""

import hashlib

import numpy as np
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


@pytest.mark.parametrize("name", [n for n in EXPECTED if "arrays_sha256" in MANIFEST["datasets"][n]])
def test_dataset_arrays_match_manifest(name):
    assert load(name).fingerprint() == MANIFEST["datasets"][name]["arrays_sha256"]


def test_a_shipped_dataset_regenerates_from_its_command(tmp_path):
    """The manifest's command, run again, makes the same data: the same episodes from the same
    starts, acting alike, at the same level. Not bit for bit across library releases: a policy's
    forward pass can differ in the last float bit between them, and a running cheetah is chaotic,
    so two such rollouts part within about ten steps."""
    from xted.cli.main import main

    name = "halfcheetah-medium-expert"
    entry = MANIFEST["datasets"][name]
    args = entry["command"].split()[1:]
    args[args.index("--out") + 1] = str(tmp_path / f"{name}.npz")
    assert main(args) == 0
    again, shipped = load(tmp_path / f"{name}.npz"), load(name)
    np.testing.assert_array_equal(again.episode_bounds(), shipped.episode_bounds())
    starts = again.episode_bounds()[:, 0]
    np.testing.assert_array_equal(again.observations[starts], shipped.observations[starts])  # same reset seeds
    np.testing.assert_allclose(again.actions[starts], shipped.actions[starts], atol=1e-4)
    assert again.metadata["normalized_score"] == pytest.approx(entry["normalized_score"], abs=1.0)
