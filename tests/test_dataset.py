"""Dataset validation and helpers; Normalizer fit/apply/serialise."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from xted.data import Dataset, Normalizer
from xted.errors import InputError


def _fields(dataset: Dataset) -> dict:
    return dict(
        observations=dataset.observations.copy(),
        actions=dataset.actions.copy(),
        rewards=dataset.rewards.copy(),
        terminals=dataset.terminals.copy(),
        timeouts=dataset.timeouts.copy(),
        next_observations=dataset.next_observations.copy(),
        extras=dict(dataset.extras),
        metadata=dict(dataset.metadata),
    )


def test_construction_converts_dtypes(tiny_dataset):
    fields = _fields(tiny_dataset)
    fields["observations"] = fields["observations"].astype(np.float64)
    fields["terminals"] = fields["terminals"].astype(np.int64)
    fields["metadata"] = {"shape": (1, 2)}
    dataset = Dataset(**fields)
    assert dataset.observations.dtype == np.float32
    assert dataset.terminals.dtype == np.bool_
    assert dataset.metadata == {"shape": [1, 2]}


def test_episode_helpers(tiny_dataset):
    d = tiny_dataset
    assert (len(d), d.observation_dim, d.action_dim, d.num_episodes) == (13, 3, 2, 3)
    np.testing.assert_array_equal(d.episode_bounds(), [[0, 4], [4, 10], [10, 13]])
    np.testing.assert_array_equal(d.episode_lengths(), [4, 6, 3])
    expected = [d.rewards[a:b].astype(np.float64).sum() for a, b in d.episode_bounds()]
    np.testing.assert_allclose(d.episode_returns(), expected)
    summary = d.summary()
    assert summary["episodes"] == 3 and summary["transitions"] == 13
    assert (summary["terminals"], summary["timeouts"]) == (1, 2)
    assert summary["extras"] == ["qpos", "sim/contact", "step"]
    json.dumps(summary)


def _set(field, index, value):
    return lambda f: f[field].__setitem__(index, value)


def _replace(**changes):
    return lambda f: f.update({k: change(f) for k, change in changes.items()})


def _empty(fields):
    fields.update({k: v[:0] for k, v in fields.items() if isinstance(v, np.ndarray)}, extras={})


@pytest.mark.parametrize(
    "change, message",
    [
        (_empty, "empty dataset"),
        (_replace(observations=lambda f: f["observations"][:, 0]), "observations must be 2-D"),
        (_replace(actions=lambda f: f["actions"][:-1]), "actions has 12 rows"),
        (_set("observations", (3, 1), np.nan), "observations[3, 1] is nan"),
        (_set("rewards", 5, np.inf), "rewards[5] is inf"),
        (_set("timeouts", 9, True), "terminals[9] and timeouts[9] are both true"),
        (_set("timeouts", 12, False), "final step (index 12) ends no episode"),
        (_replace(next_observations=lambda f: f["next_observations"][:, :2]), "next_observations has shape"),
        (_replace(extras=lambda f: {"qpos": np.zeros((5, 2))}), "extras['qpos'] has shape (5, 2)"),
        (_replace(terminals=lambda f: f["terminals"] * 2), "terminals[9] is 2"),
        (_replace(metadata=lambda f: {"x": object()}), "metadata is not JSON-serialisable"),
    ],
)
def test_validation_errors_name_field_and_index(tiny_dataset, change, message):
    fields = _fields(tiny_dataset)
    change(fields)
    with pytest.raises(InputError, match=re.escape(message)):
        Dataset(**fields)


def test_select_and_concatenate(tiny_dataset):
    picked = tiny_dataset.select_episodes([2, 0])
    np.testing.assert_array_equal(picked.episode_lengths(), [3, 4])
    np.testing.assert_array_equal(picked.observations[:3], tiny_dataset.observations[10:13])
    np.testing.assert_array_equal(picked.extras["step"], [10, 11, 12, 0, 1, 2, 3])
    with pytest.raises(InputError, match="episode 3 out of range"):
        tiny_dataset.select_episodes([3])

    both = Dataset.concatenate([tiny_dataset, picked])
    assert len(both) == 20 and both.num_episodes == 5
    assert both.metadata == {"sources": [tiny_dataset.metadata, picked.metadata]}
    no_next = Dataset(**{**_fields(picked), "next_observations": None, "extras": {}})
    mixed = Dataset.concatenate([tiny_dataset, no_next], metadata={"a": 1})
    assert mixed.next_observations is None and mixed.extras == {} and mixed.metadata == {"a": 1}


def test_with_metadata_copies(tiny_dataset):
    updated = tiny_dataset.with_metadata(domain="gravity-2x")
    assert updated.metadata["domain"] == "gravity-2x"
    assert "domain" not in tiny_dataset.metadata
    assert updated.observations is tiny_dataset.observations


def test_require_next_observations(tiny_dataset):
    assert tiny_dataset.require_next_observations() is tiny_dataset.next_observations
    bare = Dataset(**{**_fields(tiny_dataset), "next_observations": None})
    with pytest.raises(InputError, match="index 3"):
        bare.require_next_observations()


def test_a_loaded_file_s_missing_next_observations_is_named(tiny_dataset, tmp_path):
    from xted.data import load, save

    path = tmp_path / "no-next.npz"
    save(Dataset(**{**_fields(tiny_dataset), "next_observations": None}), path)
    loaded = load(path)
    with pytest.raises(InputError, match=re.escape(f"{path}: next_observations is missing")):
        loaded.require_next_observations()
    with pytest.raises(InputError, match=re.escape(str(path))):
        loaded.select_episodes([0]).require_next_observations()
    assert "origin" not in loaded.metadata and load(save(loaded, tmp_path / "again.npz").path).origin != str(path)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(lengths=st.lists(st.integers(1, 6), min_size=1, max_size=6), seed=st.integers(0, 5))
def test_episode_bounds_property(make_dataset, lengths, seed):
    d = make_dataset(lengths, seed=seed)
    bounds = d.episode_bounds()
    assert bounds[0, 0] == 0 and bounds[-1, 1] == len(d) == sum(lengths)
    np.testing.assert_array_equal(bounds[1:, 0], bounds[:-1, 1])
    np.testing.assert_array_equal(d.episode_lengths(), lengths)
    assert len(d.select_episodes(range(len(lengths)))) == len(d)


# ------------------------------------------------------------------ Normalizer
def test_normalizer_fit_apply_invert(tiny_dataset):
    norm = Normalizer.fit(tiny_dataset)
    z = norm.normalize("observations", tiny_dataset.observations)
    np.testing.assert_allclose(z.mean(axis=0), 0, atol=1e-5)
    np.testing.assert_allclose(z.std(axis=0), 1, atol=1e-4)
    back = norm.denormalize("observations", z)
    np.testing.assert_allclose(back, tiny_dataset.observations, atol=1e-5)
    windows = np.broadcast_to(tiny_dataset.actions, (4, 13, 2))
    back = norm.denormalize("actions", norm.normalize("actions", windows))
    np.testing.assert_allclose(back, windows, atol=1e-5)
    r = norm.normalize("rewards", tiny_dataset.rewards)
    assert r.shape == (13,)
    np.testing.assert_array_equal(
        norm.normalize("next_observations", tiny_dataset.next_observations),
        norm.normalize("observations", tiny_dataset.next_observations),
    )
    with pytest.raises(InputError, match="unknown field 'terminals'"):
        norm.normalize("terminals", tiny_dataset.terminals)


def test_normalizer_floors_constant_std(tiny_dataset):
    fields = _fields(tiny_dataset)
    fields["actions"] = np.ones_like(fields["actions"])
    norm = Normalizer.fit(Dataset(**fields), eps=1e-3)
    z = norm.normalize("actions", fields["actions"])
    assert np.all(np.isfinite(z)) and np.all(z == 0)


def test_normalizer_serialise_round_trip(tiny_dataset, tmp_path):
    norm = Normalizer.fit(tiny_dataset)
    again = Normalizer.from_dict(json.loads(json.dumps(norm.to_dict())))
    path = tmp_path / "norm.json"
    norm.save(path)
    loaded = Normalizer.load(path)
    assert [p.name for p in tmp_path.iterdir()] == ["norm.json"]
    for other in (again, loaded):
        for field in ("observations", "actions", "rewards"):
            np.testing.assert_array_equal(other.mean[field], norm.mean[field])
            np.testing.assert_array_equal(other.std[field], norm.std[field])
        assert other.eps == norm.eps
    (tmp_path / "bad.json").write_text('{"mean": {}}')
    with pytest.raises(InputError, match="bad.json"):
        Normalizer.load(tmp_path / "bad.json")


def test_fingerprint_follows_the_arrays_not_the_metadata(tiny_dataset):
    same = Dataset(**_fields(tiny_dataset))
    assert same.fingerprint() == tiny_dataset.fingerprint()
    assert tiny_dataset.with_metadata(note="renamed").fingerprint() == tiny_dataset.fingerprint()
    for name in ("observations", "rewards", "next_observations"):
        fields = _fields(tiny_dataset)
        fields[name][-1] += 1.0
        assert Dataset(**fields).fingerprint() != tiny_dataset.fingerprint(), name


def test_a_dataset_from_observations_and_actions_alone_is_one_reward_free_episode():
    data = Dataset(observations=np.zeros((5, 3)), actions=np.zeros((5, 2)))
    assert data.num_episodes == 1 and data.timeouts[-1] and not data.terminals.any() and not data.has_rewards
    assert repr(data) == "Dataset(5 transitions, 1 episodes, observations 3-d, actions 2-d, reward-free)"


def test_next_observations_equal_to_observations_are_refused():
    observations = np.arange(12.0).reshape(4, 3)
    with pytest.raises(InputError, match="next_observations equals observations in every row"):
        Dataset(observations=observations, actions=np.zeros((4, 1)), next_observations=observations.copy())
