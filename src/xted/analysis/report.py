"""What an edit did, measured the three ways xted reports everywhere (``xted demo``,
``benchmarks/edit_quality.py``): replayed in the target simulator (next states and rewards), by the
paper's learned dynamics proxy where one is given, and for the task content it kept."""

from __future__ import annotations

from xted.analysis.content import content_shift, content_similarity
from xted.analysis.proxy import DynamicsProxy
from xted.data import Dataset
from xted.envs import Domain
from xted.envs.dynamics import dataset_dynamics_error, reward_error
from xted.envs.make import forward_velocity_index
from xted.envs.step_function import StepFunction, step_function_error


def simulator_measures(domain: Domain | StepFunction, data: Dataset) -> dict:
    """Simulator dynamics error (MAE, MSE, n, of those how many reach beyond the observation clip,
    how many were excluded at it) and the recorded rewards' error (MAE, bias; None for reward-free
    data, and for a user's step function, which gives no rewards)."""
    if not isinstance(domain, Domain):
        dynamics = step_function_error(domain, data)
        return {"mae": dynamics.mae, "mse": dynamics.mse, "n": dynamics.n, "beyond_clip": 0, "excluded_clipped": 0,
                "reward_mae": None, "reward_bias": None}
    dynamics = dataset_dynamics_error(domain, data)
    rewards = reward_error(domain, data) if data.has_rewards else None
    return {"mae": dynamics.mae, "mse": dynamics.mse, "n": dynamics.n, "beyond_clip": dynamics.beyond_clip,
            "excluded_clipped": dynamics.excluded_clipped, "reward_mae": rewards and rewards.mae,
            "reward_bias": rewards and rewards.bias}


def edit_report(domain: Domain | StepFunction | None, source: Dataset, edited: Dataset,
                proxy: DynamicsProxy | None = None, forward_index: int | None = None,
                target: Dataset | None = None) -> dict:
    """``{"simulator": {"source", "edited"}`` (with a domain, or a user's step function), ``"proxy":
    {"source", "edited"}`` (with a proxy), ``"content"`` (with the forward-velocity correlation where
    ``forward_index`` or the domain names that observation column), ``"shift"}`` (with the target data:
    :func:`~xted.analysis.content.content_shift`)."""
    report: dict = {}
    if domain is not None:
        report["simulator"] = {name: simulator_measures(domain, data) for name, data in (("source", source),
                                                                                         ("edited", edited))}
    if proxy is not None:
        report["proxy"] = {"source": proxy.error(source).mae, "edited": proxy.error(edited).mae}
    if forward_index is None and isinstance(domain, Domain):
        forward_index = forward_velocity_index(domain)
    report["content"] = content_similarity(source, edited, forward_index)
    if target is not None:
        report["shift"] = content_shift(source, edited, target, forward_index)
    return report
