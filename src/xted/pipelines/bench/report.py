"""The table from stored results, nothing recomputed: one row per env x target x gap x column x
algo (mean, std and 95% t-interval of the final normalised score over the seeds found, and the
learning curve of those seeds), its markdown with each mixed column's gain against Tgt as the
paper prints it, and the aggregate over tasks (IQM per column, the probability that Tgt+Edited
improves on Tgt and on Tgt+Src; :mod:`xted.analysis.stats`), and what the cells cost."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from xted.analysis.stats import improvement_interval, iqm_interval, t_interval
from xted.pipelines.bench import store
from xted.pipelines.bench.columns import COLUMNS, TGT
from xted.pipelines.bench.grid import Grid
from xted.pipelines.bench.paper import paper_cell

MISSING = "—"


def table_rows(grid: Grid) -> list[dict]:
    """Each row of the grid with the seeds' final scores found in the store, and the paper's cell
    (``paper``: mean and std, None where it printed none)."""
    rows = []
    for row in grid.rows:
        results = [store.read_result(grid.config.store, cell) for cell in row.cells]
        found = [result for result in results if result is not None]
        scores = [result["final_score"] for result in found]
        other_data = sum(store.trained_on_other_data(grid.config.store, cell, result)
                         for cell, result in zip(row.cells, results) if result is not None)
        rows.append({"env": row.env, "target": row.target, "gap": row.gap, "column": row.column, "algo": row.algo,
                     **score_summary(scores), "scores": scores, "curve": learning_curve(found),
                     "trained_on_other_data": other_data,
                     "paper": paper_cell(row.env, row.target, row.gap, row.column, row.algo)})
    return rows


def learning_curve(results: Sequence[dict]) -> list[dict]:
    """Mean and std over the seeds' results of the normalised score at every evaluation step that
    all of them recorded."""
    histories = [{e["step"]: e["normalized_score"] for e in result.get("evals", [])} for result in results]
    if not histories:
        return []
    steps = sorted(set.intersection(*(set(history) for history in histories)))
    return [{"step": step, **score_summary([history[step] for history in histories])} for step in steps]


def task_rows(env: str, target: str, gap: str, columns: Sequence[str], store: str) -> list[dict]:
    """The lite table's rows (IQL, the default seeds and steps) of one task, from ``store``."""
    from xted.pipelines.bench.config import BenchConfig
    from xted.pipelines.bench.grid import plan

    config = BenchConfig(envs=(env,), targets=(target,), gaps=(gap,), columns=tuple(columns), store=store)
    return table_rows(plan(config))


def score_summary(scores: Sequence[float]) -> dict:
    """Mean and std (over seeds, ddof 0) of the final scores and the mean's 95% t-interval
    (``ci95``; None below two seeds); None for none."""
    if not scores:
        return {"mean": None, "std": None, "ci95": None, "n_seeds": 0}
    return {"mean": float(np.mean(scores)), "std": float(np.std(scores)), "ci95": t_interval(scores),
            "n_seeds": len(scores)}


# Aggregates over tasks: each column against those it declares it is compared with (the paper's claims:
# Table 1; Table 2 for DARA; §5.4 for augmentation; the multi-source appendix; the head-to-head).
IMPROVEMENTS = tuple((column.name, baseline) for column in COLUMNS.values() for baseline in column.compared_with)


def aggregate(rows: list[dict]) -> list[dict]:
    """Per algo: each column's IQM over all (task, seed) scores, and P(edited > unedited) over
    the tasks (env, target, gap) where both were run; each with its stratified-bootstrap 95% interval,
    and beside P(improvement) the paper's form of the claim (``mean_comparison``)."""
    out = []
    for algo in dict.fromkeys(row["algo"] for row in rows):
        scores, paper_means = {}, {}
        for row in rows:
            if row["algo"] == algo and row["scores"]:
                scores.setdefault(row["column"], {})[(row["env"], row["target"], row["gap"])] = row["scores"]
            if row["algo"] == algo and row["paper"]:
                paper_means.setdefault(row["column"], {})[(row["env"], row["target"], row["gap"])] = row["paper"]["mean"]
        for column, tasks in scores.items():
            out.append({"algo": algo, "measure": "IQM", "column": column, **iqm_interval(list(tasks.values()))})
        # Tgt's cell is one per target: the same scores on every gap's row and against a per-target column.
        per_target_tgt = {(env, target, None): found for (env, target, _), found in scores.get(TGT, {}).items()}
        for better, baseline in IMPROVEMENTS:
            against = per_target_tgt if baseline == TGT and COLUMNS[better].per_target else scores.get(baseline, {})
            shared = [task for task in scores.get(better, {}) if task in against]
            if shared:
                better_scores, baseline_scores = [scores[better][t] for t in shared], [against[t] for t in shared]
                out.append({"algo": algo, "measure": "P(improvement)", "column": f"{better} > {baseline}",
                            **improvement_interval(better_scores, baseline_scores),
                            **mean_comparison(better_scores, baseline_scores),
                            **paper_comparison(shared, paper_means.get(better, {}), paper_means.get(baseline, {}))})
    return out


def mean_comparison(better: list[list[float]], baseline: list[list[float]]) -> dict:
    """The paper's form of a claim over tasks: on how many the better column's mean over seeds is at
    least the baseline's (``ahead``), and the change of its total of means against the baseline's
    (``total_gain``, %; None where the baseline's total is 0)."""
    better_means, baseline_means = [float(np.mean(s)) for s in better], [float(np.mean(s)) for s in baseline]
    ahead = sum(b >= a for b, a in zip(better_means, baseline_means))
    total = sum(baseline_means)
    return {"ahead": ahead, "total_gain": None if total == 0 else 100 * (sum(better_means) - total) / abs(total)}


def paper_comparison(tasks: list[tuple], better: dict[tuple, float], baseline: dict[tuple, float]) -> dict:
    """The paper's own cells in the form of :func:`mean_comparison`, over those of ``tasks`` where it
    printed both columns: so a claim checked on part of the grid is set beside the paper's figure
    on the same part, not its figure over all 18 tasks."""
    printed = [task for task in tasks if task in better and _paper_baseline(task, baseline) is not None]
    if not printed:
        return {}
    found = mean_comparison([[better[task]] for task in printed], [[_paper_baseline(task, baseline)] for task in printed])
    return {"paper_tasks": len(printed), "paper_ahead": found["ahead"], "paper_total_gain": found["total_gain"]}


def _paper_baseline(task: tuple, baseline: dict[tuple, float]) -> float | None:
    """The paper's baseline cell of a task; a per-target column's (gap None) is compared with Tgt's on any gap."""
    if task in baseline:
        return baseline[task]
    return next((mean for (env, target, _), mean in baseline.items() if task[2] is None and (env, target) == task[:2]),
                None)


def aggregate_markdown(rows: list[dict]) -> str:
    """The aggregate block: one line per algo, measure and column; beside each P(improvement) the
    paper's count and total over the same tasks."""
    out = ["| algo | measure | column | value | 95% interval | tasks | mean ahead | total | the paper, same tasks |",
           "|---|---|---|---|---|---|---|---|---|"]
    for row in aggregate(rows):
        low, high = row["ci95"]
        ahead = f"{row['ahead']}/{row['tasks']}" if "ahead" in row else ""
        total = "" if row.get("total_gain") is None else f"{row['total_gain']:+.1f}%"
        paper = ""
        if "paper_ahead" in row:
            paper = f"{row['paper_ahead']}/{row['paper_tasks']}" + (
                "" if row["paper_total_gain"] is None else f", {row['paper_total_gain']:+.1f}%")
        out.append(f"| {row['algo']} | {row['measure']} | {row['column']} | {row['value']:.2f} | "
                   f"[{low:.2f}, {high:.2f}] | {row['tasks']} | {ahead} | {total} | {paper} |")
    return "\n".join(out)


def gain(value: float | None, baseline: float | None) -> str:
    """The relative change against Tgt, as the paper prints it (+17.5%)."""
    if value is None or baseline is None or baseline == 0:
        return ""
    return f" ({100 * (value - baseline) / abs(baseline):+.1f}%)"


def markdown(rows: list[dict], paper: bool = False) -> str:
    """Columns side by side per env, target, gap and algo (mean ± std over seeds [95% t-interval]);
    a Total line per algo (sums of means). ``paper``: under each line the paper's cells of it, and
    under each Total the paper's over the same rows. Columns of one cell per target (augmentation,
    several sources) follow in a table of their own, one line per target, beside its Tgt."""
    table = [row for row in rows if row["gap"] is not None]
    per_target = [row for row in rows if row["gap"] is None]
    sections = [_table(table, ("env", "target", "gap"), paper)] if table else []
    if per_target:
        tgt = {(row["env"], row["target"], row["algo"]): row for row in table if row["column"] == TGT}
        with_tgt = []
        for key in dict.fromkeys((row["env"], row["target"], row["algo"]) for row in per_target):
            if key in tgt:
                with_tgt.append(tgt[key])
            with_tgt += [row for row in per_target if (row["env"], row["target"], row["algo"]) == key]
        sections.append(_table(with_tgt, ("env", "target"), paper))
    return "\n\n".join(sections)


def compact_markdown(rows: list[dict]) -> str:
    """One line per task (env, target, gap; the algo too where there are several), each cell mean ± std
    [95% interval] with the paper's mean in brackets, "not run" where the store has no seed of it. A column of the
    target's data alone (Tgt) is one cell per target: in full on its first line, its mean on the others."""
    columns = list(dict.fromkeys(row["column"] for row in rows))
    several_algos = len({row["algo"] for row in rows}) > 1
    lines: dict[tuple, dict[str, dict]] = {}
    for row in rows:
        task = (row["env"], row["target"], row["gap"] or "(per target)", *((row["algo"],) if several_algos else ()))
        lines.setdefault(task, {})[row["column"]] = row
    out = ["| task | " + " | ".join(columns) + " |", "|" + "---|" * (len(columns) + 1)]
    shown_in_full = set()
    for task, found in lines.items():
        cells = []
        for column in columns:
            per_target = (task[0], task[1], *task[3:], column) if COLUMNS[column].data == ("target",) else None
            cells.append(_compact(found.get(column), repeated=per_target is not None and per_target in shown_in_full))
            if per_target is not None and found.get(column) is not None and found[column]["mean"] is not None:
                shown_in_full.add(per_target)
        out.append(f"| {' '.join(task)} | " + " | ".join(cells) + " |")
    return "\n".join(out)


def _compact(cell: dict | None, repeated: bool) -> str:
    if cell is None:
        return MISSING
    paper = f" ({cell['paper']['mean']:.1f})" if cell.get("paper") else ""
    if cell["mean"] is None:
        return "not run" + paper
    if repeated:
        return f"{cell['mean']:.1f}" + paper
    interval = f" [{cell['ci95'][0]:.1f}, {cell['ci95'][1]:.1f}]" if cell.get("ci95") is not None else ""
    return f"{cell['mean']:.1f} ± {cell['std']:.1f}{interval}" + paper


def _table(rows: list[dict], labels: tuple[str, ...], paper: bool) -> str:
    columns = list(dict.fromkeys(row["column"] for row in rows))
    lines: dict[tuple, dict[str, dict]] = {}
    for row in rows:
        lines.setdefault((*(row[label] for label in labels), row["algo"]), {})[row["column"]] = row
    header = [*labels, "algo", *columns]
    blank = "|" + " |" * len(labels) + " "  # the label cells left empty
    total = "| Total |" + " |" * (len(labels) - 1) + " "
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for (*names, algo), found in lines.items():
        cells = [_shown(found.get(column), found.get(TGT), column) for column in columns]
        out.append("| " + " | ".join([*names, algo, *cells]) + " |")
        if paper and any(row["paper"] for row in found.values()):
            cells = [_shown(found[c]["paper"] if c in found else None, found.get(TGT, {}).get("paper"), c)
                     for c in columns]
            out.append(blank + "paper | " + " | ".join(cells) + " |")
    for algo in dict.fromkeys(row["algo"] for row in rows):
        mine = [row for row in rows if row["algo"] == algo]
        out.append(total + algo + " | " + " | ".join(_totals(mine, columns)) + " |")
        if paper and any(row["paper"] for row in mine):
            papers = [{**row, **(row["paper"] or {"mean": None})} for row in mine]
            out.append(total + "paper | " + " | ".join(_totals(papers, columns)) + " |")
    return "\n".join(out)


def _shown(cell: dict | None, tgt: dict | None, column: str) -> str:
    """One cell: mean ± std [interval where there is one], and its gain against Tgt in a mixed column."""
    if cell is None or cell["mean"] is None:
        return MISSING
    shown = f"{cell['mean']:.1f} ± {cell['std']:.1f}"
    if cell.get("ci95") is not None:
        shown += f" [{cell['ci95'][0]:.1f}, {cell['ci95'][1]:.1f}]"
    shown += gain(cell["mean"], (tgt or {}).get("mean")) if _against_tgt(column) else ""
    if cell.get("trained_on_other_data"):
        shown += f" ({cell['trained_on_other_data']} seeds trained on other data: rerun)"
    return shown


def _totals(rows: list[dict], columns: list[str]) -> list[str]:
    """Per column the sum of the rows' means (missing where any row has none), with the gain against Tgt's."""
    totals = {}
    for column in columns:
        means = [row["mean"] for row in rows if row["column"] == column]
        totals[column] = None if None in means else float(sum(means))
    return [MISSING if totals[c] is None else f"{totals[c]:.1f}" + (gain(totals[c], totals.get(TGT))
                                                                     if _against_tgt(c) else "")
            for c in columns]


def _against_tgt(column: str) -> bool:
    """A column that adds data to Tgt's (a source's, or made from the target): shown with its gain."""
    return COLUMNS[column].adds_to_target


def curves_markdown(rows: list[dict]) -> str:
    """One line per row: the mean ± std over seeds at each evaluation step (columns: the steps)."""
    steps = sorted({point["step"] for row in rows for point in row["curve"]})
    header = ["env", "target", "gap", "column", "algo", *(f"{step:,}" for step in steps)]
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for row in rows:
        points = {point["step"]: point for point in row["curve"]}
        cells = [f"{points[step]['mean']:.1f} ± {points[step]['std']:.1f}" if step in points else MISSING
                 for step in steps]
        out.append("| " + " | ".join([row["env"], row["target"], row["gap"], row["column"], row["algo"], *cells]) + " |")
    return "\n".join(out)


def cost_rows(grid: Grid) -> list[dict]:
    """The wall-clock hours the grid's stored cells took on the machines that computed them: per
    group of learner seeds (each seed's share of its group's time, summed over the seeds found),
    then each edit, oracle and bench-trained prior once, however many groups read it. ``unrecorded``
    counts the cells found without a time (stored before times were kept)."""
    groups: dict[tuple, dict] = {}
    made: dict[str, dict] = {}
    for cell in grid.learners.values():
        result = store.read_result(grid.config.store, cell)
        if result is None:
            continue
        row = groups.setdefault(cell.group, {"kind": "learner", "group": " ".join(str(part) for part in cell.group
                                                                                  if part is not None),
                                             "column": cell.column, "cells": 0, "hours": 0.0, "unrecorded": 0})
        row["cells"] += 1
        if "group_seconds" in result:
            row["hours"] += result["group_seconds"] / result["group_size"] / 3600
        else:
            row["unrecorded"] += 1
        data_cell = cell.data_cell
        for made_cell in (data_cell, data_cell and data_cell.prior_cell):
            if made_cell is not None and made_cell.key not in made:
                record = store.read_result(grid.config.store, made_cell)
                if record is not None:
                    made[made_cell.key] = {"kind": made_cell.kind, "group": f"{made_cell.env} {made_cell.name}",
                                           "column": cell.column, "cells": 1, "hours": record.get("seconds", 0.0) / 3600,
                                           "unrecorded": int("seconds" not in record)}
    return [*groups.values(), *made.values()]


def cost_markdown(costs: list[dict]) -> str:
    """The cost block: one line per group and a total; then per column, its learners' hours and those
    of the data made for it (an edit read by several columns counts under the first), per timed cell."""
    out = ["| cost: group | kind | cells | hours | cells without a time |", "|---|---|---|---|---|"]
    for row in costs:
        out.append(f"| {row['group']} | {row['kind']} | {row['cells']} | {row['hours']:.2f} | {row['unrecorded']} |")
    total = {key: sum(row[key] for row in costs) for key in ("cells", "hours", "unrecorded")}
    out.append(f"| Total | | {total['cells']} | {total['hours']:.2f} | {total['unrecorded']} |")
    out += ["", "| cost: column | learner cells | learner hours | hours of data made for it | hours per learner cell |",
            "|---|---|---|---|---|"]
    for column in dict.fromkeys(row["column"] for row in costs):
        learners = [row for row in costs if row["column"] == column and row["kind"] == "learner"]
        cells, hours = sum(row["cells"] for row in learners), sum(row["hours"] for row in learners)
        data = sum(row["hours"] for row in costs if row["column"] == column and row["kind"] != "learner")
        timed = cells - sum(row["unrecorded"] for row in learners)
        per_cell = f"{(hours + data) / timed:.3f}" if timed else "-"
        out.append(f"| {column} | {cells} | {hours:.2f} | {data:.2f} | {per_cell} |")
    return "\n".join(out)
