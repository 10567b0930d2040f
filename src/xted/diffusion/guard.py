"""The guarded edit (beyond the paper; docs/editing.md, "The guard"): an edited window is kept only
where it is a valid transition of the target and measurably more consistent with the target than
the source's window was; everywhere else the source's window stays as it was.

- The **target model** travels with the prior (``target_model.msgpack``, written when training
  ends): an MLP dynamics model ``(s, a) -> s'`` fitted to the prior's target data, its
  *resolution* (mean one-step error on target episodes it did not see) and the ranges of the
  target's actions and observations.
- **Support**: a source window holding a state more than ``support_z`` target standard deviations
  from the target's mean lies beyond what the prior learned (kept as it is, dropped, or edited
  anyway: ``outside_support``).
- **Gain**: the edit must lower the model's one-step error, averaged over the window, by more than
  ``guard_margin`` x the model's resolution; a smaller change is below what the model can tell apart.
  Opt-in (``guard_disagreement`` w > 0): by w x the window's *disagreement* too, the mean absolute
  spread of an ensemble's predictions (the model and ``ENSEMBLE_MEMBERS`` more fitted to the same
  episodes, seeds after its own; ``target_ensemble.msgpack``). Where the source leaves the target's
  data, the model's error measures that distance as much as dynamics, and the members disagree there.
- **Validity**: every edited transition's terminal flag agrees with the target's termination rule
  (:mod:`xted.envs.termination`, or the caller's), and edited actions are clipped into the action space.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import flax.serialization
import numpy as np

from xted.atomic import atomic_path
from xted.data import Dataset, split_heldout
from xted.errors import InputError
from xted.nn import FittedMLP, fit_mlp

TARGET_MODEL_FILE = "target_model.msgpack"
ENSEMBLE_FILE = "target_ensemble.msgpack"  # the extra members, apart so that the model's own file (and keys) stay
ENSEMBLE_MEMBERS = 3
HELDOUT_SHARE = 0.1  # of the target's episodes, left out of the dynamics model to measure its resolution
FIT_EPOCHS, MIN_FIT_STEPS, MAX_FIT_STEPS = 250, 200, 20_000


@dataclass(frozen=True)
class _FitSettings:
    steps: int
    seed: int
    hidden: tuple[int, ...] = (256, 256, 256)
    batch_size: int = 256
    learning_rate: float = 1e-3


@dataclass(frozen=True)
class TargetModel:
    """What the guard knows of the target beyond the diffusion prior (module docstring)."""

    dynamics: FittedMLP  # (s, a) -> s' - s
    resolution: float
    action_low: np.ndarray
    action_high: np.ndarray
    observation_low: np.ndarray
    observation_high: np.ndarray
    members: tuple[FittedMLP, ...] = ()  # the ensemble's other members (guard_disagreement); none: the model alone

    def predict(self, observations: np.ndarray, actions: np.ndarray) -> np.ndarray:
        """Next observations, raw units."""
        observations = np.asarray(observations, np.float64)
        return observations + self.dynamics(np.concatenate([observations, actions], axis=1))

    def errors(self, observations: np.ndarray, actions: np.ndarray, next_observations: np.ndarray) -> np.ndarray:
        """Per-transition mean absolute one-step error ``[N]``."""
        return np.abs(self.predict(observations, actions) - next_observations).mean(axis=1)

    def disagreement(self, observations: np.ndarray, actions: np.ndarray) -> np.ndarray:
        """Per transition ``[N]``: the mean absolute deviation of the ensemble's predictions (the model's
        and its members') from their mean."""
        if not self.members:
            raise InputError("the guard's disagreement needs the target model's ensemble, which this prior does "
                             f"not hold ({ENSEMBLE_FILE}): give the target data (--target, "
                             "Prior.edit(target=...)) to fit it, or set guard_disagreement=0")
        inputs = np.concatenate([observations, actions], axis=1)
        deltas = np.stack([member(inputs) for member in (self.dynamics, *self.members)])
        return np.abs(deltas - deltas.mean(axis=0)).mean(axis=(0, 2))

    def outside_range(self, observations: np.ndarray) -> np.ndarray:
        """``[N]`` True where an observation leaves the range the target data spans."""
        return np.any((observations < self.observation_low) | (observations > self.observation_high), axis=1)

    def save(self, folder: str | Path) -> Path:
        path = Path(folder) / TARGET_MODEL_FILE
        ranges = {name: getattr(self, name).tolist() for name in
                  ("action_low", "action_high", "observation_low", "observation_high")}
        payload = {"dynamics": self.dynamics.to_bytes(), "resolution": self.resolution, **ranges}
        with atomic_path(path) as tmp:
            tmp.write_bytes(flax.serialization.msgpack_serialize(payload))
        if self.members:
            self.save_members(folder)
        return path

    def save_members(self, folder: str | Path) -> Path:
        """Write the ensemble's other members alone (beside a target model already saved)."""
        path = Path(folder) / ENSEMBLE_FILE
        with atomic_path(path) as tmp:
            tmp.write_bytes(flax.serialization.msgpack_serialize({"members": [m.to_bytes() for m in self.members]}))
        return path

    @classmethod
    def load(cls, folder: str | Path) -> TargetModel | None:
        """The folder's target model, or None where it holds none (a prior trained before it existed,
        or one whose training did not finish)."""
        path, ensemble = Path(folder) / TARGET_MODEL_FILE, Path(folder) / ENSEMBLE_FILE
        if not path.is_file():
            return None
        try:
            data = flax.serialization.msgpack_restore(path.read_bytes())
            ranges = {k: np.asarray(data[k], np.float32) for k in
                      ("action_low", "action_high", "observation_low", "observation_high")}
            model = cls(FittedMLP.from_bytes(data["dynamics"], str(path)), float(data["resolution"]), **ranges)
        except (ValueError, KeyError, TypeError) as err:
            raise InputError(f"{path}: unreadable target model ({err})") from None
        if not ensemble.is_file():
            return model
        try:
            members = flax.serialization.msgpack_restore(ensemble.read_bytes())["members"]
            return dataclasses.replace(model, members=tuple(FittedMLP.from_bytes(m, str(ensemble)) for m in members))
        except (ValueError, KeyError, TypeError) as err:
            raise InputError(f"{ensemble}: unreadable target model ensemble ({err})") from None


def fit_target_model(target: Dataset, seed: int = 0, progress: bool = False, members: int = 0) -> TargetModel:
    """Fit the dynamics model to ``target`` less a tenth of its episodes, on which its resolution is
    measured (with a single episode, on its own training data); ``FIT_EPOCHS`` passes, within bounds.
    ``members``: as many more, seeds ``seed + 1``..., fitted to the same episodes (the ensemble)."""
    heldout_episodes = int(round(HELDOUT_SHARE * target.num_episodes))
    train, heldout = split_heldout(target, heldout_episodes, seed=seed) if heldout_episodes else (target, None)
    observations, actions, next_observations = _transitions(train)
    steps = int(np.clip(FIT_EPOCHS * len(observations) / 256, MIN_FIT_STEPS, MAX_FIT_STEPS))
    inputs = np.concatenate([observations, actions], axis=1)
    dynamics, *others = [fit_mlp(inputs, next_observations - observations, _FitSettings(steps=steps, seed=seed + i),
                                 progress, desc="target model" if i == 0 else f"ensemble member {i}")
                         for i in range(1 + members)]
    model = TargetModel(dynamics, 0.0, target.actions.min(0), target.actions.max(0),
                        target.observations.min(0), target.observations.max(0), tuple(others))
    resolution = model.errors(*_transitions(heldout or train)).mean()
    return dataclasses.replace(model, resolution=float(resolution))


def fit_for_edit(target: Dataset, guard_disagreement: float, seed: int = 0, progress: bool = False) -> TargetModel:
    """The target model an edit needs: with its ensemble where the edit's guard asks for its disagreement."""
    return fit_target_model(target, seed, progress, members=ENSEMBLE_MEMBERS if guard_disagreement > 0 else 0)


def _transitions(data: Dataset) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(s, a, s')`` of every transition whose next state is known: all where the data stores next
    observations, else every step but each episode's last."""
    if data.next_observations is not None:
        return data.observations, data.actions, data.next_observations
    inside = ~(data.terminals | data.timeouts)
    rows = np.flatnonzero(inside)
    return data.observations[rows], data.actions[rows], data.observations[rows + 1]


def window_means(values: np.ndarray, windows: np.ndarray, n_windows: int) -> np.ndarray:
    """Mean of per-transition ``values`` over each window's transitions (``windows[i]``: transition i's)."""
    return np.bincount(windows, values, n_windows) / np.maximum(np.bincount(windows, minlength=n_windows), 1)


def required_gain(resolution: float, margin: float, disagreement_weight: float = 0.0,
                  disagreement: np.ndarray | None = None) -> float | np.ndarray:
    """The drop in the target model's error an edited window must show: ``margin`` x the model's
    resolution, plus ``disagreement_weight`` x the window's ensemble disagreement where that is on."""
    if disagreement_weight == 0.0:
        return margin * resolution
    return margin * resolution + disagreement_weight * disagreement


@dataclass(frozen=True)
class GuardVerdict:
    """Per window: ``edit`` (the edited window is kept), ``drop`` (its transitions are left out)."""

    edit: np.ndarray
    drop: np.ndarray
    counts: dict[str, int]


def judge_windows(source_error: np.ndarray, edited_error: np.ndarray, outside_support: np.ndarray,
                  invalid: np.ndarray, needed: float | np.ndarray, outside_action: str) -> GuardVerdict:
    """Which edited windows to keep: inside the support (or ``outside_action == "edit"``), valid,
    and with an error lowered by more than ``needed`` (:func:`required_gain`; one for all or
    one per window); outside the support and ``outside_action == "drop"``: dropped. Counts say why
    each window ended as it did."""
    considered = ~outside_support | (outside_action == "edit")
    gain = source_error - edited_error > needed
    edit = considered & ~invalid & gain
    drop = outside_support & (outside_action == "drop")
    counts = {"windows": int(len(edit)), "edited": int(edit.sum()),
              "source_outside_support": int((outside_support & ~drop & ~considered).sum()),
              "dropped_outside_support": int(drop.sum()),
              "source_invalid_edit": int((considered & invalid).sum()),
              "source_no_gain": int((considered & ~invalid & ~gain).sum())}
    return GuardVerdict(edit, drop, counts)


def verdict_line(counts: dict[str, int], source_error: float, resolution: float) -> str:
    """One line for a user: what the guard did and whether editing this source is expected to help."""
    windows = max(counts["windows"], 1)
    share = counts["edited"] / windows
    outside = (counts["source_outside_support"] + counts["dropped_outside_support"]) / windows
    expect = ("help" if share >= 0.5 else "keep the source mostly as it is" if share < 0.1
              else "help on part of the source")
    return (f"guard: {counts['edited']} of {counts['windows']} windows edited ({share:.0%}); {outside:.0%} beyond the "
            f"prior's support, {counts['source_invalid_edit']} edits invalid, {counts['source_no_gain']} without a "
            f"gain; the source's one-step mismatch {source_error:.3f} against the target model's resolution "
            f"{resolution:.3f} ({source_error / max(resolution, 1e-12):.1f}x): editing is expected to {expect}")
