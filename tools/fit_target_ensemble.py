"""Give a prior folder the guard's ensemble (``target_ensemble.msgpack``) where it holds only the target model.

    python tools/fit_target_ensemble.py --prior src/xted/assets/priors/halfcheetah-medium-replay-cpu \
        --target halfcheetah-medium-replay --heldout-episodes 2 [--seed 0]

A prior trained now fits the ensemble when its training ends; one trained before holds the target
model alone. This refits the model on the prior's training episodes (the target less
``--heldout-episodes``, as ``xted train`` split it) with its seed and, where that refit predicts what
the folder's model predicts (same data, same seed), writes the members beside it. The target model's
own file is left as it is (the bench's keys of guarded edits name its bytes).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from xted.data import load, split_heldout
from xted.diffusion.guard import ENSEMBLE_MEMBERS, TargetModel, fit_target_model
from xted.errors import InputError

AGREEMENT = 1e-3  # largest mean |difference| of the refit's predictions from the folder's model, in raw units


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--prior", type=Path, required=True)
    parser.add_argument("--target", required=True, help="The target data the prior was trained on.")
    parser.add_argument("--heldout-episodes", type=int, default=2)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    shipped = TargetModel.load(args.prior)
    if shipped is None:
        raise InputError(f"{args.prior}: holds no target model to add an ensemble to")
    train, _ = split_heldout(load(args.target), args.heldout_episodes)
    refit = fit_target_model(train, seed=args.seed, progress=True, members=ENSEMBLE_MEMBERS)
    difference = float(np.abs(refit.predict(train.observations, train.actions)
                              - shipped.predict(train.observations, train.actions)).mean())
    if difference > AGREEMENT:
        raise InputError(f"{args.prior}: the refit model predicts {difference:.2e} apart from the folder's (more than "
                         f"{AGREEMENT}): other data, heldout episodes or seed than the prior's")
    refit.save_members(args.prior)
    print(f"{args.prior}: {len(refit.members)} ensemble members written (refit within {difference:.1e} of its model)")


if __name__ == "__main__":
    main()
