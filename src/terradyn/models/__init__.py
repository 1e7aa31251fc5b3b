"""The force-model protocol and registry: one place that knows which models exist.

A model is a :class:`Model`: a ``name``, its ``options`` (each an :class:`Option` with a
type, a default, a unit and its allowed range or choices) and a function
``simulate(body, motion, medium, **options) -> force series`` (an :mod:`terradyn.series`
Dataset of the model's ``schema``, "2d" or "3d"; always a force series, never a tuple).
Sweeps, studies and the command line look models up here::

    from terradyn import models
    models.names()                                 # ('rft', 'sph', ...)
    m = models.get("rft")
    series = m.simulate(leg, motion, "poppy LP", alpha="generic", zeta=0.3)
    series = models.simulate("rft", leg, motion, "poppy LP")   # the same, by name

Adding a model
--------------
Write its file (anywhere; the built-ins live in ``terradyn/models/<name>.py``) defining
a module-level ``MODEL = Model(...)``, and add one line to :data:`BUILTIN`::

    # terradyn/models/toy.py
    from . import Model, Option

    def _simulate(body, motion, medium, *, gain=1.0):
        ...                                     # return a force series
    MODEL = Model("toy", _simulate, options=(Option("gain", float, 1.0, lo=0, lo_open=True),),
                  description="a toy")

    # terradyn/models/__init__.py
    BUILTIN = {..., "toy": "terradyn.models.toy:MODEL"}

Code outside the package (a plugin, a test) registers at run time with
``models.register(MODEL)``. A 3D model declares ``schema="3d"`` and builds its series with
:func:`terradyn.series.make_series` (components Fx, Fy, Fz, Tx, Ty, Tz). Built-ins load
lazily on first use, so ``import terradyn`` stays fast and a model's heavy dependencies
(Numba for SPH) load only when it is asked for.

Option names carry their unit where it is not SI base (``dx_mm``, ``thickness_cm``,
``friction_deg``), the same names as the sweep spec's ``[model]`` keys and, with dashes,
as the CLI options. ``controls`` are run controls a model accepts besides its options
(``checkpoint``, ``progress``...): they change how a run is carried out, not its result,
and are not part of a sweep case's identity.
"""
from __future__ import annotations

import importlib
import math
import warnings
from dataclasses import dataclass, field
from typing import Any, Callable

from ..errors import InputError

#: name -> "module:attribute" of a :class:`Model`; one line per built-in model.
BUILTIN: dict[str, str] = {
    "rft": "terradyn.models.rft:MODEL",
    "rft3d": "terradyn.models.rft3d:MODEL",
    "sph": "terradyn.models.sph:MODEL",
}

_REGISTRY: dict[str, "Model"] = {}
_TYPE_NAMES = {float: "a number", int: "an integer", str: "a string", bool: "true or false"}


class IgnoredOptionWarning(UserWarning):
    """An option was given that has no effect with the other options (named in the text)."""


def ignored(field: str, message: str) -> None:
    """Warn that option ``field`` has no effect (the CLI prints it as one line)."""
    warnings.warn(f"{field}: {message}", IgnoredOptionWarning, stacklevel=3)


@dataclass(frozen=True)
class Option:
    """One option of a model: ``kind`` (float, int, str or bool), ``default`` (None: unset),
    ``unit`` (as written in messages), an allowed range [``lo``, ``hi``] (``lo_open`` /
    ``hi_open`` for strict bounds) or ``choices``, and ``help``."""

    name: str
    kind: type = float
    default: Any = None
    unit: str = ""
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False
    choices: tuple | None = None
    help: str = ""

    def describe(self) -> str:
        """The allowed values in words, e.g. '(0, 10] mm' or 'one of fit, generic, table'."""
        if self.choices:
            return "one of " + ", ".join(map(str, self.choices))
        if self.lo is None and self.hi is None:
            return _TYPE_NAMES.get(self.kind, self.kind.__name__)
        lo = "-inf" if self.lo is None else f"{self.lo:g}"
        hi = "inf" if self.hi is None else f"{self.hi:g}"
        b = "(" if self.lo_open or self.lo is None else "["
        e = ")" if self.hi_open or self.hi is None else "]"
        return f"{b}{lo}, {hi}{e}" + (f" {self.unit}" if self.unit else "")

    def check(self, value, field: str | None = None):
        """``value`` converted to the option's type, or :class:`InputError` on ``field``
        (default: the option's name) saying what is allowed, in the option's unit."""
        f = field or self.name
        if value is None:
            return None
        if self.kind is bool:
            if not isinstance(value, bool):
                raise InputError(f, f"must be true or false, got {value!r}")
            return value
        if self.kind is str:
            if not isinstance(value, str):
                raise InputError(f, f"must be a string, got {value!r}")
            v = value
        elif self.kind is int:
            if isinstance(value, bool) or not isinstance(value, (int, float)) or \
                    (isinstance(value, float) and not value.is_integer()):
                raise InputError(f, f"must be an integer, got {value!r}")
            v = int(value)
        else:
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise InputError(f, f"must be a number{' in ' + self.unit if self.unit else ''}, got {value!r}")
            v = float(value)
            if not math.isfinite(v):
                raise InputError(f, f"must be finite, got {value!r}")
        if self.choices is not None and v not in self.choices:
            raise InputError(f, f"unknown value {v!r}; allowed: {', '.join(map(str, self.choices))}")
        if self.kind in (int, float):
            bad_lo = self.lo is not None and (v <= self.lo if self.lo_open else v < self.lo)
            bad_hi = self.hi is not None and (v >= self.hi if self.hi_open else v > self.hi)
            if bad_lo or bad_hi:
                raise InputError(f, f"must be in {self.describe()}, got {value!r}")
        return v


def _dashes(name: str) -> str:
    return name.replace("_", "-")


@dataclass(frozen=True)
class Model:
    """A force model: see the module docstring. ``resolve`` (optional) turns a sweep's
    ``[model]`` table into the canonical parameters that identify a case (defaults filled
    in); without it, the declared defaults are filled in. ``legacy`` are option values to
    assume for stored cases recorded before the option existed. ``physics`` (optional) maps
    a case's resolved ``[model]`` parameters to the physical inputs that its defaults supply
    and that may change between versions (SPH: the shipped plate calibration of a named
    medium); a sweep compares it with what each stored case recorded before resuming."""

    name: str
    simulate_fn: Callable
    options: tuple[Option, ...] = ()
    description: str = ""
    schema: str = "2d"
    controls: tuple[str, ...] = ()
    resolve_fn: Callable[[dict], dict] | None = None
    legacy: dict = field(default_factory=dict)
    physics: Callable[[dict], dict] | None = None

    def option(self, name: str) -> Option:
        for o in self.options:
            if o.name == name:
                return o
        raise InputError(name, f"model {self.name!r} has no such option; it has "
                               f"{', '.join(o.name for o in self.options) or 'none'}")

    def check_options(self, options: dict, field: Callable[[str], str] = _dashes) -> dict:
        """The options checked (types, ranges, choices; unknown names refused), unset ones
        left out. ``field`` names an option in messages (default: the CLI's dashed name)."""
        known = {o.name: o for o in self.options}
        out = {}
        for k, v in options.items():
            if k not in known:
                raise InputError(field(k), f"unknown option of model {self.name!r}; allowed: "
                                           f"{', '.join(known) or 'none'}")
            v = known[k].check(v, field(k))
            if v is not None:
                out[k] = v
        return out

    def resolve(self, options: dict) -> dict:
        """Canonical parameters of a sweep case (``name`` and defaults included)."""
        if self.resolve_fn is not None:
            return {"name": self.name, **self.resolve_fn(dict(options))}
        options = dict(options)
        medium = options.pop("medium", None)
        if medium is None:
            raise InputError("model.medium", "missing; name the granular medium")
        opts = self.check_options(options, field=lambda k: f"model.{k}")
        full = {o.name: o.default for o in self.options if o.default is not None} | opts
        return {"name": self.name, "medium": medium, **full}

    def simulate(self, body, motion, medium, **options):
        """Check the options, run the model, check that it returned a force series of its
        schema; returns the series."""
        from ..series import schema_of, validate

        controls = {k: options.pop(k) for k in list(options) if k in self.controls}
        opts = self.check_options(options)
        ds = self.simulate_fn(body, motion, medium, **opts, **controls)
        validate(ds)
        if schema_of(ds).name != self.schema:
            raise TypeError(f"model {self.name!r} declared schema {self.schema!r} but returned "
                            f"{schema_of(ds).name!r}")
        return ds


def register(model: Model, *, replace: bool = False) -> Model:
    """Add ``model`` to the registry (``replace`` to supersede one of the same name)."""
    if not isinstance(model, Model):
        raise TypeError(f"register() takes a terradyn.models.Model, got {type(model).__name__}")
    if not replace and _REGISTRY.get(model.name) not in (None, model):
        raise ValueError(f"a model named {model.name!r} is already registered")
    _REGISTRY[model.name] = model
    return model


def unregister(name: str) -> None:
    """Remove a model registered at run time (tests); built-ins come back on next use."""
    _REGISTRY.pop(name, None)


def names() -> tuple[str, ...]:
    """Names of every model (built-in and registered), built-ins first."""
    return tuple(BUILTIN) + tuple(n for n in _REGISTRY if n not in BUILTIN)


def get(name: str, field: str = "model") -> Model:
    """The model called ``name`` (loading a built-in on first use), or :class:`InputError`
    on ``field`` listing the models."""
    if name in _REGISTRY:
        return _REGISTRY[name]
    if name in BUILTIN:
        mod, _, attr = BUILTIN[name].partition(":")
        model = getattr(importlib.import_module(mod), attr)
        _REGISTRY[name] = model
        return model
    raise InputError(field, f"unknown model {name!r}; allowed: {', '.join(names())}")


def simulate(name: str, body, motion, medium, **options):
    """``get(name).simulate(body, motion, medium, **options)``."""
    return get(name).simulate(body, motion, medium, **options)


__all__ = ["Model", "Option", "BUILTIN", "IgnoredOptionWarning", "ignored", "register",
           "unregister", "names", "get", "simulate"]
