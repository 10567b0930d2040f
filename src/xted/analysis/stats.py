"""Statistics of scores over seeds and tasks that a reader can trust, after Agarwal et al. (2021),
"Deep RL at the Edge of the Statistical Precipice" (rliable): a t-interval per cell; over tasks,
the interquartile mean and the probability of improvement, each with a stratified-bootstrap
interval (seeds resampled within every task).

NumPy and SciPy (already JAX's dependency): rliable itself brings arch, pandas and seaborn for
these few functions.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy import stats

from xted.errors import InputError

CONFIDENCE = 0.95
RESAMPLES = 2000


def t_interval(scores: Sequence[float], confidence: float = CONFIDENCE) -> tuple[float, float] | None:
    """Student-t interval of the mean over seeds (ddof 1); None for fewer than two scores."""
    values = np.asarray(scores, np.float64)
    if len(values) < 2:
        return None
    half = stats.t.ppf(0.5 + confidence / 2, len(values) - 1) * values.std(ddof=1) / np.sqrt(len(values))
    return float(values.mean() - half), float(values.mean() + half)


def interquartile_mean(values: Sequence[float]) -> float:
    """Mean of ``values`` without their lowest and highest quarter (``int(n / 4)`` values each):
    rliable's IQM, ``scipy.stats.trim_mean(values, 0.25)``."""
    return float(stats.trim_mean(np.asarray(values, np.float64), 0.25))


def probability_of_improvement(x: Sequence[float], y: Sequence[float]) -> float:
    """P(X > Y) for one task: the share of (x, y) seed pairs with x > y, ties counting half
    (the Mann-Whitney U statistic over n * m)."""
    x, y = np.asarray(x, np.float64)[:, None], np.asarray(y, np.float64)[None, :]
    return float(np.mean((x > y) + 0.5 * (x == y)))


def _check_tasks(tasks: Sequence[Sequence[float]], what: str) -> list[np.ndarray]:
    arrays = [np.asarray(task, np.float64) for task in tasks]
    if not arrays or any(len(task) == 0 for task in arrays):
        raise InputError(f"{what}: every task needs at least one score")
    return arrays


def _percentile_interval(samples: np.ndarray, confidence: float) -> tuple[float, float]:
    tail = 100 * (1 - confidence) / 2
    return float(np.percentile(samples, tail)), float(np.percentile(samples, 100 - tail))


def iqm_interval(tasks: Sequence[Sequence[float]], confidence: float = CONFIDENCE, resamples: int = RESAMPLES,
                 seed: int = 0) -> dict:
    """IQM over all scores of all tasks and its stratified-bootstrap interval."""
    arrays = _check_tasks(tasks, "IQM")
    rng = np.random.default_rng(seed)
    boot = np.array([interquartile_mean(np.concatenate([rng.choice(task, len(task)) for task in arrays]))
                     for _ in range(resamples)])
    return {"value": interquartile_mean(np.concatenate(arrays)), "ci95": _percentile_interval(boot, confidence),
            "tasks": len(arrays)}


def improvement_interval(x_tasks: Sequence[Sequence[float]], y_tasks: Sequence[Sequence[float]],
                         confidence: float = CONFIDENCE, resamples: int = RESAMPLES, seed: int = 0) -> dict:
    """The mean over tasks of P(X > Y), with a stratified-bootstrap interval (the seeds of X and of
    Y resampled independently within each task)."""
    xs, ys = _check_tasks(x_tasks, "P(improvement)"), _check_tasks(y_tasks, "P(improvement)")
    if len(xs) != len(ys):
        raise InputError(f"P(improvement): {len(xs)} tasks of X against {len(ys)} of Y")
    rng = np.random.default_rng(seed)

    def mean_over_tasks(pairs) -> float:
        return float(np.mean([probability_of_improvement(x, y) for x, y in pairs]))

    boot = np.array([mean_over_tasks((rng.choice(x, len(x)), rng.choice(y, len(y))) for x, y in zip(xs, ys))
                     for _ in range(resamples)])
    return {"value": mean_over_tasks(zip(xs, ys)), "ci95": _percentile_interval(boot, confidence), "tasks": len(xs)}
