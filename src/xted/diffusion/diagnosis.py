"""Before any learner: what editing a source is expected to do, and the kappa to edit it at, with no
simulator. The guarded edit (:mod:`xted.diffusion.guard`) runs on a sample of the source's episodes
at each candidate kappa; its score is the target model's mean one-step error of the result (edited
windows where kept, the source's elsewhere) over the windows inside the prior's support (beyond
it, the model extrapolates and its verdict cannot be trusted). The chosen kappa is the smallest whose
score comes within ``TOLERANCE`` of the best; where no kappa lowers the source's own score by that
much, editing is expected to keep the source as it is. Where ``UNRELIABLE_SHARE`` or more of the
source lies beyond the support, the verdict says so: only a learner (or a simulator) can tell."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from xted.data import Dataset
from xted.diffusion.config import EditConfig
from xted.diffusion.editor import edit_dataset
from xted.diffusion.guard import TargetModel
from xted.diffusion.prior import Prior
from xted.envs.termination import Termination

KAPPAS = (0.1, 0.3, 0.5, 0.7)
TOLERANCE = 0.02  # relative: scores this close to the best count as equal
UNRELIABLE_SHARE = 0.25


def diagnose_edit(prior: Prior, source: Dataset, config: EditConfig = EditConfig(), kappas: tuple[float, ...] = KAPPAS,
                  transitions: int = 2000, target_model: TargetModel | None = None,
                  termination: Termination | None = None, seed: int = 0) -> dict[str, Any]:
    """Per kappa the guard's counts and score on random source episodes of about ``transitions`` steps
    (at least one episode); the kappa chosen, why, and the verdict."""
    order = np.random.default_rng(seed).permutation(source.num_episodes)
    enough = int(np.searchsorted(np.cumsum(source.episode_lengths()[order]), transitions)) + 1
    source = source.select_episodes(np.sort(order[:enough]))
    rows = []
    for kappa in kappas:
        _, report = edit_dataset(prior, source, dataclasses.replace(config, kappa=kappa, guard=True),
                                 target_model=target_model, termination=termination)
        guard = report["guard"]
        inside = guard["guarded_error_inside_support"] is not None
        rows.append({"kappa": kappa, "score": guard["guarded_error_inside_support"] if inside else guard["guarded_error"],
                     "source_score": guard["source_error_inside_support"] if inside else guard["source_error"],
                     "edited_share": guard["edited"] / guard["windows"],
                     "outside_support_share": (guard["source_outside_support"] + guard["dropped_outside_support"])
                     / guard["windows"], "verdict": guard["verdict"], "source_error": guard["source_error"],
                     "resolution": guard["resolution"], "disagreement": guard["source_disagreement"]})
    source_score, best = rows[0]["source_score"], min(row["score"] for row in rows)
    beyond = rows[0]["outside_support_share"]
    if best >= (1 - TOLERANCE) * source_score:
        chosen, reason = None, (f"no kappa lowers the target model's error of the source ({source_score:.3f}) by "
                                f"{TOLERANCE:.0%}: editing is expected to keep the source as it is")
    else:
        chosen = next(row for row in rows if row["score"] <= (1 + TOLERANCE) * best)
        reason = (f"the smallest kappa within {TOLERANCE:.0%} of the best score ({best:.3f}; the source's "
                  f"{source_score:.3f}; resolution {rows[0]['resolution']:.3f})")
    verdict = chosen["verdict"] if chosen else reason
    if beyond >= UNRELIABLE_SHARE:
        verdict += (f"; {beyond:.0%} of the source lies beyond the prior's support, where the target model cannot "
                    "judge an edit: the guard keeps those windows as they are, and only a learner can tell the rest")
    return {"episodes": source.num_episodes, "transitions": len(source), "kappas": rows,
            "kappa": None if chosen is None else chosen["kappa"], "reason": reason, "verdict": verdict}
