"""The ``xted`` command: one Typer app with a sub-app per area.

Exit codes: 0 success, 2 bad input or usage, 1 internal error.
"""

from __future__ import annotations

import importlib
import sys

import typer

from xted.errors import InputError

app = typer.Typer(
    name="xted",
    help="Cross-domain trajectory editing with diffusion models.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

# (module, attribute, name) of each sub-app; a module that is not there yet is skipped.
_SUBAPPS = [
    ("xted.cli.data", "app", "data"),
    ("xted.cli.analyze", "app", "analyze"),
    ("xted.cli.online", "app", "online"),
]
# (module, attribute) of modules that register top-level commands on ``app``.
_COMMAND_MODULES = ["xted.cli.commands", "xted.cli.policy"]


def _register() -> None:
    for module_name, attr, name in _SUBAPPS:
        try:
            module = importlib.import_module(module_name)
        except ModuleNotFoundError as err:
            if err.name == module_name:
                continue
            raise
        app.add_typer(getattr(module, attr), name=name)
    for module_name in _COMMAND_MODULES:
        try:
            importlib.import_module(module_name)
        except ModuleNotFoundError as err:
            if err.name != module_name:
                raise


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
