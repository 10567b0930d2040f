"""Measuring edits: learned models of the target (the paper's dynamics proxy, a reward proxy) and
task-content similarity. Names are loaded on first use (``xted.analysis.config`` stays light)."""

from xted.lazy import lazy_exports

_EXPORTS = {
    "ProxyConfig": "config", "content_similarity": "content", "content_shift": "content", "mean_spectra": "content",
    "edit_report": "report",
    "simulator_measures": "report", "DynamicsProxy": "proxy", "RewardProxy": "proxy", "fit_proxy": "proxy",
    "fit_reward_proxy": "proxy", "relabel_rewards": "proxy", "transition_validity": "validity",
}

__all__ = sorted(_EXPORTS)
__getattr__ = lazy_exports(__name__, _EXPORTS)
