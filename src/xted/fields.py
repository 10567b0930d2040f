"""Config dataclass fields: the help text beside each field (:func:`setting`), the one override
parser (``--set FIELD=VALUE`` strings applied to a typed config), and field-name and value checks."""

from __future__ import annotations

import dataclasses
import types
import typing
from typing import Any

from xted.errors import InputError

BOOLEAN_WORDS = {"true": True, "1": True, "yes": True, "false": False, "0": False, "no": False}


def setting(default: Any, help: str) -> Any:
    """A dataclass field with its default and the help text the CLI shows for it."""
    return dataclasses.field(default=default, metadata={"help": help})


def field_help(config_type: type) -> dict[str, str]:
    """Each field's help text (:func:`setting`), by name, in declaration order."""
    return {f.name: f.metadata.get("help", "") for f in dataclasses.fields(config_type)}


def _typed_values(config_type: type, pairs: list[str]) -> dict[str, Any]:
    """``["field=value", ...]`` -> typed values of a config dataclass's scalar fields."""
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


def apply_overrides(config: Any, pairs: list[str]) -> Any:
    """``config`` (a dataclass instance) with ``FIELD=VALUE`` overrides, typed by its annotations:
    booleans as true/false/1/0/yes/no, ``none`` for an optional field, layer widths as
    ``hidden=256,256``, a nested config's fields (DARA's IQL backbone) as ``iql.FIELD=VALUE``. The
    result is built with ``dataclasses.replace``, so the config's own validation runs."""
    own: list[str] = []
    nested: dict[str, list[str]] = {}
    sizes: dict[str, tuple[int, ...]] = {}
    for pair in pairs:
        name, _, text = pair.partition("=")
        head, dot, _ = name.partition(".")
        current = getattr(config, head, None)
        if dataclasses.is_dataclass(current):
            if not dot:
                raise InputError(f"--set {pair!r}: {head} is a config; set {head}.FIELD=VALUE")
            nested.setdefault(head, []).append(pair[len(head) + 1:])
        elif isinstance(current, tuple) and not dot:
            try:
                sizes[head] = tuple(int(width) for width in text.split(","))
            except ValueError:
                sizes[head] = ()
            if not sizes[head] or min(sizes[head]) <= 0:
                raise InputError(f"--set {pair!r}: expected comma-separated positive layer widths such as 256,256")
        else:
            own.append(pair)
    changes = {**_typed_values(type(config), own), **sizes}
    changes.update({name: apply_overrides(getattr(config, name), sub) for name, sub in nested.items()})
    return dataclasses.replace(config, **changes)


def known_fields(config_type: type, fields: dict[str, Any]) -> dict[str, Any]:
    """``fields`` if each names a field of the dataclass ``config_type``, else an InputError naming
    the unknown ones (keyword arguments of the Python API, a config read from JSON)."""
    names = {f.name for f in dataclasses.fields(config_type)}
    unknown = sorted(set(fields) - names)
    if unknown:
        raise InputError(f"{config_type.__name__} has no field {', '.join(unknown)}; "
                         f"its fields: {', '.join(sorted(names))}")
    return fields


def check_fields(config: Any) -> None:
    """Validate an RL config's fields by what their names say: learning rates, epsilons, variances and
    tolerances > 0; sizes, steps, delays, iterations, chunks, dims and sample counts >= 1; discount,
    tau, expectile and fractions in (0, 1]; layer widths positive; every other number >= 0.
    InputError names the config and the field."""
    for field in dataclasses.fields(config):
        name, value = field.name, getattr(config, field.name)
        if isinstance(value, bool) or dataclasses.is_dataclass(value) or value is None:
            continue
        if isinstance(value, tuple):
            ok, need = len(value) > 0 and all(isinstance(w, int) and w > 0 for w in value), "positive layer widths"
        elif name.endswith(("lr", "epsilon", "variance", "tolerance")) or name == "learning_rate":
            ok, need = value > 0, "> 0"
        elif name.endswith(("batch_size", "batch", "steps", "delay", "iterations", "chunk", "dim", "samples")):
            ok, need = int(value) == value and value >= 1, "an integer >= 1"
        elif name in ("discount", "tau", "expectile") or name.endswith("fraction"):
            ok, need = 0 < value <= 1, "in (0, 1]"
        elif isinstance(value, int | float):
            ok, need = value >= 0, ">= 0"
        else:
            continue
        if not ok:
            raise InputError(f"{type(config).__name__}.{name} must be {need}, got {value!r}")
