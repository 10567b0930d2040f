"""Working through the grid: every learner cell without a stored result is trained, its seeds
together, after the edit or oracle data it reads (made once, kept in the cache, reused).

The pieces here are shared by both executors: ``pending`` (what is left), ``data_of`` (a data
cell from the cache or made now), ``group_records`` (train one group of seeds; what the store
keeps of each) and ``store_records``. The local executor runs the groups one after another in
this process; ``ray_executor`` runs the same functions as Ray tasks and writes what they return.
The local executor claims each group and data cell before computing it (:mod:`claims`), so a
second process on the same store skips the groups the first is training and waits for its data.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import importlib.metadata
import os
import platform
import shutil
import time
from collections.abc import Callable, Sequence
from pathlib import Path

from tqdm.auto import tqdm

from xted.data import Dataset, load, save, split_heldout
from xted.diffusion.prior import export_prior
from xted.diffusion.training import train_prior_folder
from xted.pipelines.bench import cells, claims, store
from xted.pipelines.bench.config import BenchConfig, RayConfig
from xted.pipelines.bench.grid import DataCell, Grid, LearnerCell, PriorCell, plan


@dataclasses.dataclass(frozen=True)
class Work:
    """What computes cells: ``make_data(cell, source)`` and ``train_group(cells, training, progress)``.

    The defaults are the real computations; a test may pass stand-ins (a Ray task receives them
    as arguments, so they reach its worker)."""

    make_data: Callable[[DataCell, Dataset], Dataset] = cells.make_data
    train_group: Callable[[Sequence[LearnerCell], Sequence[Dataset], bool], list[dict]] = cells.train_group


class CellsFailed(RuntimeError):
    """Cells that failed after their retries: ``failed`` pairs each cell's name with why; ``computed``
    names the cells whose results were stored before and around them."""

    def __init__(self, failed: list[tuple[str, str]], computed: list[str]):
        super().__init__(f"{len(failed)} cells failed: " + "; ".join(f"{name} ({why})" for name, why in failed))
        self.failed, self.computed = failed, computed


COMPUTING_LIBRARIES = ("xted", "jax", "jaxlib", "flax", "optax", "numpy", "mujoco", "gymnasium")


@functools.cache
def library_versions() -> dict[str, str]:
    """The versions of the libraries that compute a cell, recorded in every cell's result."""
    return {name: importlib.metadata.version(name) for name in COMPUTING_LIBRARIES}


def pending(grid: Grid) -> list[list[LearnerCell]]:
    """Learner cells without a current result (none, or one trained on other data than its data cells
    record), in groups that differ only by seed (grid order)."""
    groups: dict[tuple, list[LearnerCell]] = {}
    for cell in grid.learners.values():
        if store.current_result(grid.config.store, cell) is None:
            groups.setdefault(cell.group, []).append(cell)
    return list(groups.values())


def data_needed(groups: list[list[LearnerCell]]) -> list[DataCell]:
    """The data cells the groups read, each once, in the order the groups need them."""
    found: dict[str, DataCell] = {}
    for group in groups:
        for ref in group[0].training:
            if isinstance(ref, DataCell):
                found.setdefault(ref.key, ref)
    return list(found.values())


def cached_data(grid: Grid, cell: DataCell) -> Dataset | None:
    """The cell's data from the cache where it is there and is what the store recorded."""
    record, path = store.read_result(grid.config.store, cell), store.data_path(grid.config.cache, cell)
    if record is not None and path.is_file():
        data = load(path)
        if data.fingerprint() in store.makes(record):
            return data
    return None


def make_data(cell: DataCell, source: Dataset, make: Callable[[DataCell, Dataset], Dataset]) -> tuple[Dataset, float]:
    """The cell's data made from its source, and the seconds it took."""
    began = time.perf_counter()
    data = make(cell, source)
    return data, time.perf_counter() - began


def keep_data(config: BenchConfig, cell: DataCell, data: Dataset, seconds: float) -> None:
    """Cache made data and record it in the store (both atomically). A cell recorded already (made on
    another checkout, whose cache this one lacks) keeps its record: a remake in other bytes is added to
    it as one more make, so the learners trained on the first stay current."""
    path = store.data_path(config.cache, cell)
    path.parent.mkdir(parents=True, exist_ok=True)
    save(data, path)
    make = {"data_fingerprint": data.fingerprint(), "seconds": seconds, "versions": library_versions(),
            "machine": machine()}
    record = store.read_result(config.store, cell)
    if record is None:
        record = {"kind": cell.kind, "env": cell.env, "target": cell.target, "gap": cell.gap,
                  "transitions": len(data), **make}
    elif make["data_fingerprint"] in store.makes(record):
        return
    else:
        record = {**record, "remade": [*record.get("remade", ()), make]}
    store.write_result(config.store, cell, record)


def machine() -> str:
    """The CPU a data cell was made on (its float reductions decide the made data's last bits)."""
    return f"{platform.machine()} {cpu_model()} x{os.cpu_count()}"


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def kept_prior(config: BenchConfig, cell: PriorCell) -> Path:
    """Where the bench keeps an exported copy of a prior it trained, beside its store (committed with
    the results, so that a fresh checkout restores the prior instead of training it again)."""
    return Path(config.store).parent / "priors" / cell.env / cell.name


def prior_of(grid: Grid, cell: PriorCell, progress: bool = False) -> bool:
    """Train the prior cell's prior into its folder (resuming one cut short) unless the store records
    it finished and the folder is there, or its kept copy is (restored into the folder); whether it
    trained now. A prior trained now is exported to its kept copy. The prior is claimed first: where
    another process holds it, wait for that one and use what it made. The store's record is written
    last, so a prior whose training was cut off is never taken for a finished one."""
    with claims.claim(grid.config.store, cell.name) as mine:
        if mine:
            return _train_prior(grid, cell, progress)
    claims.wait_for_release(grid.config.store, cell.name)
    return prior_of(grid, cell, progress)


def _train_prior(grid: Grid, cell: PriorCell, progress: bool) -> bool:
    folder, kept = Path(cell.folder), kept_prior(grid.config, cell)
    if store.read_result(grid.config.store, cell) is not None:
        if (folder / "prior.json").is_file():
            return False
        if (kept / "prior.json").is_file():
            shutil.copytree(kept, folder)
            return False
    training, _ = split_heldout(grid.datasets[cell.source], cell.heldout_episodes)
    began = time.perf_counter()
    train_prior_folder(training, folder, cell.config, cell.steps, progress=progress)
    seconds = time.perf_counter() - began
    if not kept.exists():
        export_prior(folder, kept, provenance={"bench_prior_cell": cell.name, "inputs": cell.inputs})
    store.write_result(grid.config.store, cell, {
        "kind": cell.kind, "env": cell.env, "target": cell.target, "steps": cell.steps,
        "folder": cell.folder, "seconds": seconds, "versions": library_versions()})
    return True


def data_of(grid: Grid, cell: DataCell, work: Work = Work(), progress: bool = False) -> tuple[Dataset, list[str]]:
    """The cell's data from the cache, else made now (cached, recorded, after its prior where the
    bench trains that); and the names of the cells computed for it."""
    data = cached_data(grid, cell)
    if data is not None:
        return data, []
    with claims.claim(grid.config.store, cell.name) as mine:
        if mine:
            return _make_data(grid, cell, work, progress)
    claims.wait_for_release(grid.config.store, cell.name)  # another process makes it: use its result
    return data_of(grid, cell, work, progress)


def _make_data(grid: Grid, cell: DataCell, work: Work, progress: bool) -> tuple[Dataset, list[str]]:
    computed = [cell.prior_cell.name] if cell.prior_cell is not None and prior_of(grid, cell.prior_cell, progress) else []
    data, seconds = make_data(cell, grid.datasets[cell.source], work.make_data)
    keep_data(grid.config, cell, data, seconds)
    return data, [*computed, cell.name]


def group_records(group: Sequence[LearnerCell], training: Sequence[Dataset], work: Work,
                  progress: bool = False) -> list[dict]:
    """Train one group of seeds together; each cell's result as the store keeps it."""
    data_cell = group[0].data_cell
    fingerprints = {"training_data": [data.fingerprint() for data in training]}
    if data_cell is not None:
        fingerprints[f"{data_cell.kind}_key"] = data_cell.key
    began = time.perf_counter()
    results = work.train_group(group, training, progress)
    cost = {"group_seconds": time.perf_counter() - began, "group_size": len(group)}  # the seeds' shared wall time
    records = []
    for cell, result in zip(group, results, strict=True):
        identity = {"env": cell.env, "target": cell.target, "gap": cell.gap, "column": cell.column,
                    "algo": cell.algo}
        records.append({**identity, **result, **fingerprints, **cost, "versions": library_versions()})
    return records


def store_records(config: BenchConfig, group: Sequence[LearnerCell], records: Sequence[dict]) -> list[str]:
    """Write each cell's record (atomically); returns the cells' names."""
    for cell, record in zip(group, records, strict=True):
        store.write_result(config.store, cell, record)
    return [cell.name for cell in group]


def group_label(group: Sequence[LearnerCell]) -> str:
    first = group[0]
    return f"{first.env} {first.name.rsplit('-seed', 1)[0]}"


def group_claim(group: Sequence[LearnerCell]) -> str:
    """The claim's name of a group: its label and a digest of its cells' keys."""
    digest = hashlib.sha256("".join(sorted(cell.key for cell in group)).encode()).hexdigest()[:12]
    return f"{group_label(group).replace(' ', '-')}-{digest}"


def run_local(grid: Grid, groups: list[list[LearnerCell]], progress: bool, work: Work,
              echo: Callable[[str], None] = print) -> list[str]:
    """One group after another in this process, each after the data it reads; a group another
    process has claimed is skipped, one it finished meanwhile too."""
    computed: list[str] = []
    bar = tqdm(total=len(grid.learners), initial=len(grid.learners) - sum(map(len, groups)), desc="bench cells",
               unit="cell", disable=not progress, smoothing=0.0)
    made: dict[str, Dataset] = {}
    for group in groups:
        with claims.claim(grid.config.store, group_claim(group)) as mine:
            if not mine:
                echo(f"bench: skipped {group_label(group)}: another process is training it")
            elif any(store.current_result(grid.config.store, cell) is None for cell in group):
                bar.set_postfix_str(f"running {len(group)} ({group_label(group)}), "
                                    f"{bar.total - bar.n - len(group)} left after them")
                computed += _run_group(grid, group, made, work, progress)
        bar.update(len(group))
    bar.close()
    return computed


def _run_group(grid: Grid, group: list[LearnerCell], made: dict[str, Dataset], work: Work,
               progress: bool) -> list[str]:
    """Train one group after the data it reads (made now where no other group made it); the names
    of the cells computed."""
    computed: list[str] = []
    training = []
    for ref in group[0].training:
        if isinstance(ref, DataCell):
            if ref.key not in made:
                made[ref.key], fresh = data_of(grid, ref, work, progress)
                computed += fresh
            training.append(made[ref.key])
        else:
            training.append(grid.datasets[ref])
    return computed + store_records(grid.config, group, group_records(group, training, work, progress))


def train_priors(grid: Grid, progress: bool, echo: Callable[[str], None]) -> list[str]:
    """Train (or restore) every prior the grid's edits read, and nothing else; the names of those
    trained now. Priors take the longest of any cell: training them ahead lets a later run, here or
    in a fresh checkout (their exported copies are committed), start with its edits."""
    priors = [cell for cell in grid.cells() if isinstance(cell, PriorCell)]
    echo(f"bench: {len(priors)} priors read by the grid's edits")
    return [cell.name for cell in priors if prior_of(grid, cell, progress)]


def run_bench(config: BenchConfig, progress: bool = True, echo: Callable[[str], None] = print,
              ray: RayConfig | None = None, work: Work = Work(), priors_only: bool = False) -> list[str]:
    """Compute every missing cell of ``config``'s grid, here or (``ray``) as Ray tasks; returns the
    names of the cells computed. Cells that fail on Ray raise ``CellsFailed`` once every other
    cell's result is stored. ``priors_only``: train the grid's priors here and stop."""
    if ray is not None:
        from xted.pipelines.bench import ray_executor

        ray_executor.import_ray()  # refuse a missing Ray before planning
    grid = plan(config)
    if priors_only:
        return train_priors(grid, progress, echo)
    groups = pending(grid)
    todo = sum(len(group) for group in groups)
    where = "" if ray is None else " as Ray tasks (a task is a group of seeds, as locally)"
    echo(f"bench: {len(grid.learners)} learner cells, {len(grid.learners) - todo} done, {todo} to train "
         f"in {len(groups)} groups of seeds{where}")
    if ray is None:
        return run_local(grid, groups, progress, work, echo)
    return ray_executor.run_on_ray(grid, groups, ray, progress, work, echo)
