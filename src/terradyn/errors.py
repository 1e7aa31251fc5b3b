"""Errors that terradyn raises for bad input.

Every check on user input raises :class:`InputError`, which names the offending field
and what is allowed. The CLI turns it into a one-line message and exit code 2.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np


class InputError(ValueError):
    """Bad user input: ``field`` names the input, the message says what is allowed."""

    def __init__(self, field: str, message: str):
        self.field = field
        super().__init__(f"{field}: {message}")


def positive(field: str, value: Any, unit: str = "") -> float:
    """Return ``value`` as a float, or raise if it is not a finite number > 0."""
    v = finite(field, value, unit)
    if v <= 0:
        raise InputError(field, f"must be > 0{' ' + unit if unit else ''}, got {value!r}")
    return v


def finite(field: str, value: Any, unit: str = "") -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(field, f"must be a number{' in ' + unit if unit else ''}, got {value!r}") from None
    if not math.isfinite(v):
        raise InputError(field, f"must be finite, got {value!r}")
    return v


def in_range(field: str, value: Any, lo: float, hi: float, unit: str = "") -> float:
    v = finite(field, value, unit)
    if not lo <= v <= hi:
        u = f" {unit}" if unit else ""
        raise InputError(field, f"must be in [{lo:g}, {hi:g}]{u}, got {value!r}")
    return v


def integer(field: str, value: Any, minimum: int) -> int:
    try:
        v = int(value)
    except (TypeError, ValueError):
        raise InputError(field, f"must be an integer >= {minimum}, got {value!r}") from None
    if v != value and not (isinstance(value, float) and value.is_integer()):
        raise InputError(field, f"must be an integer >= {minimum}, got {value!r}")
    if v < minimum:
        raise InputError(field, f"must be an integer >= {minimum}, got {value!r}")
    return v


def finite_array(field: str, values: Any, ndim: int | None = None) -> np.ndarray:
    """Convert to a float array; raise if it is empty, non-numeric or has NaN/inf."""
    try:
        a = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise InputError(field, "must contain only numbers") from None
    if a.size == 0:
        raise InputError(field, "is empty")
    if ndim is not None and a.ndim != ndim:
        raise InputError(field, f"must be {ndim}-dimensional, got shape {a.shape}")
    bad = ~np.isfinite(a)
    if bad.any():
        idx = np.argwhere(bad)[0]
        raise InputError(field, f"contains a non-finite value at index {tuple(int(i) for i in idx)}")
    return a


def choice(field: str, value: str, allowed: list[str] | tuple[str, ...]) -> str:
    if value not in allowed:
        raise InputError(field, f"unknown value {value!r}; allowed: {', '.join(allowed)}")
    return value


#: Environment variable capping the memory one command may plan to use, GiB.
MEMORY_ENV = "TERRADYN_MAX_MEMORY_GB"


def memory_limit() -> int:
    """Bytes a single allocation plan may use: ``TERRADYN_MAX_MEMORY_GB`` or half of the
    machine's physical memory."""
    import os

    env = os.environ.get(MEMORY_ENV)
    if env:
        try:
            return int(float(env) * 2**30)
        except ValueError:
            pass
    try:
        return int(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") // 2)
    except (ValueError, OSError, AttributeError):  # pragma: no cover - non-POSIX
        return 8 * 2**30


def check_memory(field: str, nbytes: float, what: str) -> None:
    """Raise :class:`InputError` on ``field`` when ``what`` would need ``nbytes`` (an
    estimate) beyond :func:`memory_limit`: the check runs before the allocation."""
    limit = memory_limit()
    if nbytes > limit:
        raise InputError(field, f"{what} would need about {_gib(nbytes)} of memory, more than the "
                                f"limit {_gib(limit)} (half the RAM; set {MEMORY_ENV} to change it)")


def _gib(n: float) -> str:
    return f"{n / 2**30:.3g} GiB"


class renamed:
    """Context manager: an :class:`InputError` raised inside on a field in ``names`` comes
    out on the caller's name for it (e.g. the library's ``rate`` is the CLI's ``rate-hz``)."""

    def __init__(self, **names: str):
        self.names = {k.replace("__", "-"): v for k, v in names.items()}

    def __enter__(self):
        return self

    def __exit__(self, typ, e, tb):
        if isinstance(e, InputError) and e.field in self.names:
            msg = str(e).split(": ", 1)[-1]
            raise InputError(self.names[e.field], msg) from None
        return False


def non_negative(field: str, value: Any, unit: str = "") -> float:
    """Return ``value`` as a float, or raise if it is not a finite number >= 0."""
    v = finite(field, value, unit)
    if v < 0:
        raise InputError(field, f"must be >= 0{' ' + unit if unit else ''}, got {value!r}")
    return v


def open_text(path, field: str):
    """A text file's content as a stream (``io.StringIO``), or :class:`InputError` on
    ``field`` when it cannot be read or is not UTF-8 text (a binary file, say)."""
    import io

    try:
        with open(path, "rb") as fh:
            data = fh.read()
    except IsADirectoryError:
        raise InputError(field, f"{path} is a directory; give a file") from None
    except FileNotFoundError:
        raise InputError(field, f"file not found: {path}") from None
    except PermissionError:
        raise InputError(field, f"{path} is not readable (permission denied)") from None
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise InputError(field, f"{path} is not a text (UTF-8) file: byte {e.start} cannot be read") from None
    return io.StringIO(text, newline=None)
