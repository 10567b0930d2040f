"""The bench's grid: its cells, what each is computed from, and each cell's key.

A cell's key is the SHA-256 of everything that determines its result: the fingerprints of the
data it reads, the prior's files, the edit and algorithm configs, steps, evaluation and seed. Its
result is stored under that key, so a rerun skips a cell whose key it finds and computes any
whose inputs changed; planning is cheap (shipped data is small), so the report plans too and
reads exactly the current cells.

Kinds of cell: a *prior* (trained by the bench for a target with no prior shipped or given), an
*edit* (a source, or the target itself, edited with a prior), an *oracle* (a source relabelled by
the target simulator), an *s4rl* copy (the target with Gaussian state noise) and *ser* samples (of
a transition diffusion model trained on the target: :mod:`xted.diffusion.transitions`) make what
learners read; a *learner* trains one algorithm with one seed on target and/or source data. A
learner that reads an edit or an oracle, and an edit that reads a prior the bench trains, names
that cell's key, not its output's fingerprint, so the key is known before the output is made.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
from pathlib import Path
from typing import Any

from xted.analysis.config import ProxyConfig
from xted.fields import apply_overrides
from xted.data import Dataset, load, shipped
from xted.data.augment import S4RL_STATE_STD
from xted.diffusion.config import GUARD_FIELDS, EditConfig, PriorConfig
from xted.diffusion.config import preset as prior_preset
from xted.diffusion.config import presets as prior_presets
from xted.diffusion.guard import ENSEMBLE_FILE, TARGET_MODEL_FILE
from xted.diffusion.prior import read_prior_json
from xted.diffusion.transitions import TransitionModelConfig
from xted.envs import ENV_IDS, PAPER_GAPS, check_same_env, parse_domain
from xted.envs.make import observation_velocity_clip
from xted.errors import InputError
from xted.pipelines.bench.columns import COLUMNS, DATA_KINDS, LEARNER_WRAPPERS, WRAPPED_ALGO, Column
from xted.pipelines.bench.config import BenchConfig
from xted.resume import as_json
from xted.rl.config import OFFLINE_ALGORITHMS
from xted.rl.offline_train import AlgoConfig, algorithm_name, default_config

SHIPPED_PRIOR_SUFFIX = "-cpu"  # the shipped prior of target ENV-LEVEL is ENV-LEVEL-cpu
# A prior the bench trains leaves out two target episodes (fewer where the data has fewer than three)
# and starts from seed 0, as the shipped ones.
PRIOR_HELDOUT_EPISODES = 2
PRIOR_SEED = 0
AUGMENT_SEED = 0  # the noise of the S4RL copy; the SER model's initialisation, batches and samples
# Bound on the predicted x_0 (normalised units) of the augmentation columns' kappa = 1 edits: at the
# chain's noisiest step sqrt(abar) is 2.5e-4, and without it halfcheetah's edits at kappa 1 erred 370-510
# one step ahead in the simulator, with it 0.26 (BENCHMARKS.md, "Augmenting the target").
FULL_CHAIN_CLIP = 5.0


def cell_key(inputs: dict) -> str:
    return hashlib.sha256(json.dumps(as_json(inputs), sort_keys=True).encode()).hexdigest()


def folder_fingerprint(folder: Path) -> str:
    """SHA-256 of every file's relative path and bytes: exact identity of a prior folder, less its
    guard's target model and ensemble (a plain edit never reads them; a guarded edit's key names them apart)."""
    digest = hashlib.sha256()
    for path in sorted(p for p in folder.rglob("*") if p.is_file() and p.name not in (TARGET_MODEL_FILE, ENSEMBLE_FILE)):
        digest.update(str(path.relative_to(folder)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def first_transitions(data: Dataset, n: int | None) -> Dataset:
    """The first ``n`` transitions (the episode cut there ends in a timeout); all for None."""
    if n is None or n >= len(data):
        return data
    terminals, timeouts = data.terminals[:n].copy(), data.timeouts[:n].copy()
    timeouts[-1] = not terminals[-1]
    return Dataset(observations=data.observations[:n], actions=data.actions[:n], rewards=data.rewards[:n],
                   terminals=terminals, timeouts=timeouts,
                   next_observations=None if data.next_observations is None else data.next_observations[:n],
                   extras={k: v[:n] for k, v in data.extras.items()}, metadata=data.metadata)


@dataclasses.dataclass(frozen=True, eq=False)
class PriorCell:
    """A prior the bench trains itself (a target with no shipped prior and none passed), into
    ``folder`` in the cache; its edits name its key."""

    env: str
    target: str  # target level
    source: str  # the target dataset's name
    config: PriorConfig
    steps: int
    heldout_episodes: int
    folder: str
    inputs: dict
    key: str
    kind: str = "prior"

    @property
    def name(self) -> str:
        return f"prior-{self.target}-{self.key[:12]}"


@dataclasses.dataclass(frozen=True)
class DynamicsModel:
    """A dynamics model of the target, fitted to its first ``transitions`` (all for None)."""

    target: str  # dataset name
    transitions: int | None
    proxy: ProxyConfig


@dataclasses.dataclass(frozen=True, eq=False)
class DataCell:
    """An edit (``target`` is the prior's target level) or an oracle relabelling of one source; with
    ``gap`` None, data made from the target itself (an edit of it, its ``s4rl`` copy, ``ser`` samples)."""

    kind: str  # "edit", "oracle", "s4rl" or "ser"
    env: str
    gap: str
    source: str  # dataset name
    target: str | None = None
    prior: str | None = None  # the prior's folder (edits)
    edit: EditConfig | None = None
    inputs: dict = dataclasses.field(default_factory=dict)
    key: str = ""
    prior_cell: PriorCell | None = None  # where the bench trains the prior itself
    dynamics: DynamicsModel | None = None  # the model an edit is projected onto (``--project-dynamics``)

    @property
    def name(self) -> str:
        return "-".join(part for part in (self.kind, self.target, self.gap, self.key[:12]) if part)


@dataclasses.dataclass(frozen=True, eq=False)
class LearnerCell:
    """One seed of one algorithm on its training data (dataset names or data cells, target first).

    ``target`` is None where the result does not depend on the target level (Src), ``gap`` where it
    does not depend on the source (Tgt): such a cell is shared by every row it appears in."""

    env: str
    target: str | None
    gap: str | None
    column: str
    algo: str
    seed: int
    config: AlgoConfig
    training: tuple[str | DataCell, ...]
    inputs: dict
    key: str

    @property
    def group(self) -> tuple:
        """Cells that differ only by seed train together."""
        return (self.env, self.target, self.gap, self.column, self.algo)

    @property
    def data_cell(self) -> DataCell | None:
        return next((ref for ref in self.training if isinstance(ref, DataCell)), None)

    @property
    def name(self) -> str:
        slug = self.column.lower().replace(" ", "-")
        parts = (self.target, self.gap, slug, self.algo, f"seed{self.seed}", self.key[:12])
        return "-".join(part for part in parts if part is not None)


@dataclasses.dataclass(frozen=True)
class Row:
    """One line of the table: env x target x gap x column x algo, with its cell per seed; ``gap``
    None for a column of one cell per target (a column of per-target data kinds)."""

    env: str
    target: str
    gap: str | None
    column: str
    algo: str
    cells: tuple[LearnerCell, ...]  # empty where the column cannot be computed (no prior)


@dataclasses.dataclass(frozen=True, eq=False)
class Grid:
    config: BenchConfig
    datasets: dict[str, Dataset]
    rows: list[Row]
    learners: dict[str, LearnerCell]  # by key: a cell shared by several rows appears once

    def cells(self) -> list[LearnerCell | DataCell | PriorCell]:
        """Every cell of the grid once: learners, the data cells they read, the priors those read."""
        found: dict[str, LearnerCell | DataCell | PriorCell] = dict(self.learners)
        for learner in self.learners.values():
            for ref in learner.training:
                if isinstance(ref, DataCell):
                    found.setdefault(ref.key, ref)
                    if ref.prior_cell is not None:
                        found.setdefault(ref.prior_cell.key, ref.prior_cell)
        return list(found.values())


def check_names(config: BenchConfig) -> None:
    """Every env, target level, gap and algorithm known, with its shipped data; before any loading."""
    for env in config.envs:
        if env not in ENV_IDS:
            raise InputError(f"bench: unknown env {env!r}; known: {', '.join(ENV_IDS)}")
        for gap in config.gaps:
            if gap not in PAPER_GAPS[env]:
                raise InputError(f"bench: unknown gap {gap!r}; known: {', '.join(PAPER_GAPS[env])}")
        for name in [f"{env}-{target}" for target in config.targets] + [f"{env}-{gap}" for gap in config.gaps]:
            if shipped.find(name) is None:
                raise InputError(f"bench: no shipped dataset {name!r}; shipped: {', '.join(shipped.names())}")
    for algo in config.algos:
        default_config(algo)
    if config.prior_preset not in prior_presets():
        raise InputError(f"bench: unknown prior preset {config.prior_preset!r}; known: {', '.join(prior_presets())}")
    for key in config.prior_paths():
        if key.split("-", 1)[0] not in config.envs:
            raise InputError(f"--prior {key}=...: {key!r} is not ENV or ENV-TARGET of an env in the grid")
    for pair in config.prior_overrides:
        scope, colon, _ = pair.partition(":")
        if colon and "=" not in scope and scope not in config.envs:
            raise InputError(f"--prior-set {pair!r}: {scope!r} is not an env in the grid")
    for env in config.envs:
        try:
            apply_overrides(prior_preset(config.prior_preset, 1, 1), config.prior_overrides_for(env))
        except InputError as err:
            raise InputError(str(err).replace("--set ", "--prior-set ", 1)) from None


def edit_identity(edit: EditConfig, projected: bool) -> dict:
    """What makes two of the bench's edits the same: the edit config, without ``dynamics_weight``
    where the edit is not projected (the weight changes nothing then), without ``hold_first``
    where it holds and without ``guard_disagreement`` where it is off (cells keyed before those
    fields existed keep their keys)."""
    fields = {**dataclasses.asdict(edit), "hold_last": False}  # a field since removed, still in every edit's key
    if not projected:
        fields.pop("dynamics_weight")
    if edit.hold_first:
        fields.pop("hold_first")
    if not edit.guard:  # the plain edit, keyed as before the guard existed
        for name in GUARD_FIELDS:
            fields.pop(name)
    elif edit.guard_disagreement == 0:  # the guard as keyed before its disagreement test existed
        fields.pop("guard_disagreement")
    return fields


def edit_config(config: BenchConfig) -> EditConfig:
    """The plain edit (the paper's, the Tgt+Edited column's) at ``--kappa`` with ``--edit``'s overrides."""
    return dataclasses.replace(apply_overrides(EditConfig(guard=False), list(config.edit)), kappa=config.kappa)


def learner_config(config: BenchConfig, algo: str, column: Column, env: str) -> AlgoConfig | None:
    """The learner of ``column``'s rows of ``algo`` in ``env``: the algorithm's config with ``--set``'s
    pairs, or the column's wrapper of it as the IQL backbone (its ``env_settings``, then ``--set
    WRAPPER.FIELD=VALUE``); None where the column has no learner for ``algo``."""
    prefixes = tuple(f"{name}." for name in LEARNER_WRAPPERS)
    learner = apply_overrides(default_config(algo), [pair for pair in config.overrides if not pair.startswith(prefixes)])
    if column.learner is None:
        return learner
    if algo != WRAPPED_ALGO:
        return None
    own = [pair[len(column.learner) + 1:] for pair in config.overrides if pair.startswith(f"{column.learner}.")]
    return apply_overrides(OFFLINE_ALGORITHMS[column.learner](iql=learner), [*column.settings_for(env), *own])


def resolve_prior(config: BenchConfig, env: str, target: str) -> Path | None:
    given = config.prior_paths()
    path = given.get(f"{env}-{target}", given.get(env))
    if path is not None:
        if not (Path(path) / "prior.json").is_file():
            raise InputError(f"--prior {env}={path}: no prior.json there (not a prior folder)")
        return Path(path)
    shipped_prior = shipped.prior_dir(f"{env}-{target}{SHIPPED_PRIOR_SUFFIX}")
    return shipped_prior if (shipped_prior / "prior.json").is_file() else None


def plan(config: BenchConfig) -> Grid:
    """Every cell of the grid with its key; loads the datasets (and hashes the given priors), trains nothing.
    A target with no prior given or shipped gets a prior cell (``config.prior_steps`` of its preset)."""
    check_names(config)
    edit = edit_config(config)
    datasets: dict[str, Dataset] = {}

    def dataset(name: str) -> Dataset:
        if name not in datasets:
            datasets[name] = first_transitions(load(name), config.transitions)
        return datasets[name]

    def fingerprint(ref: str | DataCell) -> Any:
        return {"kind": ref.kind, "key": ref.key} if isinstance(ref, DataCell) else dataset(ref).fingerprint()

    def prior_cell(env: str, target_level: str) -> PriorCell:
        target = f"{env}-{target_level}"
        data = dataset(target)
        prior_config = apply_overrides(prior_preset(config.prior_preset, data.observation_dim, data.action_dim,
                                                    seed=PRIOR_SEED), config.prior_overrides_for(env))
        heldout = min(PRIOR_HELDOUT_EPISODES, data.num_episodes - 1)
        inputs = {"kind": "prior", "target": fingerprint(target), "config": prior_config.to_dict(),
                  "steps": config.prior_steps, "heldout_episodes": heldout}
        cell = PriorCell(env, target_level, target, prior_config, config.prior_steps, heldout, "", inputs, cell_key(inputs))
        return dataclasses.replace(cell, folder=str(Path(config.cache) / env / cell.name))

    def data_cell(kind: str, env: str, gap: str | None, target: str | None = None,
                  prior: Path | PriorCell | None = None, this_edit: EditConfig = edit) -> DataCell:
        """An edit (by ``this_edit``) or oracle of the ``gap`` source; with ``gap`` None, data made from
        the target itself: an edit (never projected), an ``s4rl`` copy or ``ser`` samples."""
        source = f"{env}-{gap}" if gap is not None else f"{env}-{target}"
        trained = prior if isinstance(prior, PriorCell) else None
        dynamics = None
        if kind == "edit":
            if trained is not None:
                prior, identity = Path(trained.folder), {"kind": "prior", "key": trained.key}
            else:
                meta = read_prior_json(prior / "prior.json")
                check_same_env(env, meta.get("data", {}).get("env"), f"the prior {prior}")
                identity = folder_fingerprint(prior)
            projected = config.project_dynamics and gap is not None
            inputs = {"kind": kind, "source": fingerprint(source), "prior": identity,
                      "edit": edit_identity(this_edit, projected)}
            if this_edit.guard and trained is None:  # a bench-trained prior's key covers its target model
                for name, file in (("target_model", TARGET_MODEL_FILE), ("target_ensemble", ENSEMBLE_FILE)):
                    if name == "target_model" or this_edit.guard_disagreement > 0:
                        shipped_model = prior / file
                        inputs[name] = (hashlib.sha256(shipped_model.read_bytes()).hexdigest() if shipped_model.is_file()
                                        else {"fitted_to": fingerprint(f"{env}-{target}")})
            if projected:
                dynamics = DynamicsModel(f"{env}-{target}", config.transitions,
                                         ProxyConfig(steps=config.dynamics_proxy_steps, seed=edit.seed))
                inputs["dynamics"] = {"target": fingerprint(dynamics.target), "proxy": dataclasses.asdict(dynamics.proxy)}
        elif kind == "s4rl":
            inputs = {"kind": kind, "source": fingerprint(source), "state_std": S4RL_STATE_STD, "seed": AUGMENT_SEED}
        elif kind == "ser":
            model = TransitionModelConfig(steps=config.ser_steps, seed=AUGMENT_SEED)
            inputs = {"kind": kind, "source": fingerprint(source), "model": dataclasses.asdict(model)}
        else:
            inputs = {"kind": kind, "source": fingerprint(source), "domain": env}
            if math.isfinite(observation_velocity_clip(parse_domain(env))):
                # Only where observations clip does the recovery change the relabelling (and the key).
                inputs["states_at_velocity_clip"] = "recovered by replaying the source"
        return DataCell(kind, env, gap, source, target, None if prior is None else str(prior),
                        this_edit if kind == "edit" else None, inputs, cell_key(inputs), trained, dynamics)

    # The paper's §5.4: Tgt (Edit) noises the target all the way (kappa 1) and denoises it from its
    # held first transitions; Tgt (Gen) holds nothing, generating from pure noise. From kappa 1 the
    # predicted x_0 is clipped (unless --edit sets a bound): unclipped, the chain's first steps blow up.
    full_chain = dataclasses.replace(edit, kappa=1.0, clip_denoised=edit.clip_denoised or FULL_CHAIN_CLIP)
    edits_of_kind = {"edit": edit, "guarded": dataclasses.replace(edit, guard=True), "self-edit": full_chain,
                     "gen": dataclasses.replace(full_chain, hold_first=False)}
    rows: list[Row] = []
    learners: dict[str, LearnerCell] = {}

    def add_rows(env: str, target_level: str, gap: str | None,
                 trainings: dict[Column, tuple[str | DataCell, ...] | None]) -> None:
        """A row per algo and column of ``trainings`` (None: not computable here), a cell per seed."""
        for algo in config.algos:
            for column, training in trainings.items():
                algo_config = learner_config(config, algo, column, env)
                if algo_config is None:
                    continue
                cells = []
                for seed in config.seeds if training is not None else ():
                    inputs = {"kind": "learner", "algo": algorithm_name(algo_config),
                              "config": dataclasses.asdict(algo_config), "domain": env,
                              "data": [fingerprint(ref) for ref in training], "steps": config.steps,
                              "eval_every": config.eval_every, "eval_episodes": config.eval_episodes, "seed": seed}
                    key = cell_key(inputs)
                    cells.append(learners.setdefault(key, LearnerCell(
                        env, target_level if column.reads_target else None,
                        None if column.data == ("target",) else gap, column.name, algo, seed, algo_config, training,
                        inputs, key)))
                rows.append(Row(env, target_level, gap, column.name, algo, tuple(cells)))

    columns = [COLUMNS[name] for name in config.columns]
    # Shipped or given priors (None: the bench trains that target's prior).
    resolved = ({(env, level): resolve_prior(config, env, level) for env in config.envs for level in config.targets}
                if any(column.needs_prior for column in columns) else {})
    for env in config.envs:
        kept = [prior for (prior_env, _), prior in resolved.items() if prior_env == env]
        if config.prior_overrides_for(env) and kept and all(prior is not None for prior in kept):
            raise InputError(
                f"--prior-set {' '.join(config.prior_overrides_for(env))}: {env}'s targets edit with the priors "
                f"{', '.join(prior.name for prior in kept)} (shipped or given), which the bench does not train, and "
                "--prior-set changes only the priors it trains; add a target without a shipped prior to --targets, or "
                "train that prior (xted train --set) and pass it with --prior")
    for env in config.envs:
        for target_level in config.targets:
            target = f"{env}-{target_level}"
            prior: Path | PriorCell | None = None
            if resolved:
                prior = resolved[env, target_level] or prior_cell(env, target_level)
            made: dict[tuple[str, str | None], DataCell] = {}

            def made_once(kind: str, gap: str | None) -> DataCell:
                if (kind, gap) not in made:
                    cell_kind = kind if kind in ("oracle", "s4rl", "ser") else "edit"
                    made[kind, gap] = data_cell(cell_kind, env, gap, None if kind == "oracle" else target_level, prior,
                                                edits_of_kind.get(kind, edit))
                return made[kind, gap]

            def data_of(kind: str, gap: str | None) -> tuple[str | DataCell, ...] | None:
                """What the data kind is in this row: datasets by name or data cells; None without a prior."""
                if DATA_KINDS[kind].needs_prior and prior is None:
                    return None
                if kind == "target":
                    return (target,)
                if kind == "source":
                    return (f"{env}-{gap}",)
                if kind == "sources":
                    return tuple(f"{env}-{each}" for each in config.gaps)
                if kind == "edits":
                    return tuple(made_once("edit", each) for each in config.gaps)
                return (made_once(kind, None if DATA_KINDS[kind].per_target else gap),)

            def training(column: Column, gap: str | None) -> tuple[str | DataCell, ...] | None:
                parts = [data_of(kind, gap) for kind in column.data]
                return None if None in parts else tuple(ref for part in parts for ref in part)

            for gap in config.gaps:
                add_rows(env, target_level, gap, {c: training(c, gap) for c in columns if not c.per_target})
            per_target = [column for column in columns if column.per_target]
            if per_target:
                add_rows(env, target_level, None, {c: training(c, None) for c in per_target})
    return Grid(config, datasets, rows, learners)
