"""Command options derived from config dataclasses, so a field's type, default and help live in one
place (the field, :func:`xted.fields.setting`) and every field is reachable from the CLI.

:func:`config_options` gives a command one named option per field (``--field-name``); the values
given reach the command as ``FIELD=VALUE`` strings for :func:`xted.fields.apply_overrides`, the
same parser ``--set`` uses. :func:`fields_epilog` lists a config's fields and their help for a
command whose configs are chosen at run time (``xted policy --algo``) and set with ``--set``.
"""

from __future__ import annotations

import dataclasses
import functools
import inspect
import types
import typing
from collections.abc import Callable
from typing import Any, Optional

import typer

from xted.errors import InputError
from xted.fields import field_help

PLAIN_TYPES = (bool, int, float, str)


def option_name(field: str) -> str:
    return "--" + field.replace("_", "-")


def _option_type(hint: Any) -> type:
    """The option's Python type: the field's own for bool/int/float/str, else ``str`` (optional
    values such as ``none``, layer widths) parsed by the override parser."""
    return hint if hint in PLAIN_TYPES else str


def _metavar(hint: Any) -> str | None:
    if hint in PLAIN_TYPES:
        return None
    kinds = [k for k in typing.get_args(hint) if k is not type(None)]
    if isinstance(hint, types.UnionType) and kinds:
        return f"{kinds[0].__name__.upper()}|none"
    return "W,W,..." if typing.get_origin(hint) is tuple else None


def config_options(config_type: type, into: str, skip: tuple[str, ...] = (), preset_defaults: bool = False,
                   panel: str | None = None) -> Callable:
    """Decorate a Typer command with one option per field of ``config_type`` (``skip`` apart). The
    command's parameter ``into`` receives the options given as ``["field=value", ...]``. With
    ``preset_defaults`` every option defaults to unset (a preset chosen at run time fills the
    rest); else to the field's default, shown in ``--help``."""
    hints = typing.get_type_hints(config_type)
    help_text = field_help(config_type)
    fields = [f for f in dataclasses.fields(config_type) if f.init and f.name not in skip]

    def decorate(command: Callable) -> Callable:
        signature = inspect.signature(command, eval_str=True)
        own = [p for p in signature.parameters.values() if p.name != into]
        clash = {p.name for p in own} & {f.name for f in fields}
        if into not in signature.parameters or clash:
            raise TypeError(f"{command.__name__}: needs a parameter {into!r}, and no option named like a field "
                            f"of {config_type.__name__} ({sorted(clash)})")
        derived = []
        for field in fields:
            hint = hints[field.name]
            kind = _option_type(hint)
            if preset_defaults or field.default is dataclasses.MISSING:
                default = None
            else:
                default = field.default if kind is hint else _text(field.default)
            decls = [f"{option_name(field.name)}/--no-{field.name.replace('_', '-')}"] if kind is bool else [
                option_name(field.name)]
            info = typer.Option(default, *decls, help=help_text[field.name] + (" [default: the preset's]"
                                                                              if preset_defaults else ""),
                                metavar=_metavar(hint), rich_help_panel=panel or f"{config_type.__name__} fields")
            derived.append(inspect.Parameter(field.name, inspect.Parameter.KEYWORD_ONLY, default=info,
                                             annotation=Optional[kind] if default is None else kind))

        @functools.wraps(command)
        def wrapper(**kwargs: Any) -> Any:
            values = {f.name: kwargs.pop(f.name) for f in fields}
            given = [f"{name}={_text(value)}" for name, value in values.items() if value is not None]
            return command(**kwargs, **{into: given})

        wrapper.__signature__ = signature.replace(parameters=[*own, *derived])
        wrapper.__annotations__ = {p.name: p.annotation for p in wrapper.__signature__.parameters.values()}
        del wrapper.__wrapped__
        return wrapper

    return decorate


def _text(value: Any) -> str:
    """A value as the override parser reads it (``none``, ``256,256``)."""
    if value is None:
        return "none"
    if isinstance(value, tuple):
        return ",".join(map(str, value))
    return str(value)


def fields_epilog(configs: dict[str, Any], option: str = "--set", prefix: str = "", nested: bool = True) -> str:
    """For a command's ``epilog``: under a heading per config (a dataclass, its defaults shown, or
    an instance, its values shown), one paragraph per
    field, ``{option} {prefix}field=default  help``, a nested config's fields as ``nested.field``
    (left out without ``nested``)."""
    paragraphs = []
    for heading, config in configs.items():
        paragraphs.append(f"{heading}:")
        paragraphs.extend(_field_lines(config() if isinstance(config, type) else config, option, prefix, nested))
    return "\n\n".join(paragraphs)


def _field_lines(config: Any, option: str, prefix: str, nested: bool) -> list[str]:
    lines = []
    for field in dataclasses.fields(config):
        value = getattr(config, field.name)
        if dataclasses.is_dataclass(value):
            if nested:
                lines.extend(_field_lines(value, option, f"{prefix}{field.name}.", nested))
        else:
            lines.append(f"{option} {prefix}{field.name}={_text(value)}  {field.metadata.get('help', '')}")
    return lines


def parse_seeds(text: str) -> list[int]:
    """``--seeds 0,1,2``: distinct non-negative integers."""
    try:
        seeds = [int(part) for part in text.split(",")]
    except ValueError:
        seeds = []
    if not seeds or min(seeds) < 0 or len(set(seeds)) != len(seeds):
        raise InputError(f"--seeds {text!r}: expected distinct non-negative integers such as 0,1,2")
    return seeds
