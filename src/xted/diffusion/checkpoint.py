"""A prior training folder on disk: ``prior.json`` written once and checked on resume, ``log.csv``,
and Orbax checkpoints of the train state plus the batch generator's state (a killed run resumes
exactly)."""

from __future__ import annotations

import csv
import functools
import json
from pathlib import Path
from typing import Any

import jax
import orbax.checkpoint as ocp

from xted.atomic import atomic_path
from xted.diffusion.config import PriorConfig
from xted.diffusion.objective import init_train_state
from xted.diffusion.prior import read_prior_json
from xted.errors import InputError
from xted.resume import check_same_run


def checkpoint_manager(out_dir: Path) -> ocp.CheckpointManager:
    options = ocp.CheckpointManagerOptions(max_to_keep=2, create=True)
    return ocp.CheckpointManager(out_dir.resolve() / "checkpoints", options=options)


def trained_steps(out_dir: Path) -> int:
    """The step of the last finished checkpoint in ``out_dir`` (0 where there is none); reads the
    folder only (Orbax names a finished step's folder by its number, one in progress otherwise)."""
    folder = Path(out_dir) / "checkpoints"
    return max((int(p.name) for p in folder.iterdir() if p.name.isdigit()), default=0) if folder.is_dir() else 0


def prepare_out_dir(out_dir: Path, meta: dict[str, Any]) -> None:
    """Write ``prior.json``, or check that the one there describes the same run."""
    path = out_dir / "prior.json"
    if path.exists():
        old = read_prior_json(path)
        old_config = PriorConfig.from_dict(old.get("config", {})).to_dict()  # fields added since take their defaults
        check_same_run(out_dir, {"config": old_config, "data": old.get("data", {}).get("fingerprint")},
                       {"config": meta["config"], "data": meta["data"]["fingerprint"]})
        return
    out_dir.mkdir(parents=True, exist_ok=True)
    with atomic_path(path, ".json") as tmp:
        tmp.write_text(json.dumps(meta, indent=1))


def read_log(path: Path, upto: int) -> list[dict[str, float]]:
    if not path.exists():
        return []
    with path.open() as f:
        return [row for row in ({k: float(v) for k, v in r.items()} for r in csv.DictReader(f)) if row["step"] <= upto]


def write_log(path: Path, rows: list[dict[str, float]]) -> None:
    with atomic_path(path, ".csv") as tmp, tmp.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=["step", "loss", "seconds"])
        writer.writeheader()
        writer.writerows({**r, "step": int(r["step"])} for r in rows)


def restore_ema(out_dir: Path, config: PriorConfig) -> tuple[Any, int]:
    manager = checkpoint_manager(out_dir)
    step = manager.latest_step()
    if step is None:
        manager.close()
        raise InputError(f"{out_dir}: no checkpoint yet")
    abstract = jax.eval_shape(functools.partial(init_train_state, config), jax.random.key(0))
    restored = manager.restore(
        step, args=ocp.args.Composite(state=ocp.args.StandardRestore(abstract), sampler=ocp.args.JsonRestore())
    )
    manager.close()
    return restored.state.ema_params, int(step)
