"""A short prior run edits with its EMA weights (warmed up: decay min(0.999, (1 + t) / (10 + t))) as
well as with its live weights: both edits of one source, replayed in the target simulator
(BENCHMARKS.md, "Your own data: a short run's EMA").

    xted train --target T --out P --steps 400
    python benchmarks/ema_warmup.py --prior P --source S --env hopper
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
from pathlib import Path

import jax
import orbax.checkpoint as ocp

from xted.analysis import simulator_measures
from xted.data import load
from xted.diffusion.checkpoint import checkpoint_manager
from xted.diffusion.config import EditConfig
from xted.diffusion.editor import edit_dataset
from xted.diffusion.objective import init_train_state
from xted.diffusion.prior import load_prior
from xted.envs import parse_domain


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--prior", required=True, help="a prior's training folder (its checkpoint holds both weights)")
    parser.add_argument("--source", required=True)
    parser.add_argument("--env", required=True, help="the target env whose simulator replays the edits")
    parser.add_argument("--kappa", type=float, default=0.5)
    args = parser.parse_args()

    prior = load_prior(args.prior)
    manager = checkpoint_manager(Path(args.prior))
    abstract = jax.eval_shape(functools.partial(init_train_state, prior.config), jax.random.key(0))
    restored = manager.restore(manager.latest_step(), args=ocp.args.Composite(
        state=ocp.args.StandardRestore(abstract), sampler=ocp.args.JsonRestore()))
    source, domain = load(args.source), parse_domain(args.env)
    errors = {}
    for name, params in (("EMA", restored.state.ema_params), ("live", restored.state.params)):
        edited, _ = edit_dataset(dataclasses.replace(prior, params=params), source,
                                 EditConfig(kappa=args.kappa, guard=False, seed=0))
        errors[name] = simulator_measures(domain, edited)["mae"]
    source_error = simulator_measures(domain, source)["mae"]
    print(f"step {prior.step}: one-step MAE in {domain.name}: source {source_error:.4f}, edit with the EMA "
          f"{errors['EMA']:.4f}, with the live weights {errors['live']:.4f} (ratio {errors['EMA'] / errors['live']:.2f})")


if __name__ == "__main__":
    main()
