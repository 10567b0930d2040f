"""Is every transition of a dataset one the target could produce, as far as that can be told without
a simulator: terminal flags against the target env's termination rule, actions against its action
space, states against the range the target data spans."""

from __future__ import annotations

import numpy as np

from xted.data import Dataset
from xted.envs.make import action_bounds
from xted.envs.termination import Termination
from xted.envs.termination import termination as termination_rule


def transition_validity(data: Dataset, env: str | None = None, target: Dataset | None = None,
                        termination: Termination | None = None) -> dict:
    """Counts of transitions that break what is known of the target: ``env`` gives its termination
    rule and action space (or ``termination`` a rule of your own); ``target`` the observed ranges.
    A count is None where nothing tells it."""
    rule = termination or termination_rule(env)
    next_observations = data.require_next_observations()
    bounds = action_bounds(env)
    if bounds is None and target is not None:
        bounds = (target.actions.min(0), target.actions.max(0))
    report: dict = {"transitions": len(data), "unflagged_terminal": None, "flagged_but_healthy": None,
                    "actions_outside": None, "states_outside_target_range": None}
    if rule is not None:
        ends = rule(next_observations)
        report["unflagged_terminal"] = int((ends & ~data.terminals).sum())
        report["flagged_but_healthy"] = int((~ends & data.terminals).sum())
    if bounds is not None:
        report["actions_outside"] = int(np.any((data.actions < bounds[0]) | (data.actions > bounds[1]), axis=1).sum())
    if target is not None:
        low, high = target.observations.min(0), target.observations.max(0)
        report["states_outside_target_range"] = int(np.any((next_observations < low) | (next_observations > high),
                                                           axis=1).sum())
    return report
