"""Working through the grid: every learner cell without a stored result is trained, its seeds
together, after the edit or oracle data it reads (made once, kept in the cache, reused)."""

from __future__ import annotations

import time
from collections.abc import Callable

from tqdm.auto import tqdm

from xted.data import Dataset, load, save
from xted.pipelines.bench import cells, store
from xted.pipelines.bench.config import BenchConfig
from xted.pipelines.bench.grid import DataCell, Grid, LearnerCell, plan


def pending(grid: Grid) -> list[list[LearnerCell]]:
    """Learner cells without a result, in groups that differ only by seed (grid order)."""
    groups: dict[tuple, list[LearnerCell]] = {}
    for cell in grid.learners.values():
        if store.read_result(grid.config.store, cell) is None:
            groups.setdefault(cell.group, []).append(cell)
    return list(groups.values())


def data_of(grid: Grid, cell: DataCell) -> tuple[Dataset, bool]:
    """The cell's data from the cache where it is there and is what the store recorded; else made
    now (cached, recorded). Returns the data and whether it was made."""
    config = grid.config
    record, path = store.read_result(config.store, cell), store.data_path(config.cache, cell)
    if record is not None and path.is_file():
        data = load(path)
        if data.fingerprint() == record["data_fingerprint"]:
            return data, False
    began = time.perf_counter()
    data = cells.make_data(cell, grid.datasets[cell.source])
    path.parent.mkdir(parents=True, exist_ok=True)
    save(data, path)
    store.write_result(config.store, cell, {
        "kind": cell.kind, "env": cell.env, "target": cell.target, "gap": cell.gap,
        "data_fingerprint": data.fingerprint(), "transitions": len(data),
        "seconds": time.perf_counter() - began})
    return data, True


def run_bench(config: BenchConfig, progress: bool = True, echo: Callable[[str], None] = print) -> list[str]:
    """Compute every missing cell of ``config``'s grid; returns the names of the cells computed."""
    grid = plan(config)
    for message in grid.blocked:
        echo(f"bench: {message}")
    groups = pending(grid)
    todo = sum(len(group) for group in groups)
    echo(f"bench: {len(grid.learners)} learner cells, {len(grid.learners) - todo} done, {todo} to train "
         f"in {len(groups)} groups of seeds")
    made: dict[str, Dataset] = {}
    computed: list[str] = []
    bar = tqdm(total=len(grid.learners), initial=len(grid.learners) - todo, desc="bench cells", unit="cell",
               disable=not progress, smoothing=0.0)
    for group in groups:
        first = group[0]
        bar.set_postfix_str(f"running {len(group)} ({first.env} {first.name.rsplit('-seed', 1)[0]}), "
                            f"{bar.total - bar.n - len(group)} left after them")
        training = []
        for ref in first.training:
            if isinstance(ref, DataCell):
                if ref.key not in made:
                    made[ref.key], fresh = data_of(grid, ref)
                    computed += [ref.name] if fresh else []
                training.append(made[ref.key])
            else:
                training.append(grid.datasets[ref])
        for cell, result in zip(group, cells.train_group(group, training, progress)):
            data_cell = cell.data_cell
            identity = {"env": cell.env, "target": cell.target, "gap": cell.gap, "column": cell.column,
                        "algo": cell.algo}
            fingerprints = {"training_data": [data.fingerprint() for data in training]}
            if data_cell is not None:
                fingerprints[f"{data_cell.kind}_key"] = data_cell.key
            store.write_result(config.store, cell, {**identity, **result, **fingerprints})
            computed.append(cell.name)
        bar.update(len(group))
    bar.close()
    return computed
