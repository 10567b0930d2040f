"""Does an edit keep the source's task content? Compare each edited episode with its source.

Editing should change the fine, dynamics-level detail of a trajectory and keep its slow shape
(gait rhythm, speed profile). Per episode and state dimension, every dimension centred and scaled
by the source's mean and standard deviation, over the rFFT bins below ``cutoff`` of the Nyquist
frequency (the DC bin included):

- ``low_freq_magnitude_difference``: ``|| |F(e)| - |F(s)| || / || F(s) ||``: the spectra's shapes,
  blind to phase (any episode of the same gait scores low);
- ``low_pass_difference``: ``|| F(e) - F(s) || / || F(s) ||``: by Parseval, the relative distance
  of the low-passed signals themselves, phase included;
- ``forward_velocity_correlation``: Pearson correlation of the forward-velocity signal.

The same numbers for *mismatched* pairs (edited episode ``i`` against source episode ``i + 1``)
give the level of "any trajectory of the same kind": an edit that replaced the source with
generic target-like data would score like the mismatched pairs.

``content_shift`` sets the edit beside the *target* data instead: where the edit took the source's
mean forward velocity and return rate, against the target's.

``mean_spectra`` gives the spectra themselves, the paper's frequency analysis (appendix,
"Frequency-Domain Analysis"): the rFFT magnitude of aligned segments of source and edit, averaged.
"""

from __future__ import annotations

import numpy as np

from xted.data import Dataset
from xted.errors import InputError


def _low_freq_differences(source: np.ndarray, edited: np.ndarray, cutoff: float) -> tuple[float, float]:
    """(magnitude, low-pass) relative differences of one standardised episode ``[T, D]``, mean over dims."""
    low = np.fft.rfftfreq(len(source)) * 2.0 < cutoff
    reference = np.fft.rfft(source, axis=0)[low]
    candidate = np.fft.rfft(edited, axis=0)[low]
    norm = np.linalg.norm(reference, axis=0) + 1e-8
    magnitude = np.linalg.norm(np.abs(candidate) - np.abs(reference), axis=0) / norm
    signal = np.linalg.norm(candidate - reference, axis=0) / norm
    return float(magnitude.mean()), float(signal.mean())


def _correlation(a: np.ndarray, b: np.ndarray) -> float:
    a, b = a - a.mean(), b - b.mean()
    denominator = np.sqrt((a**2).sum() * (b**2).sum())
    return float((a * b).sum() / denominator) if denominator > 0 else float("nan")


def _standardizer(source: Dataset) -> tuple[np.ndarray, np.ndarray]:
    """Per-dimension mean and scale of the source: both datasets are measured in the source's units."""
    return source.observations.mean(axis=0), source.observations.std(axis=0) + 1e-8


def _pair_scores(source: Dataset, edited: Dataset, pairs: list[tuple[int, int]], forward_index: int | None,
                 cutoff: float) -> dict[str, float]:
    bounds = source.episode_bounds()
    mean, scale = _standardizer(source)
    differences, correlations = [], []
    for i, j in pairs:
        s = source.observations[bounds[i, 0] : bounds[i, 1]].astype(np.float64)
        e = edited.observations[bounds[j, 0] : bounds[j, 1]].astype(np.float64)
        length = min(len(s), len(e))
        s, e = s[:length], e[:length]
        differences.append(_low_freq_differences((s - mean) / scale, (e - mean) / scale, cutoff))
        if forward_index is not None:
            correlations.append(_correlation(s[:, forward_index], e[:, forward_index]))
    magnitude, signal = np.mean(differences, axis=0)
    scores = {"low_freq_magnitude_difference": float(magnitude), "low_pass_difference": float(signal)}
    if forward_index is not None:
        scores["forward_velocity_correlation"] = float(np.nanmean(correlations))
    return scores


def content_similarity(source: Dataset, edited: Dataset, forward_index: int | None = None,
                       cutoff: float = 0.2) -> dict[str, dict[str, float]]:
    """``{"matched": ..., "mismatched": ...}`` scores for an edit of ``source`` (same episodes)."""
    if not 0.0 < cutoff <= 1.0:
        raise InputError(f"cutoff must be in (0, 1], got {cutoff}")
    check_same_episodes(source, edited)
    if forward_index is not None and not 0 <= forward_index < source.observation_dim:
        raise InputError(f"forward_index {forward_index} is outside the {source.observation_dim}-d observations")
    episodes = source.num_episodes
    result = {"matched": _pair_scores(source, edited, [(i, i) for i in range(episodes)], forward_index, cutoff)}
    if episodes > 1:
        shifted = [(i, (i + 1) % episodes) for i in range(episodes)]
        result["mismatched"] = _pair_scores(source, edited, shifted, forward_index, cutoff)
    return result


def return_per_1000_steps(data: Dataset) -> float:
    """The mean over episodes of the return per step, times 1,000 (episodes of any length compare)."""
    return float((data.episode_returns() / data.episode_lengths()).mean() * 1000.0)


def content_shift(source: Dataset, edited: Dataset, target: Dataset,
                  forward_index: int | None = None) -> dict[str, dict[str, float | bool]]:
    """Where the edit took the source's task content against the target data's: per measure (the mean
    forward velocity where ``forward_index`` names its column; the return per 1,000 steps where all three
    have rewards) its ``source``, ``edited`` and ``target`` values, and ``nearer_target``: whether the
    edit's value is nearer the target's than the source's. The learner's gain from an edit followed the
    sign of the velocity shift on every halfcheetah task (BENCHMARKS.md, "The ensemble's disagreement")."""
    check_same_episodes(source, edited)
    if target.observation_dim != source.observation_dim:
        raise InputError(f"the target data has {target.observation_dim}-d observations, the source "
                         f"{source.observation_dim}-d: the shift is measured in one space")
    if forward_index is not None and not 0 <= forward_index < source.observation_dim:
        raise InputError(f"forward_index {forward_index} is outside the {source.observation_dim}-d observations")
    measures = {}
    if forward_index is not None:
        measures["forward_velocity"] = lambda data: float(data.observations[:, forward_index].mean())
    if source.has_rewards and edited.has_rewards and target.has_rewards:
        measures["return_per_1000_steps"] = return_per_1000_steps
    shift = {}
    for name, measure in measures.items():
        values = {"source": measure(source), "edited": measure(edited), "target": measure(target)}
        nearer = abs(values["edited"] - values["target"]) < abs(values["source"] - values["target"])
        shift[name] = {**values, "nearer_target": bool(nearer)}
    return shift


def shift_text(shift: dict) -> str:
    """The measures of :func:`content_shift` in one line."""
    shown = {"forward_velocity": ("forward velocity", "{:.2f}"), "return_per_1000_steps": ("return per 1,000 steps", "{:,.0f}")}
    lines = []
    for name, row in shift.items():
        label, number = shown[name]
        source, edited, target = (number.format(row[key]) for key in ("source", "edited", "target"))
        lines.append(f"{label} source {source} -> edited {edited} (target {target}: "
                     f"{'nearer' if row['nearer_target'] else 'not nearer'})")
    return "; ".join(lines) or "no measure (no forward velocity, no rewards)"


def check_same_episodes(source: Dataset, edited: Dataset) -> None:
    """InputError unless ``edited`` has ``source``'s episodes (same bounds) and observation dims."""
    if len(source) != len(edited) or not np.array_equal(source.episode_bounds(), edited.episode_bounds()):
        raise InputError(
            f"the edited dataset must have the source's episodes: {source.num_episodes} episodes / "
            f"{len(source)} transitions against {edited.num_episodes} / {len(edited)}"
        )
    if source.observation_dim != edited.observation_dim:
        raise InputError(f"observation dims differ: {source.observation_dim} and {edited.observation_dim}")


def mean_spectra(source: Dataset, edited: Dataset, segment: int = 100,
                 reference: Dataset | None = None) -> dict[str, np.ndarray | int]:
    """rFFT magnitude per state dimension of source and edit, averaged over every aligned segment.

    Each episode is cut into consecutive ``segment``-step pieces (a shorter rest is dropped), every
    dimension standardised by the source's mean and standard deviation. Returns ``frequency``
    (fraction of the Nyquist frequency, as ``cutoff``), ``source`` and ``edited`` (``[F, D]``, the
    magnitude divided by ``segment``) and ``segments``, how many were averaged. With ``reference``
    (the target data, other episodes) also ``reference``: its spectrum in the same units, to tell
    whether what the edit changed moves the source toward the target's motion.
    """
    check_same_episodes(source, edited)
    if segment < 2:
        raise InputError(f"segment must be at least 2 steps, got {segment}")
    mean, scale = _standardizer(source)
    datasets = {"source": source, "edited": edited, **({} if reference is None else {"reference": reference})}
    if reference is not None and reference.observation_dim != source.observation_dim:
        raise InputError(f"observation dims differ: {source.observation_dim} and {reference.observation_dim} "
                         "(the reference)")
    spectra = {}
    for name, data in datasets.items():
        pieces = [(data.observations[first : first + segment] - mean) / scale
                  for start, end in data.episode_bounds() for first in range(start, end - segment + 1, segment)]
        if not pieces:
            raise InputError(f"no {name} episode has {segment} steps; the longest has "
                             f"{int(data.episode_lengths().max())}")
        spectra[name] = np.abs(np.fft.rfft(np.stack(pieces).astype(np.float64), axis=1)).mean(axis=0) / segment
        if name == "source":
            spectra["segments"] = len(pieces)
    return {"frequency": np.fft.rfftfreq(segment) * 2.0, **spectra}
