"""Typed configuration helpers: ``FIELD=VALUE`` strings to config dataclass fields."""

from __future__ import annotations

import dataclasses
import types
import typing
from typing import Any

from xted.errors import InputError


def parse_overrides(config_type: type, pairs: list[str]) -> dict[str, Any]:
    """``["field=value", ...]`` -> typed overrides of a config dataclass's fields."""
    hints = typing.get_type_hints(config_type)
    overrides: dict[str, Any] = {}
    for pair in pairs:
        name, sep, text = pair.partition("=")
        if not sep or name not in hints:
            fields = ", ".join(f.name for f in dataclasses.fields(config_type))
            raise InputError(f"--set {pair!r}: expected FIELD=VALUE with FIELD one of {fields}")
        kinds = [k for k in typing.get_args(hints[name]) if k is not type(None)] or [hints[name]]
        if isinstance(hints[name], types.UnionType) and text.lower() == "none":
            overrides[name] = None
            continue
        kind = kinds[0]
        try:
            overrides[name] = (text.lower() in ("1", "true", "yes")) if kind is bool else kind(text)
        except ValueError:
            raise InputError(f"--set {pair!r}: {text!r} is not a {kind.__name__}") from None
    return overrides
