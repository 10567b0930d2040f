"""Typed configuration helpers: ``FIELD=VALUE`` strings to config dataclass fields."""

from __future__ import annotations

import dataclasses
import types
import typing
from typing import Any

from xted.errors import InputError

BOOLEAN_WORDS = {"true": True, "1": True, "yes": True, "false": False, "0": False, "no": False}


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
        if kind is bool:
            if text.lower() not in BOOLEAN_WORDS:
                raise InputError(f"--set {pair!r}: {text!r} is not a boolean; use one of {', '.join(BOOLEAN_WORDS)}")
            overrides[name] = BOOLEAN_WORDS[text.lower()]
            continue
        try:
            overrides[name] = kind(text)
        except ValueError:
            raise InputError(f"--set {pair!r}: {text!r} is not a {kind.__name__}") from None
    return overrides
