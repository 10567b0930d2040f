"""xted: cross-domain trajectory editing with diffusion models.

The public API (:mod:`xted.api`): ``load_dataset``, ``train_prior``, ``load_prior``,
``measure_edit``, a prior's ``edit``; loaded on first use, so ``import xted`` stays light.
"""

from xted.lazy import lazy_exports

__version__ = "0.1.0"

_EXPORTS = {
    "load_dataset": "api", "train_prior": "api", "load_prior": "api", "measure_edit": "api",
    "Dataset": "data", "EditConfig": "diffusion", "PriorConfig": "diffusion", "Prior": "diffusion",
}

__all__ = sorted(_EXPORTS)
__getattr__ = lazy_exports(__name__, _EXPORTS)
