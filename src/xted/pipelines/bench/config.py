"""The bench's settings. Plain Python: the CLI takes its defaults from here without loading JAX."""

from __future__ import annotations

import dataclasses

from xted.analysis.config import ProxyConfig
from xted.errors import InputError
from xted.pipelines.bench.columns import COLUMNS, TABLE_COLUMNS
from xted.rl.config import OFFLINE_STEPS


@dataclasses.dataclass(frozen=True)
class BenchConfig:
    """One grid: envs x target levels x gaps x columns x algos x seeds (the "lite table" by default).

    ``edit``: EditConfig overrides (``FIELD=VALUE``) on top of ``kappa``; ``project_dynamics``: each
    edit is projected onto a dynamics model fitted to the row's target data (``xted edit
    --project-dynamics TARGET``, ``dynamics_proxy_steps`` Adam steps); ``overrides``: the algorithm
    config's (``--set``; ``dara.FIELD=VALUE``, ``igdf.FIELD=VALUE`` and ``otdf.FIELD=VALUE`` for the
    fields of the columns whose learner wraps the IQL backbone); ``priors``:
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
    steps: int = OFFLINE_STEPS
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
    store: str = "benchmarks/results/bench"  # relative to the working folder: a checkout's committed store
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
    """Running the grid as Ray tasks (``xted bench run --executor ray``).

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
