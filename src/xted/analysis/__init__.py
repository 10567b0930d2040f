"""Measuring edits: learned models of the target (the paper's dynamics proxy, a reward proxy) and
task-content similarity."""

from xted.analysis.content import content_similarity
from xted.analysis.edit_report import edit_report, simulator_measures
from xted.analysis.proxy import (DynamicsProxy, ProxyConfig, RewardProxy, fit_proxy, fit_reward_proxy,
                                 relabel_rewards)

__all__ = ["DynamicsProxy", "ProxyConfig", "RewardProxy", "content_similarity", "edit_report", "fit_proxy", "fit_reward_proxy",
           "relabel_rewards", "simulator_measures"]
