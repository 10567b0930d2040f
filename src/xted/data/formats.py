"""Reading and writing datasets as ``.npz``, D4RL-style HDF5 or Minari, chosen by the path.

* ``.npz``: the fields by name, extras as ``extras/NAME``, metadata as a JSON string ``metadata``.
* ``.hdf5`` / ``.h5`` (D4RL layout): flat ``observations``, ``actions``, ``rewards``,
  ``terminals``, ``timeouts``, optional ``next_observations``, extras as ``infos/NAME`` and
  metadata as the JSON root attribute ``metadata`` (D4RL's ``metadata`` group is read too).
* Minari: ``minari:ID`` in the local Minari root (``MINARI_DATASETS_PATH``, else
  ``~/.minari/datasets``; nothing is downloaded) or the path of a dataset folder. Episodes hold
  T+1 observations, which hold next observations that agree with the following step's
  observation; others (edited data may have them) go into ``infos`` as ``xted_next_observations``.
  Extras are per-step ``infos`` (``infos[t]`` belongs to ``observations[t]``: Minari's T+1 infos
  lose their last entry). xted's metadata goes under the key ``xted`` of Minari's
  ``metadata.json``. A dataset without next observations is written with each episode's last
  observation repeated as its final one and read back without next observations. Minari's
  per-episode seeds, options and episode metadata are not read.
* A bare name that is not a path is looked up among the shipped datasets.

A file without ``rewards`` holds reward-free data (:attr:`Dataset.has_rewards` False), and
reward-free data is written without them (Minari, which needs rewards, gets zeros and the
metadata flag). Files written by other tools may lack ``terminals`` or ``timeouts`` (taken as all false), end
in an unfinished episode (ended with a timeout), or flag a step as both (the terminal wins);
each such repair is recorded in ``metadata["notes"]``.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterator

import h5py
import numpy as np

from xted.atomic import atomic_path
from xted.data import shipped
from xted.data.dataset import Dataset, as_flags
from xted.errors import InputError

NPZ, HDF5, MINARI = "npz", "hdf5", "minari"
MINARI_PREFIX = "minari:"
_SUFFIXES = {".npz": NPZ, ".hdf5": HDF5, ".h5": HDF5}
_FIELDS = ("observations", "actions", "rewards", "terminals", "timeouts", "next_observations")
_REQUIRED = ("observations", "actions")  # no rewards: reward-free data
_NPZ_EXTRAS = "extras/"
_HDF5_EXTRAS = "infos"
_MINARI_KEY = "xted"
_NEXT_INFO = "xted_next_observations"
_NEXT_ABSENT, _NEXT_IN_OBSERVATIONS, _NEXT_IN_INFOS = "absent", "observations", "infos"
_EXPECTED = "expected .npz, .hdf5, .h5, a Minari dataset folder or minari:ID"


@dataclass(frozen=True)
class Location:
    """Where a dataset lives: its format, its file or Minari dataset folder, its Minari id."""

    format: str
    path: Path
    dataset_id: str | None = None


# ----------------------------------------------------------------- public API
def load(source: str | os.PathLike) -> Dataset:
    """Read a dataset from a file, a Minari folder, ``minari:ID`` or a shipped name."""
    location = locate(source)
    reader = {NPZ: _read_npz, HDF5: _read_hdf5, MINARI: _read_minari}[location.format]
    return reader(location.path)


def save(dataset: Dataset, dest: str | os.PathLike, *, overwrite: bool = True) -> Location:
    """Write ``dataset`` atomically to ``dest`` (format from the path); return where it went."""
    location = target(dest)
    check_writable(location, overwrite)
    writer = {NPZ: _write_npz, HDF5: _write_hdf5, MINARI: _write_minari}[location.format]
    writer(dataset, location)
    return location


def locate(source: str | os.PathLike) -> Location:
    """Resolve an existing dataset: its format and path."""
    text = os.fspath(source)
    if text.startswith(MINARI_PREFIX):
        dataset_id = text[len(MINARI_PREFIX):]
        folder = minari_root() / dataset_id
        if not folder.exists():
            raise InputError(f"{text}: no such Minari dataset in {minari_root()} (nothing is downloaded)")
        return Location(MINARI, _minari_folder(folder), dataset_id)
    path = Path(text).expanduser()
    if path.is_dir():
        return Location(MINARI, _minari_folder(path))
    fmt = _SUFFIXES.get(path.suffix.lower())
    if fmt is not None:
        if not path.exists():
            raise InputError(f"{path}: no such file")
        return Location(fmt, path)
    if path.suffix or path.exists():
        raise InputError(f"{path}: unknown extension {path.suffix!r}; {_EXPECTED}")
    return _shipped(text)


def target(dest: str | os.PathLike) -> Location:
    """Resolve an output path: its format and path (nothing is checked on disk)."""
    text = os.fspath(dest)
    if text.startswith(MINARI_PREFIX):
        dataset_id = _checked_id(text[len(MINARI_PREFIX):])
        return Location(MINARI, minari_root() / dataset_id, dataset_id)
    path = Path(text).expanduser()
    fmt = _SUFFIXES.get(path.suffix.lower())
    if fmt is not None:
        return Location(fmt, path)
    if path.suffix and not path.is_dir():
        raise InputError(f"{path}: unknown extension {path.suffix!r}; {_EXPECTED}")
    return Location(MINARI, path, _folder_id(path.name))


def check_writable(location: Location, overwrite: bool) -> None:
    """Raise InputError unless ``location`` may be written (replaced only with ``overwrite``)."""
    path = location.path
    if location.format == MINARI:
        if path.exists() and not (path / "data" / "metadata.json").is_file():
            raise InputError(f"{path}: exists and is not a Minari dataset folder; refusing to replace it")
    elif path.is_dir():
        raise InputError(f"{path}: is a folder, expected a file path")
    if path.exists() and not overwrite:
        raise InputError(f"{path}: exists (use --force / overwrite=True to replace it)")


def check_apart(output: Location, inputs: dict[str, str | os.PathLike | None]) -> None:
    """Refuse an output that is one of the inputs (``{role: path}``) or lies inside an input's
    folder (a Minari dataset, a prior): inputs are never modified."""
    out = output.path.resolve()
    for role, given in inputs.items():
        if given is None:
            continue
        path = Path(given).resolve() if Path(given).is_dir() else locate(given).path.resolve()
        if out == path:
            raise InputError(f"output {output.path} is the {role} input {given}; inputs are never overwritten, "
                             f"choose another output path")
        if path.is_dir() and out.is_relative_to(path):
            raise InputError(f"output {output.path} lies inside the {role} input folder {given}; inputs are "
                             f"never modified, choose a path outside it")


def minari_root() -> Path:
    """The local Minari root, as Minari itself resolves it."""
    env = os.environ.get("MINARI_DATASETS_PATH")
    return Path(env) if env is not None else Path.home() / ".minari" / "datasets"


# ------------------------------------------------------------------ locating
def _shipped(name: str) -> Location:
    path = shipped.find(name)
    if path is None:
        known = ", ".join(shipped.names()) or "none"
        raise InputError(f"{name!r}: no such file, folder or shipped dataset (shipped datasets: {known})")
    return locate(path)


def _minari_folder(path: Path) -> Path:
    """The dataset folder (holding ``data/``) of ``path``, which may be the folder or its ``data``."""
    if (path / "data" / "metadata.json").is_file():
        return path
    if path.name == "data" and (path / "metadata.json").is_file():
        return path.parent
    raise InputError(f"{path}: not a Minari dataset folder (no data/metadata.json)")


def _checked_id(dataset_id: str) -> str:
    from minari.dataset.minari_dataset import parse_dataset_id

    try:
        parse_dataset_id(dataset_id)
    except (ValueError, TypeError):
        raise InputError(f"{dataset_id!r}: not a Minari dataset id ((namespace/)name-vN)") from None
    return dataset_id


def _folder_id(name: str) -> str:
    """A Minari id for a dataset written to folder ``name``: the name, with ``-v0`` if unversioned."""
    if re.fullmatch(r"[-\w]+-v\d+", name):
        return name
    return re.sub(r"[^-\w]", "_", name or "dataset") + "-v0"


# ------------------------------------------------------ shared array handling
def _from_arrays(
    where: Path,
    arrays: dict[str, np.ndarray],
    extras: dict[str, np.ndarray],
    metadata: dict[str, Any],
    notes: list[str],
) -> Dataset:
    """Build a Dataset from raw file arrays, repairing ambiguity-free gaps (each noted)."""
    for key in _REQUIRED:
        if key not in arrays:
            raise InputError(f"{where}: missing required key {key!r}")
    try:
        arrays = _repaired(arrays, notes)
        if notes:
            metadata = {**metadata, "notes": [*metadata.get("notes", []), *notes]}
        return Dataset(
            observations=arrays["observations"],
            actions=arrays["actions"],
            rewards=arrays.get("rewards"),
            terminals=arrays["terminals"],
            timeouts=arrays["timeouts"],
            next_observations=arrays.get("next_observations"),
            extras=extras,
            metadata=metadata,
            origin=str(where),
        )
    except InputError as err:
        raise InputError(f"{where}: {err}") from None


def _repaired(arrays: dict[str, np.ndarray], notes: list[str]) -> dict[str, np.ndarray]:
    arrays = dict(arrays)
    rewards = arrays.get("rewards")
    if rewards is not None and rewards.ndim == 2 and rewards.shape[1] == 1:
        arrays["rewards"] = rewards[:, 0]
    n = len(arrays["observations"]) if arrays["observations"].ndim else 0
    for key in ("terminals", "timeouts"):
        if key not in arrays:
            arrays[key] = np.zeros(n, dtype=bool)
            notes.append(f"no {key} in the file: all taken as false")
        elif arrays[key].ndim == 2 and arrays[key].shape[1] == 1:
            arrays[key] = arrays[key][:, 0]
    terminals, timeouts = arrays["terminals"], arrays["timeouts"]
    if n == 0 or terminals.shape != (n,) or timeouts.shape != (n,):
        return arrays  # Dataset reports the problem
    terminals, timeouts = as_flags("terminals", terminals), as_flags("timeouts", timeouts)
    both = terminals & timeouts
    if both.any():
        timeouts = timeouts & ~both
        notes.append(f"{int(both.sum())} steps flagged both terminal and timeout: kept as terminal")
    if not (terminals[-1] or timeouts[-1]):
        timeouts = timeouts.copy()
        timeouts[-1] = True
        notes.append("the final episode was unfinished: ended with a timeout")
    arrays["terminals"], arrays["timeouts"] = terminals, timeouts
    return arrays


def _numeric_only(extras: dict[str, np.ndarray], notes: list[str]) -> dict[str, np.ndarray]:
    kept = {k: v for k, v in extras.items() if v.dtype == np.bool_ or np.issubdtype(v.dtype, np.number)}
    if len(kept) < len(extras):
        notes.append(f"non-numeric extras not read: {sorted(set(extras) - set(kept))}")
    return kept


def _json_object(text: Any, where: Path) -> dict[str, Any]:
    if isinstance(text, bytes):
        text = text.decode("utf-8")
    try:
        value = json.loads(str(text))
    except json.JSONDecodeError as err:
        raise InputError(f"{where}: metadata is not valid JSON ({err})") from None
    if not isinstance(value, dict):
        raise InputError(f"{where}: metadata is not a JSON object")
    return value


def _field_arrays(dataset: Dataset) -> dict[str, np.ndarray]:
    """The arrays a file holds: reward-free data has no rewards, data without next observations none of those."""
    arrays = {name: getattr(dataset, name) for name in _FIELDS}
    if not dataset.has_rewards:
        del arrays["rewards"]
    return {k: v for k, v in arrays.items() if v is not None}


# ----------------------------------------------------------------------- npz
def _read_npz(path: Path) -> Dataset:
    if not zipfile.is_zipfile(path):
        raise InputError(f"{path}: not a readable .npz archive (not a zip file)")
    try:
        with np.load(path, allow_pickle=False) as archive:
            raw = {key: archive[key] for key in archive.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error) as err:
        raise InputError(f"{path}: not a readable .npz archive ({err})") from None
    notes: list[str] = []
    metadata = _json_object(raw.pop("metadata"), path) if "metadata" in raw else {}
    extras = {k[len(_NPZ_EXTRAS):]: raw.pop(k) for k in list(raw) if k.startswith(_NPZ_EXTRAS)}
    unknown = sorted(set(raw) - set(_FIELDS))
    if unknown:
        notes.append(f"unknown keys not read: {unknown}")
    return _from_arrays(path, raw, _numeric_only(extras, notes), metadata, notes)


def _write_npz(dataset: Dataset, location: Location) -> None:
    arrays = _field_arrays(dataset)
    arrays.update({_NPZ_EXTRAS + k: v for k, v in dataset.extras.items()})
    arrays["metadata"] = np.array(json.dumps(dataset.metadata))
    with atomic_path(location.path, ".npz") as tmp, open(tmp, "wb") as handle:
        np.savez_compressed(handle, **arrays)


# ---------------------------------------------------------------------- hdf5
def _read_hdf5(path: Path) -> Dataset:
    try:
        with h5py.File(path, "r") as file:
            arrays = {k: file[k][()] for k in _FIELDS if isinstance(file.get(k), h5py.Dataset)}
            group = file.get(_HDF5_EXTRAS)
            extras = dict(_hdf5_leaves(group)) if isinstance(group, h5py.Group) else {}
            metadata = _hdf5_metadata(file, path)
            nested = [] if "observations" in arrays else _nested_arrays(file, "observations")
    except OSError as err:
        raise InputError(f"{path}: not a readable HDF5 file ({err})") from None
    if nested:
        raise InputError(f"{path}: missing required key 'observations' at the file's root; the file holds "
                         f"{', '.join('/' + name for name in nested)}: xted reads D4RL's layout, every array at the "
                         "root (observations, actions, rewards, terminals, timeouts, next_observations)")
    notes: list[str] = []
    return _from_arrays(path, arrays, _numeric_only(extras, notes), metadata, notes)


def _nested_arrays(file: h5py.File, name: str) -> list[str]:
    """Paths of the arrays called ``name`` below the file's root."""
    found: list[str] = []
    file.visititems(lambda path, item: found.append(path) if isinstance(item, h5py.Dataset)
                    and path.rsplit("/", 1)[-1] == name and "/" in path else None)
    return found


def _hdf5_leaves(group: h5py.Group, prefix: str = "") -> Iterator[tuple[str, np.ndarray]]:
    for name, item in group.items():
        if isinstance(item, h5py.Group):
            yield from _hdf5_leaves(item, f"{prefix}{name}/")
        elif isinstance(item, h5py.Dataset):
            yield prefix + name, item[()]


def _hdf5_metadata(file: h5py.File, path: Path) -> dict[str, Any]:
    """Our JSON attribute, or else the file's scalar attributes (D4RL's ``env_name``, ...) and the
    scalar entries of D4RL's ``metadata`` group."""
    if "metadata" in file.attrs:
        return _json_object(file.attrs["metadata"], path)
    metadata = {name: _python_scalar(value) for name, value in file.attrs.items() if np.ndim(value) == 0}
    group = file.get("metadata")
    if isinstance(group, h5py.Group):
        metadata.update({name: _python_scalar(value) for name, value in _hdf5_leaves(group) if np.ndim(value) == 0})
    return metadata


def _python_scalar(value: Any) -> Any:
    value = value.item() if isinstance(value, np.generic | np.ndarray) else value
    return value.decode("utf-8", "replace") if isinstance(value, bytes) else value


def _write_hdf5(dataset: Dataset, location: Location) -> None:
    with atomic_path(location.path, location.path.suffix) as tmp:
        try:
            with h5py.File(tmp, "w") as file:
                for name, value in _field_arrays(dataset).items():
                    file.create_dataset(name, data=value)
                for name, value in dataset.extras.items():
                    file.create_dataset(f"{_HDF5_EXTRAS}/{name}", data=value)
                file.attrs["metadata"] = json.dumps(dataset.metadata)
        except RuntimeError as err:  # h5py reports a failed write (a full disk) as a RuntimeError
            raise OSError(f"HDF5 write failed ({err})") from None


# -------------------------------------------------------------------- minari
def _read_minari(folder: Path) -> Dataset:
    from minari import MinariDataset
    from minari.dataset.minari_storage import MinariStorage

    data_dir = folder / "data"
    try:
        minari_dataset = MinariDataset(data_dir)
        raw_metadata = MinariStorage.read_raw_metadata(data_dir)
        episodes = list(minari_dataset.iterate_episodes())
    except (OSError, ValueError, KeyError, AssertionError, ImportError) as err:
        raise InputError(f"{folder}: not a readable Minari dataset ({err})") from None
    _check_box(folder, "observation", minari_dataset.observation_space)
    _check_box(folder, "action", minari_dataset.action_space)
    if not episodes:
        raise InputError(f"{folder}: empty dataset: no episodes")
    notes: list[str] = []
    arrays, extras = _minari_arrays(episodes, notes)
    own = raw_metadata.get(_MINARI_KEY)
    if isinstance(own, dict):
        metadata = own.get("metadata", {})
        stored = own.get("next_observations")
        if stored == _NEXT_IN_INFOS and _NEXT_INFO in extras:
            arrays["next_observations"] = extras.pop(_NEXT_INFO)
        elif stored == _NEXT_ABSENT:
            del arrays["next_observations"]
    else:
        metadata = _foreign_minari_metadata(raw_metadata)
    return _from_arrays(folder, arrays, _numeric_only(extras, notes), metadata, notes)


def _check_box(folder: Path, what: str, space: Any) -> None:
    from gymnasium import spaces

    if not isinstance(space, spaces.Box):
        raise InputError(f"{folder}: unsupported {what} space {space}; only Box spaces are read")


def _minari_arrays(
    episodes: list[Any], notes: list[str]
) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Flat arrays from Minari episodes (T+1 observations and T or T+1 infos each)."""
    parts: dict[str, list[np.ndarray]] = {name: [] for name in _FIELDS}
    infos = [dict(_flat_infos(ep.infos or {})) for ep in episodes]
    common = set.intersection(*(set(info) for info in infos))
    if any(set(info) != common for info in infos):
        notes.append(f"infos missing from some episodes not read: {sorted(set().union(*infos) - common)}")
    extras: dict[str, list[np.ndarray]] = {name: [] for name in sorted(common)}
    for episode, info in zip(episodes, infos):
        steps = len(episode.rewards)
        observations = np.asarray(episode.observations).reshape(steps + 1, -1)
        parts["observations"].append(observations[:-1])
        parts["next_observations"].append(observations[1:])
        parts["actions"].append(np.asarray(episode.actions).reshape(steps, -1))
        parts["rewards"].append(np.asarray(episode.rewards))
        parts["terminals"].append(np.asarray(episode.terminations, dtype=bool))
        parts["timeouts"].append(_episode_timeouts(episode, notes))
        for name in extras:
            extras[name].append(np.asarray(info[name])[:steps])
    return {k: np.concatenate(v) for k, v in parts.items()}, {k: np.concatenate(v) for k, v in extras.items()}


def _episode_timeouts(episode: Any, notes: list[str]) -> np.ndarray:
    """Truncations, with an unfinished episode ended by a timeout (noted)."""
    timeouts = np.array(episode.truncations, dtype=bool)
    if len(timeouts) and not (timeouts[-1] or episode.terminations[-1]):
        timeouts[-1] = True
        notes.append(f"episode {episode.id} was unfinished: ended with a timeout")
    return timeouts


def _flat_infos(infos: dict[str, Any], prefix: str = "") -> Iterator[tuple[str, Any]]:
    for name, value in infos.items():
        if isinstance(value, dict):
            yield from _flat_infos(value, f"{prefix}{name}/")
        else:
            yield prefix + name, value


def _foreign_minari_metadata(raw: dict[str, Any]) -> dict[str, Any]:
    """What xted keeps of a Minari dataset's own metadata."""
    metadata: dict[str, Any] = {"minari_dataset_id": raw.get("dataset_id")}
    with contextlib.suppress(KeyError, TypeError, ValueError):
        metadata["env"] = json.loads(raw["env_spec"])["id"]
    for key in ("algorithm_name", "ref_min_score", "ref_max_score"):
        if key in raw:
            metadata[key] = raw[key]
    return metadata


def _write_minari(dataset: Dataset, location: Location) -> None:
    from gymnasium import spaces
    from minari import __version__ as minari_version
    from minari.dataset.minari_storage import MinariStorage

    def box(dim: int) -> spaces.Box:
        return spaces.Box(-np.inf, np.inf, shape=(dim,), dtype=np.float32)

    mode = _next_observations_mode(dataset)
    with atomic_path(location.path) as tmp:
        tmp.mkdir()
        storage = MinariStorage.new(
            tmp / "data",
            observation_space=box(dataset.observation_dim),
            action_space=box(dataset.action_dim),
            data_format="hdf5",
        )
        storage.update_metadata(
            {
                "dataset_id": location.dataset_id,
                "minari_version": minari_version,
                _MINARI_KEY: {"metadata": dataset.metadata, "next_observations": mode},
            }
        )
        storage.update_episodes(_episode_buffers(dataset, mode))


def _next_observations_mode(dataset: Dataset) -> str:
    """How Minari holds next observations: absent, as the T+1 observations, or in ``infos``."""
    if dataset.next_observations is None:
        return _NEXT_ABSENT
    inner = ~(dataset.terminals | dataset.timeouts)[:-1]
    if np.array_equal(dataset.next_observations[:-1][inner], dataset.observations[1:][inner]):
        return _NEXT_IN_OBSERVATIONS
    return _NEXT_IN_INFOS


def _episode_buffers(dataset: Dataset, mode: str) -> Iterator[Any]:
    from minari.data_collector.episode_buffer import EpisodeBuffer

    nexts = dataset.observations if mode == _NEXT_ABSENT else dataset.next_observations
    infos = dict(dataset.extras)
    if mode == _NEXT_IN_INFOS:
        infos[_NEXT_INFO] = dataset.next_observations
    for start, end in dataset.episode_bounds():
        yield EpisodeBuffer(
            observations=np.concatenate([dataset.observations[start:end], nexts[end - 1 : end]]),
            actions=dataset.actions[start:end],
            rewards=dataset.rewards[start:end],
            terminations=dataset.terminals[start:end],
            truncations=dataset.timeouts[start:end],
            infos={k: v[start:end] for k, v in infos.items()} or None,
        )
