"""Environments with domain gaps and the simulator-replay dynamics error."""

from xted.envs.domains import (
    ENV_IDS,
    PAPER_GAPS,
    REFERENCE_RETURNS,
    Domain,
    check_same_env,
    dataset_env,
    normalized_score,
    parse_domain,
)
from xted.envs.make import make, simulator

__all__ = [
    "ENV_IDS",
    "PAPER_GAPS",
    "REFERENCE_RETURNS",
    "Domain",
    "check_same_env",
    "dataset_env",
    "make",
    "normalized_score",
    "parse_domain",
    "simulator",
]
