"""Per-field standardisation fitted on one dataset (the target) and applied to any other.

``normalize`` and ``denormalize`` use only arithmetic, so they accept NumPy or JAX arrays of
any leading shape (``[N, d]``, ``[W, H, d]``). ``next_observations`` share the observation stats.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from xted.atomic import atomic_path
from xted.data.dataset import Dataset
from xted.errors import InputError
from xted.jsonfiles import read_json

FIELDS = ("observations", "actions", "rewards")
_ALIASES = {"next_observations": "observations"}


@dataclass(frozen=True, eq=False)
class Normalizer:
    """``mean[field]`` and ``std[field]`` (float32); std is floored at ``eps`` when applied."""

    mean: dict[str, np.ndarray]
    std: dict[str, np.ndarray]
    eps: float = 1e-6

    def __post_init__(self) -> None:
        for attr in ("mean", "std"):
            stats = getattr(self, attr)
            missing = set(FIELDS) - set(stats)
            if missing:
                raise InputError(f"normalizer: {attr} lacks fields {sorted(missing)}")
            object.__setattr__(self, attr, {k: np.asarray(stats[k], dtype=np.float32) for k in FIELDS})
        for name in FIELDS:
            if self.mean[name].shape != self.std[name].shape:
                raise InputError(f"normalizer: {name} mean and std differ in shape")
            if not (np.all(np.isfinite(self.mean[name])) and np.all(self.std[name] >= 0)):
                raise InputError(f"normalizer: {name} has a non-finite mean or a negative std")

    @classmethod
    def fit(cls, dataset: Dataset, eps: float = 1e-6) -> Normalizer:
        """Mean and standard deviation of each field over all steps of ``dataset``."""
        arrays = {name: getattr(dataset, name).astype(np.float64) for name in FIELDS}
        return cls(
            mean={k: v.mean(axis=0) for k, v in arrays.items()},
            std={k: v.std(axis=0) for k, v in arrays.items()},
            eps=eps,
        )

    def normalize(self, field: str, x: Any) -> Any:
        mean, std = self._stats(field)
        return (x - mean) / std

    def denormalize(self, field: str, x: Any) -> Any:
        mean, std = self._stats(field)
        return x * std + mean

    def _stats(self, field: str) -> tuple[np.ndarray, np.ndarray]:
        name = _ALIASES.get(field, field)
        if name not in FIELDS:
            raise InputError(f"normalizer: unknown field {field!r}; expected one of {FIELDS}")
        return self.mean[name], np.maximum(self.std[name], np.float32(self.eps))

    def to_dict(self) -> dict[str, Any]:
        """JSON-serialisable form."""
        return {
            "mean": {k: v.tolist() for k, v in self.mean.items()},
            "std": {k: v.tolist() for k, v in self.std.items()},
            "eps": self.eps,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Normalizer:
        """Inverse of :meth:`to_dict`."""
        if not isinstance(data, dict) or not {"mean", "std"} <= set(data):
            raise InputError("normalizer: expected an object with 'mean' and 'std'")
        return cls(mean=dict(data["mean"]), std=dict(data["std"]), eps=float(data.get("eps", 1e-6)))

    def save(self, path: str | os.PathLike) -> None:
        with atomic_path(path, ".json") as tmp:
            tmp.write_text(json.dumps(self.to_dict()))

    @classmethod
    def load(cls, path: str | os.PathLike) -> Normalizer:
        path = Path(path)
        data = read_json(path, "not a readable normalizer file")
        try:
            return cls.from_dict(data)
        except InputError as err:
            raise InputError(f"{path}: {err}") from None
