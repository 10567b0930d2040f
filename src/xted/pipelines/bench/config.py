"""The bench's settings. Plain Python: the CLI takes its defaults from here without loading JAX."""

from __future__ import annotations

import dataclasses

from xted.analysis.config import ProxyConfig
from xted.errors import InputError

# What a learner trains on, besides the target data it is evaluated against.
SRC, TGT, TGT_SRC, TGT_EDITED, TGT_ORACLE, TGT_SRC_DARA, TGT_EDITED_DARA = (
    "Src", "Tgt", "Tgt+Src", "Tgt+Edited", "Tgt+Oracle", "Tgt+Src DARA", "Tgt+Edited DARA")
TABLE_COLUMNS = (SRC, TGT, TGT_SRC, TGT_EDITED, TGT_ORACLE, TGT_SRC_DARA, TGT_EDITED_DARA)  # Tables 1 and 2
# Single-domain augmentation (the paper's §5.4): the target plus as many transitions made from it.
TGT_SELF_EDIT, TGT_GEN, TGT_S4RL, TGT_SER = "Tgt (Edit)", "Tgt (Gen)", "Tgt S4RL", "Tgt SER"
AUGMENT_COLUMNS = (TGT_SELF_EDIT, TGT_GEN, TGT_S4RL, TGT_SER)
# Several sources at once (the paper's appendix "multi-source"): the target plus every gap's source of
# the grid, unedited or edited by the one prior.
TGT_ALL_SRC, TGT_ALL_EDITED = "Tgt+All Src", "Tgt+All Edited"
MULTI_SOURCE_COLUMNS = (TGT_ALL_SRC, TGT_ALL_EDITED)
# The guarded edit (xted's default edit, beyond the paper): Tgt+Edited's source edited with the guard on.
TGT_GUARDED, TGT_GUARDED_DARA = "Tgt+Guarded", "Tgt+Guarded DARA"
GUARDED_COLUMNS = (TGT_GUARDED, TGT_GUARDED_DARA)
COLUMNS = TABLE_COLUMNS + GUARDED_COLUMNS + AUGMENT_COLUMNS + MULTI_SOURCE_COLUMNS
PER_TARGET_COLUMNS = AUGMENT_COLUMNS + MULTI_SOURCE_COLUMNS  # one cell per target, not per gap: rows of their own
# DARA's reward correction on the source's share: the paper's Table 2
DARA_COLUMNS = (TGT_SRC_DARA, TGT_EDITED_DARA, TGT_GUARDED_DARA)
EDITED_COLUMNS = (TGT_EDITED, TGT_EDITED_DARA, *GUARDED_COLUMNS)
PRIOR_COLUMNS = (*EDITED_COLUMNS, TGT_SELF_EDIT, TGT_GEN, TGT_ALL_EDITED)  # read a prior's output
DARA_BACKBONE = "iql"  # DARA corrects rewards for an IQL learner: its column exists for the IQL algo only


@dataclasses.dataclass(frozen=True)
class BenchConfig:
    """One grid: envs x target levels x gaps x columns x algos x seeds (the "lite table" by default).

    ``edit``: EditConfig overrides (``FIELD=VALUE``) on top of ``kappa``; ``project_dynamics``: each
    edit is projected onto a dynamics model fitted to the row's target data (``xted edit
    --project-dynamics TARGET``, ``dynamics_proxy_steps`` Adam steps); ``overrides``: the algorithm
    config's (``--set``; ``dara.FIELD=VALUE`` for the DARA column's own fields); ``priors``:
    ``ENV=PATH`` or ``ENV-TARGET=PATH`` (default: the shipped ``ENV-TARGET-cpu`` prior, where there is
    one, else one the bench trains: ``prior_steps`` of the ``prior_preset`` with ``prior_overrides``,
    PriorConfig's ``FIELD=VALUE`` for every env or ``ENV:FIELD=VALUE`` for one); ``ser_steps``: training
    steps of the Tgt SER column's transition model; ``transitions``: use
    only the first N transitions of every dataset (a quick look at the protocol; None: all)."""

    envs: tuple[str, ...] = ("halfcheetah", "walker2d")
    targets: tuple[str, ...] = ("medium-replay",)
    gaps: tuple[str, ...] = ("thigh", "gravity", "friction")
    columns: tuple[str, ...] = TABLE_COLUMNS
    algos: tuple[str, ...] = ("iql",)
    seeds: tuple[int, ...] = (0, 1, 2, 3, 4)
    steps: int = 30_000
    eval_every: int = 10_000
    eval_episodes: int = 10
    kappa: float = 0.5
    edit: tuple[str, ...] = ()
    project_dynamics: bool = False
    dynamics_proxy_steps: int = ProxyConfig.steps
    overrides: tuple[str, ...] = ()
    priors: tuple[str, ...] = ()
    transitions: int | None = None
    prior_steps: int = 20_000
    prior_preset: str = "cpu"
    prior_overrides: tuple[str, ...] = ()
    ser_steps: int = 20_000
    store: str = "benchmarks/results/bench"
    cache: str = "runs/bench-cache"

    def __post_init__(self) -> None:
        for name in ("envs", "targets", "gaps", "columns", "algos", "seeds"):
            values = getattr(self, name)
            if not values or len(set(values)) != len(values):
                raise InputError(f"bench: {name} must be a non-empty list without repeats, got {list(values)}")
        unknown = [column for column in self.columns if column not in COLUMNS]
        if unknown:
            raise InputError(f"bench: unknown column {unknown[0]!r}; known: {', '.join(COLUMNS)}")
        if any(seed < 0 for seed in self.seeds):
            raise InputError(f"bench: seeds must be non-negative, got {list(self.seeds)}")
        for name in ("steps", "eval_every", "eval_episodes", "prior_steps", "dynamics_proxy_steps", "ser_steps"):
            if getattr(self, name) <= 0:
                raise InputError(f"bench: {name} must be positive, got {getattr(self, name)}")
        if self.transitions is not None and self.transitions < 2:
            raise InputError(f"bench: transitions must be >= 2, got {self.transitions}")
        for pair in self.priors:
            if "=" not in pair:
                raise InputError(f"--prior {pair!r}: expected ENV=PATH or ENV-TARGET=PATH")
        for pair in self.prior_overrides:
            if "=" not in pair:
                raise InputError(f"--prior-set {pair!r}: expected FIELD=VALUE or ENV:FIELD=VALUE")

    def prior_overrides_for(self, env: str) -> list[str]:
        """The ``--prior-set`` pairs that apply to ``env``'s bench-trained priors: the unprefixed
        ones and those prefixed ``ENV:``, in the order given."""
        pairs = []
        for pair in self.prior_overrides:
            scope, colon, rest = pair.partition(":")
            if not colon or "=" in scope:
                pairs.append(pair)
            elif scope == env:
                pairs.append(rest)
        return pairs

    def prior_paths(self) -> dict[str, str]:
        """``--prior`` pairs as ``{ENV or ENV-TARGET: PATH}``."""
        return dict(pair.split("=", 1) for pair in self.priors)


@dataclasses.dataclass(frozen=True)
class RayConfig:
    """Running the grid as Ray tasks (``xted bench --executor ray``).

    ``address``: a running cluster's head (``HOST:6379``, or ``auto``); None starts a local Ray
    instance sized to this machine. ``retries``: how many times a task whose worker died (killed,
    out of memory, node lost) is run again before its cells are reported failed; an exception in a
    cell is deterministic and reported at once. ``cpus_per_task``: CPUs each task reserves;
    ``gpus_per_task``: GPUs each edit and learner task reserves (None: one where the cluster has
    GPUs, else none; oracle relabellings run on CPUs)."""

    address: str | None = None
    retries: int = 2
    cpus_per_task: int = 1
    gpus_per_task: float | None = None

    def __post_init__(self) -> None:
        if self.address is not None and not self.address.strip():
            raise InputError("--address: expected HOST:PORT of a Ray head (or 'auto')")
        if self.retries < 0:
            raise InputError(f"--retries must be >= 0, got {self.retries}")
        if self.cpus_per_task < 1:
            raise InputError(f"--cpus-per-task must be >= 1, got {self.cpus_per_task}")
        if self.gpus_per_task is not None and self.gpus_per_task < 0:
            raise InputError(f"--gpus-per-task must be >= 0, got {self.gpus_per_task}")
