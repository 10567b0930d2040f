"""The whole edit, composed in one place: the prior's edit (guarded unless the config turns the guard
off), projected onto a dynamics model of target data when asked, its rewards relabelled by a reward
model of target data when asked. ``xted edit``, the bench's edit cells and the benchmark scripts
call :func:`edit_source`; ``Prior.edit`` is the prior's own edit without the learned models."""

from __future__ import annotations

from typing import Any

from xted.analysis import ProxyConfig, fit_proxy, fit_reward_proxy, relabel_rewards
from xted.analysis.proxy import DynamicsProxy
from xted.data import Dataset
from xted.diffusion.config import EditConfig
from xted.diffusion.editor import edit_dataset
from xted.diffusion.guard import fit_for_edit
from xted.diffusion.prior import Prior
from xted.envs.step_function import StepFunction
from xted.envs.termination import Termination


def edit_source(prior: Prior, source: Dataset, config: EditConfig, *, guard_target: Dataset | None = None,
                project_onto: Dataset | DynamicsProxy | StepFunction | None = None, dynamics_proxy: ProxyConfig | None = None,
                relabel_from: Dataset | None = None, reward_proxy: ProxyConfig | None = None,
                termination: Termination | None = None, progress: bool = False) -> tuple[Dataset, dict[str, Any]]:
    """``source`` edited with ``prior`` under ``config``, and the edit's report.

    ``guard_target``: target data to fit the guard's dynamics model to (it replaces the prior's own;
    needed where the prior holds none). ``project_onto``: target data to fit a dynamics model to
    (``dynamics_proxy``'s settings; default seeded by the edit), such a model already fitted, or your
    own step function (:mod:`xted.envs.step_function`); each edited state is then projected onto its
    rollout (``config.dynamics_weight``). ``relabel_from``:
    target data whose reward model (``reward_proxy``) gives every edited transition its reward.
    ``termination``: the target's termination rule where xted does not know the env."""
    dynamics = project_onto.predict if isinstance(project_onto, DynamicsProxy) else project_onto
    if isinstance(project_onto, Dataset):
        dynamics = fit_proxy(project_onto, dynamics_proxy or ProxyConfig(seed=config.seed), progress=progress).predict
    target_model = None
    if guard_target is not None and config.guard:
        target_model = fit_for_edit(guard_target, config.guard_disagreement, seed=config.seed)
    edited, report = edit_dataset(prior, source, config, progress=progress,
                                  dynamics=dynamics,
                                  target_model=target_model, termination=termination)
    report["dynamics_projected"] = dynamics is not None
    if relabel_from is not None:
        rewards = fit_reward_proxy(relabel_from, reward_proxy or ProxyConfig(seed=config.seed), progress=progress)
        edited = relabel_rewards(edited, rewards)
    report["rewards_relabelled"] = relabel_from is not None
    return edited, report
