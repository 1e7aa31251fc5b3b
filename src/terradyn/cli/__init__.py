"""The ``terradyn`` command line: a thin layer over the Python API.

Each area lives in its own module with a ``register(app)`` function; this module collects
them. Data go to stdout or files, messages to stderr. Failures are one line, never a
traceback: bad input (and usage errors) exit with code 2 naming the field, I/O errors
(permission, disk full, broken pipe) with code 1, an interrupt with 130; an option that has
no effect is a one-line warning. Set ``TERRADYN_DEBUG=1`` to see tracebacks of unexpected
errors.
"""
from __future__ import annotations

import errno
import importlib
import importlib.util
import math
import os
import sys
import warnings

import typer
from typer.core import TyperGroup

try:  # Typer >= 0.20 carries its own click
    from typer._click.exceptions import ClickException, UsageError
except ImportError:  # pragma: no cover - older Typer on the real click
    from click.exceptions import ClickException, UsageError

from ..errors import InputError


def err(msg: str) -> None:
    """A message for the user, on stderr."""
    from rich.console import Console

    Console(stderr=True, highlight=False, soft_wrap=True).print(msg)


def _plain(msg: str) -> None:
    """A message on stderr as it is (no markup: user values may contain brackets)."""
    try:
        sys.stderr.write(msg.rstrip("\n") + "\n")
        sys.stderr.flush()
    except (OSError, ValueError):
        pass


def _io_message(e: OSError) -> str:
    where = f" {e.filename}" if getattr(e, "filename", None) else ""
    if e.errno == errno.ENOSPC:
        return f"error: no space left on device{where}: the output was not written"
    if e.errno in (errno.EACCES, errno.EPERM):
        return f"error: permission denied{where}"
    if e.errno == errno.EROFS:
        return f"error: read-only file system{where}"
    if isinstance(e, FileNotFoundError):
        return f"error: file not found:{where or ' (no name)'}"
    return f"error: I/O error{where}: {e.strerror or e}"


def _silence_stdout() -> None:
    """After a broken pipe: point stdout at /dev/null so the exit flush cannot fail again."""
    try:
        fd = os.open(os.devnull, os.O_WRONLY)
        os.dup2(fd, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):
        pass


class _Group(TyperGroup):
    """The root command: turns every failure into one line and an exit code, and makes
    every float option refuse NaN and infinity."""

    def __init__(self, *a, **kw):
        super().__init__(*a, **kw)
        _finite_floats(self)

    def invoke(self, ctx):
        from ..models import IgnoredOptionWarning

        def show(message, category, filename, lineno, file=None, line=None):
            if issubclass(category, UserWarning) and not issubclass(category, DeprecationWarning):
                _plain(f"warning: {message}")

        with warnings.catch_warnings():
            warnings.simplefilter("always", IgnoredOptionWarning)
            warnings.showwarning = show
            try:
                out = super().invoke(ctx)
                sys.stdout.flush()  # a full disk on stdout shows here, not at exit
                return out
            except (typer.Exit, typer.Abort, SystemExit):
                raise
            except UsageError as e:
                hint = f" (try '{e.ctx.command_path} --help')" if getattr(e, "ctx", None) is not None else ""
                _plain(f"error: {e.format_message()}{hint}")
                ctx.exit(2)
            except ClickException as e:
                _plain(f"error: {e.format_message()}")
                ctx.exit(e.exit_code)
            except InputError as e:
                _plain(f"error: {e}")
                ctx.exit(2)
            except BrokenPipeError:
                _silence_stdout()
                _plain("error: output pipe closed (broken pipe)")
                ctx.exit(1)
            except OSError as e:
                if e.errno == errno.EPIPE:
                    _silence_stdout()
                _plain(_io_message(e))
                ctx.exit(1)
            except MemoryError:
                _plain("error: out of memory (reduce the sizes of the run)")
                ctx.exit(1)
            except KeyboardInterrupt:
                _plain("interrupted")
                ctx.exit(130)
            except Exception as e:  # a bug: one line unless debugging
                if os.environ.get("TERRADYN_DEBUG"):
                    raise
                _plain(f"error: internal error {type(e).__name__}: {e} (set TERRADYN_DEBUG=1 for the traceback)")
                ctx.exit(1)


app = typer.Typer(
    name="terradyn",
    help="Forces on legs and feet moving through granular media (RFT, SPH, DDDAS).",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,  # help text as written: Rich markup ate the [default: ...] brackets
    cls=_Group,
    context_settings={"help_option_names": ["-h", "--help"]},
)

_AREAS = ("rft", "rft3d", "study", "sph", "dddas", "experiment", "sweep", "mujoco", "reproduce")
_REGISTERED: list = []


def sub_app(**kw) -> typer.Typer:
    """A command group of the CLI (help text shown as written, defaults visible)."""
    kw.setdefault("no_args_is_help", True)
    return typer.Typer(rich_markup_mode=None, **kw)


def _register_all() -> None:
    if _REGISTERED:
        return
    for name in _AREAS:
        mod = f"{__name__}.{name}"
        if importlib.util.find_spec(mod) is not None:
            importlib.import_module(mod).register(app)
    _REGISTERED.append(True)


def _version(value: bool):
    if value:
        from .. import __version__

        typer.echo(__version__)
        raise typer.Exit()


@app.callback()
def _root(version: bool = typer.Option(False, "--version", callback=_version, is_eager=True,
                                       help="Print the version and exit.")):
    """terradyn: forces on legs and feet in granular media."""


def _is_float(p) -> bool:
    import typing

    ann = getattr(getattr(p, "type_descriptor", None), "annotation", None)
    return ann is float or float in typing.get_args(ann) and type(None) in typing.get_args(ann)


def _finite_floats(cmd) -> None:
    """Every float option refuses NaN and infinity (they are never written into outputs)."""
    for p in cmd.params:
        if _is_float(p) and not getattr(p, "_finite", False):
            orig = p.callback

            def cb(ctx, param, value, _orig=orig):
                if isinstance(value, float) and not math.isfinite(value):
                    name = (param.opts[0] if getattr(param, "opts", None) else str(param.name)).lstrip("-")
                    raise InputError(name, f"must be a finite number, got {value!r}")
                return _orig(ctx, param, value) if _orig else value

            p.callback = cb
            p._finite = True
    for sub in getattr(cmd, "commands", {}).values():
        _finite_floats(sub)


def get_app() -> typer.Typer:
    """The Typer app with every command registered (for ``typer.testing.CliRunner``)."""
    _register_all()
    return app


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; returns the exit code (0 ok, 1 I/O, 2 bad input or usage, 130 interrupted)."""
    try:
        typer.main.get_command(get_app()).main(args=argv, prog_name="terradyn", standalone_mode=True)
    except SystemExit as e:
        return e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
    return 0


def run() -> None:  # console-script entry point
    sys.exit(main())
