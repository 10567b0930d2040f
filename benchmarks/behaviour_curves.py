"""Learning curves of online runs (``xted online train``): a PNG and a markdown table.

    python benchmarks/behaviour_curves.py RUN... --out docs/behaviour_curves.png [--at 100000]

RUN is a run folder or a copy of its ``evals.csv`` (``benchmarks/results/behaviour/NAME.csv``).

The PNG has greedy evaluation return against env steps and against the run's wall minutes, one
line per run (named by its folder). The table gives each run's steps, wall and CPU minutes, the
learning rate in env steps/s, its best evaluation and its return at step ``--at`` with the CPU
minutes spent to get there.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from xted.atomic import atomic_path  # noqa: E402
from xted.rl.run_folder import read_evals  # noqa: E402


def table_row(name: str, evals: list[dict], at: int) -> str:
    last, best = evals[-1], max(evals, key=lambda row: row["return_mean"])
    upto = [row for row in evals if row["step"] <= at]
    at_row = upto[-1] if upto else None
    at_text = (f"{at_row['return_mean']:.0f} ({at_row['cpu_seconds'] / 60:.1f} CPU min)" if at_row else "-")
    return (f"| {name} | {last['step'] / 1e3:.0f}k | {last['wall_seconds'] / 60:.1f} | {last['cpu_seconds'] / 60:.1f} "
            f"| {last['step'] / last['wall_seconds']:.0f} | {best['return_mean']:.0f} ({best['step'] / 1e3:.0f}k) "
            f"| {at_text} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("runs", nargs="+", type=Path)
    parser.add_argument("--out", type=Path, required=True, help="PNG file")
    parser.add_argument("--at", type=int, default=100_000, help="step to compare runs at")
    parser.add_argument("--title", default="Behaviour policies: greedy evaluation (10 episodes)")
    args = parser.parse_args()
    curves = {run.stem: read_evals(run) for run in args.runs}
    empty = [name for name, evals in curves.items() if not evals]
    if empty:
        parser.error(f"no evals.csv rows in {', '.join(empty)}")
    fig, (by_step, by_time) = plt.subplots(1, 2, figsize=(12, 4.5), sharey=True)
    for name, evals in curves.items():
        returns = [row["return_mean"] for row in evals]
        by_step.plot([row["step"] / 1e3 for row in evals], returns, label=name)
        by_time.plot([row["wall_seconds"] / 60 for row in evals], returns, label=name)
    by_step.set_xlabel("environment steps (thousands)")
    by_time.set_xlabel("wall time of the run (minutes)")
    by_step.set_ylabel("return (greedy, mean of 10 episodes)")
    for axis in (by_step, by_time):
        axis.grid(alpha=0.3)
    by_time.legend(fontsize=8, loc="best")
    fig.suptitle(args.title)
    fig.tight_layout()
    with atomic_path(args.out, suffix=".png") as tmp:
        fig.savefig(tmp, dpi=110)
    print("| run | env steps | wall (min) | CPU (min) | env steps/s | best return (step) "
          f"| return at {args.at / 1e3:.0f}k (CPU min) |")
    print("|---|---|---|---|---|---|---|")
    for name, evals in curves.items():
        print(table_row(name, evals, args.at))


if __name__ == "__main__":
    main()
