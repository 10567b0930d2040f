"""Which per-source rule for "edit or keep" the learner follows, over every task edit_learner.py has measured.

    python benchmarks/edit_rules.py [benchmarks/results/edit_learner.jsonl]

For each task (env, target, gap) with both the unedited source (Tgt+Src) and the plain edit (Tgt+Edited) scored,
a rule picks one of the two from what is known before any learner runs, and scores the learner's cell of its pick:
the simulator (edit where the edit lowers the one-step error in the target's simulator), the speed and the return
(edit where the edit moves the mean forward velocity, or the return per 1,000 steps, nearer the target data's), the
distance (edit where the edit brings the state-action pairs nearer the target's). Printed: each task's learner
scores and picks, then per rule the total, its gain over the unedited source and on how many tasks it picks the
one the learner scored higher. The best of the two per task is the bound any such rule has.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from xted.analysis.content import return_per_1000_steps
from xted.data import load
from xted.envs import parse_domain
from xted.envs.make import forward_velocity_index

SOURCE, EDIT = "Tgt+Src", "Tgt+Edited"


def scored_tasks(rows: list[dict]) -> dict[tuple[str, str, str], dict[str, dict]]:
    """(env, target, gap) -> {SOURCE: row, EDIT: row} where both are scored; a later row replaces an earlier one."""
    latest = {(row["env"], row["target"], row["gap"], row["variant"]): row for row in rows}
    tasks: dict[tuple[str, str, str], dict[str, dict]] = {}
    for (env, target, gap, variant), row in latest.items():
        if variant in (SOURCE, EDIT) and row["score"] is not None:
            tasks.setdefault((env, target, gap), {})[variant] = row
    return {task: pair for task, pair in sorted(tasks.items()) if len(pair) == 2}


def target_content(env: str, target: str) -> dict[str, float]:
    data = load(f"{env}-{target}")
    return {"forward_velocity": float(data.observations[:, forward_velocity_index(parse_domain(env))].mean()),
            "return_per_1000_steps": return_per_1000_steps(data)}


def nearer(measure: str):
    return lambda source, edit, target: abs(edit[measure] - target[measure]) < abs(source[measure] - target[measure])


RULES = {
    "simulator": lambda source, edit, target: edit["simulator_mae"] < source["simulator_mae"],
    "speed": nearer("forward_velocity"),
    "return": nearer("return_per_1000_steps"),
    "distance": lambda source, edit, target: edit["target_distance"] < source["target_distance"],
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("rows", nargs="?", type=Path, default=Path("benchmarks/results/edit_learner.jsonl"))
    args = parser.parse_args()
    if not args.rows.is_file():
        parser.error(f"{args.rows}: no such file (python benchmarks/edit_learner.py --out writes it)")
    tasks = scored_tasks([json.loads(line) for line in args.rows.read_text().splitlines() if line.strip()])
    if not tasks:
        parser.error(f"{args.rows}: no task with both {SOURCE} and {EDIT} scored")
    targets = {(env, target): target_content(env, target) for env, target, _ in tasks}

    print(f"| task | {SOURCE} | {EDIT} | " + " | ".join(f"{rule} edits?" for rule in RULES) + " |")
    print("|---|---|---|" + "---|" * len(RULES))
    totals = {rule: 0.0 for rule in ["source", "plain edit", *RULES, "best of the two"]}
    agree = dict.fromkeys(RULES, 0)
    for (env, target, gap), pair in tasks.items():
        source, edit = pair[SOURCE], pair[EDIT]
        picks = {rule: decide(source, edit, targets[env, target]) for rule, decide in RULES.items()}
        edit_better = edit["score"] > source["score"]
        for rule, picked_edit in picks.items():
            totals[rule] += edit["score"] if picked_edit else source["score"]
            agree[rule] += picked_edit == edit_better
        totals["source"] += source["score"]
        totals["plain edit"] += edit["score"]
        totals["best of the two"] += max(source["score"], edit["score"])
        print(f"| {env} {target} {gap} | {source['score']:.1f} | {edit['score']:.1f} | "
              + " | ".join("yes" if picks[rule] else "no" for rule in RULES) + " |")

    print(f"\nover {len(tasks)} tasks (learner's cells as stored)")
    print("| rule | total | against the unedited source | picks the learner's better cell |")
    print("|---|---|---|---|")
    for rule, total in totals.items():
        better = f"{agree[rule]} of {len(tasks)}" if rule in agree else ""
        print(f"| {rule} | {total:.1f} | {(total / totals['source'] - 1):+.1%} | {better} |")


if __name__ == "__main__":
    main()
