"""The report's statistics against values worked out by hand."""

from __future__ import annotations

import numpy as np
import pytest

from xted.analysis.stats import (improvement_interval, interquartile_mean, iqm_interval, probability_of_improvement,
                                 t_interval)
from xted.errors import InputError


def test_t_interval():
    low, high = t_interval([1, 2, 3, 4, 5])  # mean 3, s = 1.5811, t(0.975, 4) = 2.7764
    assert (low, high) == pytest.approx((3 - 1.9632, 3 + 1.9632), abs=1e-4)
    assert t_interval([7.0]) is None and t_interval([]) is None
    wider = t_interval([1, 2, 3, 4, 5], confidence=0.99)
    assert wider[0] < low and wider[1] > high


def test_interquartile_mean_drops_a_quarter_each_side():
    assert interquartile_mean([1, 2, 3, 4, 5, 6, 7, 8]) == 4.5  # mean of 3, 4, 5, 6
    assert interquartile_mean([0, 0, 0, 100]) == 0.0  # an outlier seed does not move it
    assert interquartile_mean([10, 20]) == 15.0


def test_probability_of_improvement_counts_pairs_and_half_ties():
    assert probability_of_improvement([2, 3], [1, 2]) == 0.875  # 1 + 0.5 + 1 + 1 of 4 pairs
    assert probability_of_improvement([1, 1], [1, 1]) == 0.5
    assert probability_of_improvement([0], [5, 6]) == 0.0


def test_bootstrap_intervals_hold_their_value_and_repeat_by_seed():
    rng = np.random.default_rng(0)
    tasks = [rng.normal(loc, 2.0, 5) for loc in (10, 20, 30)]
    iqm = iqm_interval(tasks)
    assert iqm["ci95"][0] <= iqm["value"] <= iqm["ci95"][1] and iqm["tasks"] == 3
    assert iqm_interval(tasks) == iqm and iqm_interval(tasks, seed=1) != iqm
    better = [task + 5 for task in tasks]
    up = improvement_interval(better, tasks)
    assert 0.5 < up["ci95"][0] <= up["value"] <= up["ci95"][1] <= 1.0
    down = improvement_interval(tasks, better)
    assert down["value"] == pytest.approx(1 - up["value"])
    with pytest.raises(InputError, match="3 tasks of X against 2"):
        improvement_interval(tasks, tasks[:2])
    with pytest.raises(InputError, match="at least one score"):
        iqm_interval([[1.0], []])
