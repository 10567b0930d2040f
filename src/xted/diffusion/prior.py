"""The trained prior as an artefact: config, target normaliser, EMA parameters and return range;
loaded from a training folder or an exported (inference-only, shippable) copy. Editing needs only
this and the denoiser."""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import flax.serialization
import jax
import numpy as np

from xted.atomic import atomic_path
from xted.fields import known_fields
from xted.data import Dataset, Normalizer, shipped
from xted.diffusion.config import EditConfig, PriorConfig
from xted.diffusion.denoiser import Denoiser
from xted.diffusion.guard import TargetModel, fit_for_edit
from xted.diffusion.schedule import Schedule, cosine_schedule
from xted.errors import InputError
from xted.jsonfiles import read_json

FORMAT = "xted-prior/1"


def read_prior_json(path: Path) -> dict[str, Any]:
    data = read_json(path, "not a readable prior file")
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise InputError(f"{path}: not an xted prior (expected format {FORMAT!r})")
    return data


def normalize_returns(raw: Any, return_range: tuple[float, float]) -> Any:
    """Window returns mapped to [0, 1] by the target's (min, max) window return, clipped."""
    low, high = return_range
    return np.clip((np.asarray(raw, np.float64) - low) / max(high - low, 1e-8), 0.0, 1.0)


@dataclass(frozen=True, eq=False)
class Prior:
    """A trained prior ready for editing: config, target normaliser and EMA parameters."""

    config: PriorConfig
    normalizer: Normalizer
    params: Any
    return_range: tuple[float, float]
    step: int = 0
    path: str | None = None
    env: str | None = None  # the env of the target data, where it said
    target_model: TargetModel | None = None  # the guard's (xted.diffusion.guard); None in older priors

    @property
    def model(self) -> Denoiser:
        return Denoiser(self.config.denoiser)

    @property
    def schedule(self) -> Schedule:
        return cosine_schedule(self.config.num_timesteps)

    def edit(self, source: Dataset, kappa: float = 0.5, seed: int = 0, progress: bool = False,
             dynamics: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None, target: Dataset | None = None,
             termination: Callable[[np.ndarray], np.ndarray] | None = None, **fields: Any) -> Dataset:
        """``source`` edited toward this prior's target dynamics (:func:`xted.diffusion.editor.edit_dataset`),
        guarded by default (``guard=False``: the paper's plain edit); ``fields`` set any other
        :class:`EditConfig` field (``temperature``, ``sampler``, ...). ``target``: target data to fit the
        guard's model to, for a prior that holds none; ``termination``: the target's termination rule
        (next observations -> terminal) where xted does not know the env. ``dynamics`` (opt-in) projects
        the edited states onto a target dynamics model's rollout. The edit's report is the result's
        ``metadata["edit"]["report"]``."""
        from xted.diffusion.editor import edit_dataset

        config = EditConfig(kappa=kappa, seed=seed, **known_fields(EditConfig, fields))
        model = None if target is None or not config.guard else fit_for_edit(target, config.guard_disagreement, seed)
        edited, report = edit_dataset(self, source, config, progress, dynamics, model, termination)
        return edited.with_metadata(edit={**edited.metadata["edit"], "report": report})


EXPORTED_PARAMS = "params.msgpack"


def export_prior(prior_dir: str | Path, dest: str | Path, provenance: dict[str, Any] | None = None) -> Path:
    """Write an inference-only copy of a prior (``prior.json`` + EMA parameters): small enough to ship.

    ``provenance`` (for example the command that trained it) is recorded in the copy's ``prior.json``."""
    prior = load_prior(prior_dir)
    dest = Path(dest)
    meta = read_prior_json(Path(prior_dir) / "prior.json")
    if provenance:
        meta["provenance"] = provenance
    with atomic_path(dest) as tmp:
        tmp.mkdir()
        (tmp / "prior.json").write_text(json.dumps(meta, indent=1))
        payload = {"params": jax.device_get(prior.params), "step": prior.step}
        (tmp / EXPORTED_PARAMS).write_bytes(flax.serialization.msgpack_serialize(payload))
        if prior.target_model is not None:
            prior.target_model.save(tmp)
    return dest


def load_prior(source: str | Path) -> Prior:
    """A trained prior: its EMA parameters (latest checkpoint, or an exported prior) with the config
    and normaliser, from its folder (``xted train --out``, or an exported copy) or the name of a
    prior shipped with xted (``halfcheetah-medium-replay-cpu``, ``walker2d-medium-replay-cpu``)."""
    out_dir = Path(source)
    if not out_dir.exists() and isinstance(source, str) and (shipped.prior_dir(source) / "prior.json").is_file():
        out_dir = shipped.prior_dir(source)
    if not out_dir.exists():
        raise InputError(f"{str(source)!r}: no prior folder or shipped prior of that name "
                         f"(shipped priors: {', '.join(shipped.prior_names())})")
    meta_path = out_dir / "prior.json"
    if not meta_path.exists():
        raise InputError(f"{out_dir}: no prior.json (not a prior folder)")
    meta = read_prior_json(meta_path)
    config = PriorConfig.from_dict(meta["config"])
    if (out_dir / EXPORTED_PARAMS).exists():
        try:
            payload = flax.serialization.msgpack_restore((out_dir / EXPORTED_PARAMS).read_bytes())
            params, step = payload["params"], int(payload["step"])
        except (ValueError, KeyError, TypeError) as err:
            raise InputError(f"{out_dir / EXPORTED_PARAMS}: unreadable prior parameters ({err})") from None
    else:
        from xted.diffusion.checkpoint import restore_ema  # a training folder: Orbax and the train state

        try:
            params, step = restore_ema(out_dir, config)
        except InputError:
            raise
        except Exception as err:  # Orbax's errors for a damaged checkpoint have no common type
            raise InputError(f"{out_dir}: unreadable prior checkpoint ({type(err).__name__}: {err})") from None
    return Prior(
        config=config,
        normalizer=Normalizer.from_dict(meta["normalizer"]),
        params=params,
        return_range=tuple(meta["return_range"]),
        step=step,
        path=str(out_dir.resolve()),
        env=meta.get("data", {}).get("env"),
        target_model=TargetModel.load(out_dir),
    )
