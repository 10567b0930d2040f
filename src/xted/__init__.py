"""xted: cross-domain trajectory editing with diffusion models.

The public API (:mod:`xted.api`): ``load_dataset``, ``save_dataset``, ``train_prior``,
``load_prior``, a prior's ``edit``, ``edit_source`` (the edit with the learned projection and reward
relabelling, as ``xted edit`` runs it), ``measure_edit``, ``split_heldout``, ``train_policy``,
``load_policy``; loaded on first use, so ``import xted`` stays light.
"""

from xted.lazy import lazy_exports

__version__ = "0.1.0"

_EXPORTS = {
    "load_dataset": "api", "save_dataset": "api", "train_prior": "api", "load_prior": "diffusion.prior", "measure_edit": "api",
    "train_policy": "api", "load_policy": "api",
    "Dataset": "data", "split_heldout": "data", "EditConfig": "diffusion", "PriorConfig": "diffusion", "Prior": "diffusion",
    "Policy": "rl.policy_io", "edit_source": "pipelines.edit",
}

__all__ = sorted(_EXPORTS)
__getattr__ = lazy_exports(__name__, _EXPORTS)
