"""The ``terradyn`` command line: a thin layer over the Python API.

Each area lives in its own module with a ``register(app)`` function; this module collects
them. Data go to stdout or files, messages to stderr; bad input exits with code 2 and one
line naming the field.
"""
from __future__ import annotations

import importlib
import importlib.util
import sys

import typer

from ..errors import InputError

app = typer.Typer(
    name="terradyn",
    help="Forces on legs and feet moving through granular media (RFT, SPH, DDDAS).",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    context_settings={"help_option_names": ["-h", "--help"]},
)

_AREAS = ("rft", "study", "sph", "dddas", "experiment", "sweep", "mujoco")


def _register_all() -> None:
    for name in _AREAS:
        mod = f"{__name__}.{name}"
        if importlib.util.find_spec(mod) is not None:
            importlib.import_module(mod).register(app)


def _version(value: bool):
    if value:
        from .. import __version__

        typer.echo(__version__)
        raise typer.Exit()


@app.callback()
def _root(version: bool = typer.Option(False, "--version", callback=_version, is_eager=True,
                                       help="Print the version and exit.")):
    """terradyn: forces on legs and feet in granular media."""


def err(msg: str) -> None:
    """A message for the user, on stderr."""
    from rich.console import Console

    Console(stderr=True, highlight=False, soft_wrap=True).print(msg)


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; returns the exit code (0 ok, 2 bad input or usage, 130 interrupted)."""
    _register_all()
    try:
        app(args=argv, prog_name="terradyn")  # standalone: usage errors exit 2 with a message
    except SystemExit as e:
        return e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
    except InputError as e:
        err(f"[bold red]error:[/] {e}")
        return 2
    except FileNotFoundError as e:
        err(f"[bold red]error:[/] file not found: {e.filename}")
        return 2
    except KeyboardInterrupt:
        err("interrupted")
        return 130
    return 0


def run() -> None:  # console-script entry point
    sys.exit(main())
