"""Wall time of editing a whole dataset, compilation apart: the default chain against few-step samplers.

    python benchmarks/edit_speed.py [--prior src/xted/assets/priors/halfcheetah-medium-replay-cpu]
        [--source halfcheetah-thigh] [--repeats 3] [--config NAME=FIELD=VALUE,FIELD=VALUE ...]

Each config edits the source once to compile (and warm up), then ``--repeats`` times; the median is
reported with transitions per second and its ratio to the first config. Configs are EditConfig
overrides on the defaults, e.g. ``ddim10=sampler=ddim,sampler_steps=10,eta=1``.
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics

from xted.fields import apply_overrides
from xted.data import load
from xted.diffusion.editor import EditConfig, edit_dataset
from xted.diffusion.prior import load_prior

DEFAULT_CONFIGS = ["default=", "ddim10=sampler=ddim,sampler_steps=10,eta=1", "ddim5=sampler=ddim,sampler_steps=5,eta=1"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--prior", default="src/xted/assets/priors/halfcheetah-medium-replay-cpu")
    parser.add_argument("--source", default="halfcheetah-thigh")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--config", nargs="+", default=DEFAULT_CONFIGS)
    args = parser.parse_args()

    prior, source = load_prior(args.prior), load(args.source)
    print(f"| config | overrides | median s ({args.repeats} runs, compile apart) | transitions/s | vs first |")
    print("|---|---|---|---|---|")
    first = None
    for spec in args.config:
        name, _, overrides = spec.partition("=")
        config = apply_overrides(EditConfig(), [pair for pair in overrides.split(",") if pair])
        edit_dataset(prior, source, config)  # compile
        seconds = statistics.median(
            edit_dataset(prior, source, dataclasses.replace(config, seed=r))[1]["seconds"] for r in range(args.repeats)
        )
        first = first or seconds
        print(f"| {name} | {overrides or '-'} | {seconds:.2f} | {len(source) / seconds:,.0f} | {seconds / first:.2f} |",
              flush=True)


if __name__ == "__main__":
    main()
