"""IGDF's and OTDF's source scores checked by the simulator before any learner.

    python benchmarks/filter_quality.py --env halfcheetah [--gaps thigh gravity friction] [--target medium-replay]
        [--out benchmarks/results/filter_quality.jsonl]

Per source: each method scores every source transition as the bench's columns do (the trainer's
standardisation of target + source, seed 0, the column's settings for the env); every source
transition's true mismatch is its one-step error against the target simulator (MAE of the recorded
next state against the oracle's, which replays the source's (s, a) in the target). Reported: the
mean mismatch of the transitions a method ranks in its keep share and of the rest (the filter works
where the kept ones err less), the rank correlation of score and -mismatch, and each method's
scoring time. The bench filters per batch; this ranks the whole source at once, the same order.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import jax
import numpy as np

from xted.data import load
from xted.fields import apply_overrides
from xted.pipelines.bench.cells import oracle
from xted.pipelines.bench.columns import COLUMNS, TGT_SRC_IGDF, TGT_SRC_OTDF
from xted.rl import igdf, otdf
from xted.rl.config import IGDFConfig, OTDFConfig
from xted.rl.dara import CLASSIFIER_INPUTS
from xted.rl.offline_train import prepare_data


def ranks(x: np.ndarray) -> np.ndarray:
    out = np.empty(len(x))
    out[np.argsort(x, kind="stable")] = np.arange(len(x))
    return out


def split_by_score(scores: np.ndarray, mismatch: np.ndarray, keep_fraction: float) -> dict:
    kept = ranks(-scores) < keep_fraction * len(scores)
    return {"keep_fraction": keep_fraction, "kept_mismatch": float(mismatch[kept].mean()),
            "dropped_mismatch": float(mismatch[~kept].mean()),
            "rank_correlation": float(np.corrcoef(ranks(scores), ranks(-mismatch))[0, 1])}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--env", required=True, choices=["halfcheetah", "walker2d"])
    parser.add_argument("--gaps", nargs="+", default=["thigh", "gravity", "friction"])
    parser.add_argument("--target", default="medium-replay")
    parser.add_argument("--out", type=Path, default=None, help="Append one JSON line per source.")
    args = parser.parse_args()

    target = load(f"{args.env}-{args.target}")
    configs = {name: apply_overrides(kind(), COLUMNS[column].settings_for(args.env))
               for name, kind, column in (("igdf", IGDFConfig, TGT_SRC_IGDF), ("otdf", OTDFConfig, TGT_SRC_OTDF))}
    print(f"| {args.env} gap | source mismatch | IGDF kept / dropped (rank corr.) | OTDF kept / dropped (rank corr.) "
          "| seconds IGDF / OTDF |")
    print("|---|---|---|---|---|")
    for gap in args.gaps:
        source = load(f"{args.env}-{gap}")
        mismatch = np.abs(source.require_next_observations() - oracle(args.env, gap, source).next_observations).mean(1)
        data = prepare_data(target, [source])
        n = data.target_size
        target_rows = {k: data.arrays[k][:n] for k in CLASSIFIER_INPUTS}
        source_rows = {k: data.arrays[k][n:] for k in CLASSIFIER_INPUTS}
        row = {"env": args.env, "target": args.target, "gap": gap, "source_mismatch": float(mismatch.mean()),
               "source_sha256": source.fingerprint()}
        started = time.perf_counter()
        scores, _ = igdf.source_scores(jax.random.PRNGKey(0)[None], target_rows, source_rows, configs["igdf"])
        row["igdf"] = {**split_by_score(scores[0], mismatch, configs["igdf"].keep_fraction),
                       "seconds": time.perf_counter() - started}
        started = time.perf_counter()
        deviations = otdf.source_deviations(target_rows, source_rows, configs["otdf"])
        row["otdf"] = {**split_by_score(-deviations, mismatch, configs["otdf"].keep_fraction),
                       "seconds": time.perf_counter() - started}
        cells = [f"{row[m]['kept_mismatch']:.3f} / {row[m]['dropped_mismatch']:.3f} ({row[m]['rank_correlation']:+.2f})"
                 for m in ("igdf", "otdf")]
        print(f"| {gap} | {row['source_mismatch']:.3f} | {cells[0]} | {cells[1]} | "
              f"{row['igdf']['seconds']:.0f} / {row['otdf']['seconds']:.0f} |", flush=True)
        if args.out is not None:
            with args.out.open("a") as out:
                out.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()
