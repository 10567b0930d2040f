"""Deprecated alias of :mod:`xted.fields` (the override parser's old name); goes in the next release."""

import warnings

from xted.fields import BOOLEAN_WORDS, apply_overrides, check_fields, known_fields  # noqa: F401

warnings.warn("xted.config is now xted.fields", DeprecationWarning, stacklevel=2)
