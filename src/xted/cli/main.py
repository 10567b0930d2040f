"""The ``xted`` command: one Typer app with a sub-app per area.

Exit codes: 0 success, 2 bad input or usage, 1 internal error.
"""

from __future__ import annotations

import importlib
import sys
import warnings

import typer
import typer.core

from xted.errors import DataWarning, InputError


def _flag_type_hidden(display_type_rich):
    """Typer labels an on/off flag ``<bool>`` in help, as if it took a value; a flag takes none."""
    def display(option, ctx):
        return None if option.is_flag else display_type_rich(option, ctx)
    return display


typer.core.TyperOption.display_type_rich = _flag_type_hidden(typer.core.TyperOption.display_type_rich)


def _short_data_warnings(format_warning):
    """A DataWarning reads ``xted: warning: ...``, without the source line Python adds."""
    def formatted(message, category, *args, **kwargs):
        if issubclass(category, DataWarning):
            return f"xted: warning: {message}\n"
        return format_warning(message, category, *args, **kwargs)
    return formatted


warnings.formatwarning = _short_data_warnings(warnings.formatwarning)

app = typer.Typer(
    name="xted",
    help="Cross-domain trajectory editing with diffusion models.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

def _print_version(value: bool) -> None:
    if value:
        from xted import __version__

        typer.echo(f"xted {__version__}")
        raise typer.Exit()


@app.callback()
def _root(version: bool = typer.Option(False, "--version", callback=_print_version, is_eager=True,
                                       help="Print xted's version and exit.")) -> None:
    """Cross-domain trajectory editing with diffusion models."""


# Sub-apps by name, and the modules that register top-level commands on ``app``. A module that
# fails to import is an error of xted itself, never a command silently missing.
_SUBAPPS = {"data": "xted.cli.data", "analyze": "xted.cli.analyze", "online": "xted.cli.online",
            "plot": "xted.cli.plot", "bench": "xted.cli.bench"}
_COMMAND_MODULES = ["xted.cli.prior", "xted.cli.policy", "xted.cli.render"]


def _register() -> None:
    for name, module_name in _SUBAPPS.items():
        app.add_typer(importlib.import_module(module_name).app, name=name)
    for module_name in _COMMAND_MODULES:
        importlib.import_module(module_name)


_register()


def main(argv: list[str] | None = None) -> int:
    """Run the CLI and return its exit code (usage errors exit 2 through Typer itself)."""
    try:
        app(args=argv, prog_name="xted")
    except SystemExit as err:
        return err.code if isinstance(err.code, int) else (0 if err.code is None else 1)
    except InputError as err:
        print(f"xted: error: {err}", file=sys.stderr)
        return 2
    return 0


def run() -> None:
    """Console-script entry point."""
    try:
        code = main()
    except Exception:
        import traceback

        traceback.print_exc()
        code = 1
    sys.exit(code)


if __name__ == "__main__":
    run()
