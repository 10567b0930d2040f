"""D4RL-style datasets made with our own behaviour policies (`xted data make`).

Levels, as D4RL made them: ``random`` (uniform actions), ``medium`` (a policy at about half the
best return its run reached; D4RL's halfcheetah medium is at 39% of its expert), ``medium-replay``
(the replay buffer of that run up to the medium checkpoint), ``expert`` (the best checkpoint), ``medium-expert`` (medium and
expert episodes, half each), and ``source`` (the best SAC policy trained in a gap domain,
collected in that domain). Policies come from a online run folder (``xted online train``) or from the
checkpoints shipped with xted.
"""

from __future__ import annotations

import dataclasses
import datetime
import shlex
import sys
from pathlib import Path

import numpy as np

import xted
from xted.data.dataset import Dataset
from xted.data.shipped import policies_dir
from xted.envs import Domain, normalized_score
from xted.errors import InputError
from xted.rl.collect import collect, uniform_policy
from xted.rl.policy_io import Policy
from xted.rl.run_folder import actor_checkpoint, read_evals

LEVELS = ("random", "medium", "medium-replay", "expert", "medium-expert", "source")
MEDIUM_FRACTION = 0.5


@dataclasses.dataclass(frozen=True)
class BehaviourPolicies:
    """Where a domain's behaviour policies (and medium replay buffer) come from."""

    expert: Path
    medium: Path | None
    replay: Path | None  # npz of the replay buffer up to the medium checkpoint

    @classmethod
    def from_run(cls, run_dir: str | Path, medium_step: int | None = None) -> "BehaviourPolicies":
        """The run's best checkpoint and its medium one: ``medium_step``'s checkpoint where given
        (an evaluated one), else the one :func:`select_checkpoints` picks."""
        run_dir = Path(run_dir)
        evals = read_evals(run_dir)
        if not evals:
            raise InputError(f"{run_dir} has no evaluated checkpoints (evals.csv)")
        best_step, chosen_step = select_checkpoints(evals)
        if medium_step is not None:
            evaluated = sorted(int(row["step"]) for row in evals)
            if medium_step not in evaluated or not actor_checkpoint(run_dir, medium_step).is_file():
                raise InputError(f"--medium-step {medium_step}: {run_dir} has no evaluated checkpoint at that step "
                                 f"({len(evaluated)} evaluated, steps {evaluated[0]} to {evaluated[-1]}: evals.csv)")
            chosen_step = medium_step
        return cls(actor_checkpoint(run_dir, best_step), actor_checkpoint(run_dir, chosen_step),
                   run_dir / "buffer.npz")

    @classmethod
    def shipped(cls, domain: Domain) -> "BehaviourPolicies":
        folder = policies_dir()
        expert = folder / f"{domain.name}-expert.msgpack"
        if not expert.exists():
            raise InputError(f"no shipped behaviour policy for {domain.name}; train one with `xted online train` "
                             f"and pass its folder with --run")
        medium = folder / f"{domain.name}-medium.msgpack"
        replay = folder / f"{domain.name}-medium-replay-buffer.npz"
        return cls(expert, medium if medium.exists() else None, replay if replay.exists() else None)


def policy_reference(path: Path) -> str:
    """How metadata names a policy file: ``xted/assets/policies/NAME`` for a shipped one (not this
    machine's install path), else the path as given."""
    path = Path(path)
    try:
        return f"xted/assets/policies/{path.resolve().relative_to(policies_dir().resolve()).as_posix()}"
    except ValueError:
        return str(path)


def select_checkpoints(evals: list[dict]) -> tuple[int, int]:
    """(best step, medium step): medium is the checkpoint before the best whose evaluation
    return is closest to ``MEDIUM_FRACTION`` of the best's."""
    best = max(evals, key=lambda row: row["return_mean"])
    before = [row for row in evals if row["step"] <= best["step"]]
    medium = min(before, key=lambda row: abs(row["return_mean"] - MEDIUM_FRACTION * best["return_mean"]))
    return int(best["step"]), int(medium["step"])


def _policy_fn(path: Path):
    actor = Policy.load(path)
    return actor, (lambda obs, rng: actor.act(obs, rng))


def _subset_episodes(arrays: dict[str, np.ndarray], transitions: int, seed: int):
    """Whole episodes in random order until ``transitions``; the last one cut with a timeout.

    Returns the arrays and the returns of the episodes kept whole."""
    if len(arrays["rewards"]) < transitions:
        raise InputError(f"the medium replay buffer holds {len(arrays['rewards'])} transitions, "
                         f"fewer than the {transitions} asked for")
    ends = np.flatnonzero(arrays["terminals"] | arrays["timeouts"]) + 1
    starts = np.concatenate([[0], ends[:-1]])
    order = np.random.default_rng(seed).permutation(len(starts))
    chosen, total = [], 0
    for i in order:
        chosen.append(np.arange(starts[i], ends[i]))
        total += ends[i] - starts[i]
        if total >= transitions:
            break
    whole = chosen if total == transitions else chosen[:-1]
    returns = np.array([arrays["rewards"][idx].sum() for idx in whole])
    idx = np.concatenate(chosen)[:transitions]
    out = {k: v[idx] for k, v in arrays.items()}
    if not (out["terminals"][-1] or out["timeouts"][-1]):
        out["timeouts"][-1] = True
    return out, returns


def _replay_prefix(replay: Path, medium: Path) -> dict[str, np.ndarray]:
    step = Policy.load(medium).meta["step"]
    with np.load(replay) as buffer:
        arrays = {k: buffer[k][:step] for k in buffer.files}
    # The buffer is cut where the medium checkpoint was taken, always at an episode end.
    if not (arrays["terminals"][-1] or arrays["timeouts"][-1]):
        arrays["timeouts"][-1] = True
    return arrays


def build_dataset(domain: Domain, level: str, transitions: int, policies: BehaviourPolicies | None,
                  seed: int = 0, progress: bool = True) -> Dataset:
    """Make ``transitions`` steps of ``level`` data in ``domain``."""
    if level not in LEVELS:
        raise InputError(f"unknown level {level!r}; known: {', '.join(LEVELS)}")
    if transitions <= 0:
        raise InputError(f"--transitions must be positive, got {transitions}")
    policy_info: dict = {}
    if level == "random":
        from xted.envs import make

        action_dim = make(domain).action_space.shape[0]
        arrays, returns = collect(uniform_policy(action_dim), domain, transitions, seed, progress=progress,
                                  desc=f"{domain.name} random")
        policy_info = {"policy": "uniform random"}
    elif policies is None:
        raise InputError(f"level {level!r} needs behaviour policies")
    elif level == "medium-replay":
        if policies.replay is None or policies.medium is None or not policies.replay.exists():
            raise InputError(f"no medium replay buffer for {domain.name}: the buffers are not shipped (tens of MB); "
                             f"pass --run with the `xted online train` run folder")
        arrays, returns = _subset_episodes(_replay_prefix(policies.replay, policies.medium), transitions, seed)
        policy_info = {"policy": policy_reference(policies.medium), "replay_buffer": policy_reference(policies.replay)}
    else:
        parts = {"medium": [(policies.medium, transitions)], "expert": [(policies.expert, transitions)],
                 "source": [(policies.expert, transitions)],
                 "medium-expert": [(policies.medium, transitions // 2), (policies.expert, transitions - transitions // 2)]}[level]
        chunks, all_returns, used = [], [], []
        for i, (path, count) in enumerate(parts):
            if path is None:
                raise InputError(f"no medium policy for {domain.name}")
            actor, fn = _policy_fn(path)
            chunk, chunk_returns = collect(fn, domain, count, seed + 7919 * i, progress=progress,
                                           desc=f"{domain.name} {level}")
            chunks.append(chunk)
            all_returns.append(chunk_returns)
            used.append({"path": policy_reference(path), "step": actor.meta.get("step"),
                         "train_domain": actor.meta.get("domain")})
        arrays = {k: np.concatenate([c[k] for c in chunks]) for k in chunks[0]}
        returns = np.concatenate(all_returns)
        policy_info = {"policy": used}
    # No score when no episode was kept whole (a small cut of long episodes).
    score = float(np.mean(normalized_score(domain.env, returns))) if len(returns) else None
    metadata = {
        "env": domain.env,
        "gap": domain.gap,
        "domain": domain.name,
        "level": level,
        "seed": seed,
        **policy_info,
        "episode_return_mean": float(np.mean(returns)) if len(returns) else None,
        "normalized_score": score,
        "command": " ".join(shlex.quote(a) for a in ["xted", *sys.argv[1:]]) if sys.argv[0].endswith("xted") else None,
        "created": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "xted_version": xted.__version__,
    }
    return Dataset(
        observations=arrays["observations"], actions=arrays["actions"], rewards=arrays["rewards"],
        terminals=arrays["terminals"], timeouts=arrays["timeouts"], next_observations=arrays["next_observations"],
        extras={}, metadata=metadata,
    )
