"""The CLI reference (docs/cli.md), generated from the Typer app so that it cannot drift from it:
``python -m xted.cli.reference docs/cli.md`` rewrites it; a test checks it is current."""

from __future__ import annotations

import sys
from pathlib import Path

import typer

from xted.atomic import atomic_path
from xted.cli.main import app

HEADER = """# CLI reference

Generated from the Typer app by `python -m xted.cli.reference docs/cli.md` (a test checks that it is
current); `xted COMMAND --help` shows the same. Options under "... fields" are a config dataclass's
fields (their help lives next to the field); a command's `--set FIELD=VALUE` sets any field of the
configs it lists.
"""


def _cell(text: str) -> str:
    return " ".join(text.split()).replace("|", "\\|")


def _option_row(param) -> str:
    names = " / ".join(f"`{name}`" for name in [*param.opts, *param.secondary_opts])
    if param.param_type_name == "argument":
        names = f"`{param.name.upper()}` (argument)"
    default = param.default
    shown = "required" if param.required else ("" if default in (None, (), []) or callable(default) else f"`{default}`")
    kind = param.metavar or param.bare_type()
    return f"| {names} | {_cell(kind)} | {shown} | {_cell(getattr(param, 'help', None) or '')} |"


def _command_section(path: str, command) -> list[str]:
    """A command's help, a table of its options and the field list of its epilog (if any)."""
    lines = [f"## `{path}`", "", _cell(command.help or ""), "",
             "| option | type | default | help |", "|---|---|---|---|"]
    lines += [_option_row(p) for p in command.params if p.name != "help"]
    for paragraph in command.epilog.split("\n\n") if command.epilog else []:
        setting, _, help_text = paragraph.partition("  ")  # fields_epilog's "--set field=default  help"
        lines += [f"\n{_cell(paragraph)}\n"] if paragraph.endswith(":") else [f"- `{setting}`: {_cell(help_text)}"]
    return [*lines, ""]


def _commands(path: str, command) -> list[tuple[str, object]]:
    """``(path, command)`` of every command under ``command`` in name order (Typer's click objects)."""
    if hasattr(command, "commands"):
        return [pair for name in sorted(command.commands) for pair in _commands(f"{path} {name}", command.commands[name])]
    return [(path, command)]


def _overview(commands: list[tuple[str, object]]) -> list[str]:
    """One row per command: its name, linked to its section, and the first sentence of its help."""
    rows = ["| command | what it does |", "|---|---|"]
    for path, command in commands:
        first = _cell(command.help or "").split(". ")[0].rstrip(".")
        anchor = path.replace(" ", "-")
        rows.append(f"| [`{path}`](#{anchor}) | {first} |")
    return [*rows, ""]


def reference() -> str:
    """The whole reference as markdown: an overview, then one section per command in name order."""
    commands = _commands("xted", typer.main.get_command(app))
    sections = [line for path, command in commands for line in _command_section(path, command)]
    return "\n".join([HEADER, *_overview(commands), *sections]).rstrip() + "\n"


if __name__ == "__main__":
    if len(sys.argv) != 2:
        raise SystemExit("usage: python -m xted.cli.reference OUT.md")
    with atomic_path(Path(sys.argv[1])) as tmp:
        Path(tmp).write_text(reference())
