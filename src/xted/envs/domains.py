"""Domains: a base environment plus a physics gap (gravity, friction, thigh length).

A gap is written ``gravity``, ``friction``, ``thigh`` (the paper's source domains) or
parametrically, ``gravity=1.5``, ``friction=0.5,thigh=3``. Every factor multiplies the
target's value; the empty gap (``None``, ``""`` or ``"none"``) is the target domain itself.
"""

from __future__ import annotations

import dataclasses
import math

from xted.envs.morphology import THIGH_BODIES
from xted.errors import InputError

ENV_IDS = {"halfcheetah": "HalfCheetah-v5", "walker2d": "Walker2d-v5", "hopper": "Hopper-v5", "ant": "Ant-v5"}
KNOWN_ENVS = "halfcheetah, walker2d, hopper or ant (or a Gymnasium id)"  # for help texts

# The paper's source domains (xTED §5.1): 2x gravity, 0.25x/0.5x friction, 2x thigh.
PAPER_GAPS = {
    "halfcheetah": {"gravity": {"gravity": 2.0}, "friction": {"friction": 0.25}, "thigh": {"thigh": 2.0}},
    "walker2d": {"gravity": {"gravity": 2.0}, "friction": {"friction": 0.5}, "thigh": {"thigh": 2.0}},
    "hopper": {"gravity": {"gravity": 2.0}, "friction": {"friction": 0.5}, "thigh": {"thigh": 2.0}},  # walker2d's
    "ant": {"gravity": {"gravity": 2.0}, "friction": {"friction": 0.5}},  # legs without a thigh to scale
}

# D4RL reference returns (random, expert) for normalised scores.
REFERENCE_RETURNS = {"halfcheetah": (-280.178953, 12135.0), "walker2d": (1.629008, 4592.3),
                     "hopper": (-20.272305, 3234.3), "ant": (-325.6, 3879.7)}

FACTORS = ("gravity", "friction", "thigh")


def _refuse_thigh(env: str) -> None:
    raise InputError(f"{env} has no thigh gap (its legs have no thigh to scale); use gravity or friction")


@dataclasses.dataclass(frozen=True)
class Domain:
    """One simulator setting: ``env`` with each physical factor scaled."""

    env: str
    gravity: float = 1.0
    friction: float = 1.0
    thigh: float = 1.0

    def __post_init__(self) -> None:
        if self.thigh != 1.0 and self.env not in THIGH_BODIES:
            _refuse_thigh(self.env)

    @property
    def env_id(self) -> str:
        return ENV_IDS[self.env]

    @property
    def is_target(self) -> bool:
        return self.gravity == 1.0 and self.friction == 1.0 and self.thigh == 1.0

    @property
    def gap(self) -> str:
        """Canonical gap string: the paper's name where it is one, else ``k=v,...``."""
        factors = {f: getattr(self, f) for f in FACTORS if getattr(self, f) != 1.0}
        if not factors:
            return "none"
        for name, preset in PAPER_GAPS[self.env].items():
            if factors == preset:
                return name
        return ",".join(f"{k}={v:g}" for k, v in factors.items())

    @property
    def name(self) -> str:
        return self.env if self.is_target else f"{self.env}-{self.gap}"


def parse_domain(env: str, gap: str | None = None) -> Domain:
    """Parse ``env`` (our name, or its Gymnasium id: ``Hopper-v5``) and a gap string into a
    :class:`Domain`; bad names raise InputError."""
    env = {env_id: name for name, env_id in ENV_IDS.items()}.get(env, env)
    if env not in ENV_IDS:
        raise InputError(f"unknown env {env!r}; known: {', '.join(ENV_IDS)}")
    if gap is None or gap.strip().lower() in ("", "none", "target"):
        return Domain(env)
    factors: dict[str, float] = {}
    for part in gap.split(","):
        part = part.strip()
        if part.partition("=")[0].strip() == "thigh" and env not in THIGH_BODIES:
            _refuse_thigh(env)
        if "=" in part:
            key, _, value = part.partition("=")
            key = key.strip()
            if key not in FACTORS:
                raise InputError(f"unknown gap factor {key!r} in {gap!r}; known: {', '.join(FACTORS)}")
            try:
                factor = float(value)
            except ValueError:
                raise InputError(f"gap factor {key}={value!r} is not a number") from None
            if not math.isfinite(factor) or factor <= 0:
                raise InputError(f"gap factor {key}={value} must be a positive number")
            factors[key] = factor
        elif part in PAPER_GAPS[env]:
            factors.update(PAPER_GAPS[env][part])
        else:
            known = ", ".join(PAPER_GAPS[env])
            raise InputError(f"unknown gap {part!r}; use one of {known} or factor=value with {', '.join(FACTORS)}")
    return Domain(env, **factors)


def normalized_score(env: str, episode_return):
    """D4RL-normalised score: 100 * (return - random) / (expert - random)."""
    low, high = REFERENCE_RETURNS[env]
    return 100.0 * (episode_return - low) / (high - low)


ENV_METADATA_KEYS = ("env", "env_name", "env_id")  # ours, D4RL's file attribute, others'


def dataset_env(metadata: dict) -> str | None:
    """The env a dataset says it comes from: our name (``halfcheetah``) where the recorded one is
    recognisable (``HalfCheetah-v5``, D4RL's ``halfcheetah-medium-v2``), else as recorded, else None."""
    recorded = next((metadata[k] for k in ENV_METADATA_KEYS if isinstance(metadata.get(k), str) and metadata[k]), None)
    if recorded is None:
        return None
    squashed = recorded.lower().replace("_", "").replace("-", "")
    return next((name for name in ENV_IDS if squashed.startswith(name)), recorded)


def check_same_env(expected: str | None, found: str | None, what: str, allow_mismatch: bool = False) -> None:
    """Refuse data of another env: InputError naming both, unless either is unknown or allowed."""
    if allow_mismatch or expected is None or found is None or expected == found:
        return
    raise InputError(f"{what} comes from env {found!r}, not {expected!r}; pass --allow-env-mismatch if that "
                     f"is intended (the observation layouts must still match)")
