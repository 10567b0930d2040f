"""Deprecated alias of :mod:`xted.rl.config` (its old name); goes in the next release."""

import warnings

from xted.rl.config import (  # noqa: F401
    ONLINE_ALGORITHM_NAMES, BCConfig, DARAConfig, IQLConfig, OnlineRunConfig, SACConfig, TD3BCConfig,
)

warnings.warn("xted.rl.configs is now xted.rl.config", DeprecationWarning, stacklevel=2)
