"""``xted bench run --executor ray``: the grid's work as Ray tasks.

A task is what the local executor computes in one go: one data cell (an edit or an oracle
relabelling), or one group of learner cells that differ only by seed, trained together as locally
(one vmapped ``train_offline``), so results equal the local executor's bitwise on CPU. A learner
task takes the object ref of the data cell it reads as an argument, so Ray starts it only once that
data exists, wherever it was made. Tasks return their results and only the driver writes the store
and the cache, one result at a time and each atomically: a cluster needs no shared file system,
two tasks finishing together never write at once, and a dying worker leaves nothing half-written.
A task whose worker dies is run again up to ``RayConfig.retries`` times; a cell that still fails
is reported by name (``CellsFailed``) after every other result is stored. A prior the bench
trains (a target with none shipped or given) is trained by the driver, into its cache, before its
edit tasks start: on a multi-node cluster that cache must be on a path every node reads.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from pathlib import Path

from tqdm.auto import tqdm

from xted.data import Dataset
from xted.errors import InputError
from xted.pipelines.bench.columns import DATA_KINDS
from xted.pipelines.bench.config import RayConfig
from xted.pipelines.bench.grid import DataCell, Grid, LearnerCell, folder_fingerprint
from xted.pipelines.bench.run import (
    CellsFailed,
    Work,
    cached_data,
    data_needed,
    group_label,
    group_records,
    keep_data,
    make_data,
    prior_of,
    store_records,
)


def import_ray():
    try:
        import ray
    except ImportError:
        raise InputError("--executor ray needs Ray, which is not installed here: pip install 'xted[ray]'") from None
    return ray


def _make(cell: DataCell, source: Dataset, make: Callable) -> tuple[Dataset, float]:
    """Task body of a data cell (on a worker)."""
    if cell.kind == "edit" and not _prior_here(cell):
        raise InputError(f"the prior folder {cell.prior} on this worker differs from the driver's (or is "
                         "missing): install the same xted on every node, or put --prior folders on a shared path")
    return make_data(cell, source, make)


def _prior_here(cell: DataCell) -> bool:
    """The edit's prior folder on this worker is the driver's: the one it trained (into its cache), or the given one."""
    folder = Path(cell.prior)
    if cell.prior_cell is not None:
        return (folder / "prior.json").is_file()
    return folder_fingerprint(folder) == cell.inputs["prior"]


def _train(group: Sequence[LearnerCell], work: Work, *training: Dataset) -> list[dict]:
    """Task body of a group of seeds (on a worker)."""
    return group_records(group, training, work)


def connect(ray, settings: RayConfig) -> bool:
    """Connect to ``settings.address`` or start a local instance; True where this call did (and so
    must shut it down). A Ray already initialised in this process (a notebook, a test) is used as is."""
    if ray.is_initialized():
        return False
    if settings.address is None:
        ray.init(include_dashboard=False)
        return True
    try:
        ray.init(address=settings.address)
    except ConnectionError as err:
        raise InputError(
            f"--address {settings.address}: cannot connect ({err}). Start a head with `ray start --head`; if it uses "
            "token authentication, set RAY_AUTH_MODE=token here with its token in ~/.ray/auth_token (`ray "
            "get-auth-token` on the head); or leave out --address for a local instance") from None
    return True


def run_on_ray(grid: Grid, groups: list[list[LearnerCell]], settings: RayConfig, progress: bool, work: Work,
               echo: Callable[[str], None]) -> list[str]:
    ray = import_ray()
    started = connect(ray, settings)
    try:
        return _run(ray, grid, groups, settings, progress, work, echo)
    finally:
        if started:
            ray.shutdown()


def _why(ray, err: Exception, retries: int) -> str:
    if isinstance(err, ray.exceptions.RayTaskError) and getattr(err, "cause", None) is not None:
        return f"{type(err.cause).__name__}: {err.cause}"
    if isinstance(err, ray.exceptions.WorkerCrashedError):
        return f"its worker died, {retries + 1} times"
    return f"{type(err).__name__}: {str(err).splitlines()[0] if str(err) else ''}"


def _run(ray, grid: Grid, groups: list[list[LearnerCell]], settings: RayConfig, progress: bool, work: Work,
         echo: Callable[[str], None]) -> list[str]:
    resources = ray.cluster_resources()
    gpus = settings.gpus_per_task
    if gpus is None:
        gpus = 1 if resources.get("GPU", 0) > 0 else 0
    echo(f"bench: Ray cluster of {resources.get('CPU', 0):g} CPUs and {resources.get('GPU', 0):g} GPUs; each task "
         f"reserves {settings.cpus_per_task} CPUs (edits and learners {gpus:g} GPUs), retried {settings.retries} times")
    options = dict(num_cpus=settings.cpus_per_task, max_retries=settings.retries, retry_exceptions=False)
    make = ray.remote(num_returns=2, **options)(_make)
    train = ray.remote(num_gpus=gpus, **options)(_train)

    shared: dict[str, object] = {}  # dataset name -> object ref: each dataset crosses to the cluster once

    def put(name: str):
        if name not in shared:
            shared[name] = ray.put(grid.datasets[name])
        return shared[name]

    inputs: dict[str, object] = {}  # data cell key -> object ref of its data
    waiting: dict[object, tuple] = {}  # object ref -> ("data", cell, seconds ref) or ("group", cells)
    computed: list[str] = []
    for cell in data_needed(groups):
        data = cached_data(grid, cell)
        if data is not None:
            inputs[cell.key] = ray.put(data)
            continue
        if cell.prior_cell is not None and prior_of(grid, cell.prior_cell, progress):  # here, before its edits
            computed.append(cell.prior_cell.name)
        remote_cell = cell if cell.prior is None else dataclasses.replace(cell, prior=str(Path(cell.prior).resolve()))
        data_ref, seconds_ref = make.options(name=cell.name, num_gpus=gpus if DATA_KINDS[cell.kind].accelerator else 0).remote(
            remote_cell, put(cell.source), work.make_data)
        inputs[cell.key] = data_ref
        waiting[data_ref] = ("data", cell, seconds_ref)
    for group in groups:
        training = [inputs[ref.key] if isinstance(ref, DataCell) else put(ref) for ref in group[0].training]
        waiting[train.options(name=group_label(group)).remote(group, work, *training)] = ("group", group)

    failures: list[tuple[DataCell | list[LearnerCell], str]] = []
    bar = tqdm(total=len(grid.learners), initial=len(grid.learners) - sum(map(len, groups)), desc="bench cells",
               unit="cell", disable=not progress, smoothing=0.0)
    while waiting:
        [ready], _ = ray.wait(list(waiting), num_returns=1)
        kind, what, *seconds_ref = waiting.pop(ready)
        try:
            if kind == "data":
                data, seconds = ray.get([ready, *seconds_ref])
                keep_data(grid.config, what, data, seconds)
                computed.append(what.name)
            else:
                computed += store_records(grid.config, what, ray.get(ready))
        except ray.exceptions.RayError as err:
            failures.append((what, _why(ray, err, settings.retries)))
        if kind == "group":
            bar.update(len(what))
    bar.close()
    if failures:
        raise CellsFailed(_named(failures), computed)
    return computed


def _named(failures: list[tuple[DataCell | list[LearnerCell], str]]) -> list[tuple[str, str]]:
    """(name, why) per failed cell; a learner whose data cell failed says so rather than repeat its error."""
    failed_data = {what.key for what, _ in failures if isinstance(what, DataCell)}
    named = []
    for what, why in failures:
        if isinstance(what, DataCell):
            named.append((what.name, why))
            continue
        data_cell = what[0].data_cell
        if data_cell is not None and data_cell.key in failed_data:
            why = f"reads {data_cell.name}, which failed"
        named += [(cell.name, why) for cell in what]
    return named
