"""The force-series schema: what every model in terradyn produces.

A force series is an :class:`xarray.Dataset` with

* one motion coordinate: ``theta`` (deg, leg angle) for rotation tests, or ``time`` (s);
  the other, when known, as a non-index coordinate on the same dimension;
* data variables ``Fx`` and ``Fz`` (N): force of the medium on the leg, x forward (thrust
  positive in the standard rotating-leg test), z up (lift positive); ``torque`` (N m) about
  the hip axis, anticlockwise positive in the x-z plane, where known; optional ``Fx_std``,
  ``Fz_std`` (N) for uncertain predictions;
* attributes: ``model``, ``leg``, ``medium``, ``terradyn_version``, ``created`` and ``input``
  (JSON of the full input) so that a series says what made it.

Stacks of series along a ``case`` dimension are what sweeps write and surrogates train on.

Schemas
-------
A series declares its components through its schema (attribute ``schema``; a series
without one is ``"2d"``). Code that loops over force or torque components (compare,
surrogate, filter, plots) asks the schema, so a 3D model is an addition, not an edit::

    SCHEMAS["2d"]: forces ("Fx", "Fz"),        torques ("torque",)     planar: x forward, z up
    SCHEMAS["3d"]: forces ("Fx", "Fy", "Fz"),  torques ("Tx", "Ty", "Tz")  y to the left

3D models build their series with :func:`make_series` (schema "3d")::

    make_series("time", t, {"Fx": fx, "Fy": fy, "Fz": fz, "Tx": tx, "Ty": ty, "Tz": tz},
                schema="3d", model="rft3d", inputs={...})

and read them back with :func:`schema_of` / :func:`components`. Every force component is
required; torque components are optional (all or none). ``<component>_std`` variables
(the same units) are the uncertainty of a prediction.
"""
from __future__ import annotations

import datetime as _dt
import json
from typing import Any

import numpy as np
import xarray as xr

from .errors import InputError

from dataclasses import dataclass

COORDS = ("theta", "time")


@dataclass(frozen=True)
class Schema:
    """The components a force series carries: ``forces`` (N, required) and ``torques``
    (N m, optional: all or none)."""

    name: str
    forces: tuple[str, ...]
    torques: tuple[str, ...]

    @property
    def components(self) -> tuple[str, ...]:
        return self.forces + self.torques


SCHEMAS = {
    "2d": Schema("2d", ("Fx", "Fz"), ("torque",)),
    "3d": Schema("3d", ("Fx", "Fy", "Fz"), ("Tx", "Ty", "Tz")),
}
UNITS = {"theta": "deg", "time": "s", "Fx": "N", "Fy": "N", "Fz": "N", "torque": "N m",
         "Tx": "N m", "Ty": "N m", "Tz": "N m"}
UNITS.update({f"{k}_std": u for k, u in list(UNITS.items()) if k not in COORDS})
LONG_NAMES = {"theta": "leg angle from the downward vertical", "time": "time",
              "Fx": "horizontal force (+ forward / thrust)", "Fz": "vertical force (+ up / lift)",
              "Fy": "lateral force (+ left)",
              "torque": "torque about the hip (+ anticlockwise)",
              "Tx": "torque about x (roll)", "Ty": "torque about y (pitch)", "Tz": "torque about z (yaw)"}
LONG_NAMES.update({f"{k}_std": f"standard deviation of {k}" for k in list(LONG_NAMES) if k not in COORDS})


def schema_of(ds: xr.Dataset) -> Schema:
    """The schema of a series (attribute ``schema``; "2d" when absent, "3d" when it has Fy)."""
    name = ds.attrs.get("schema") or ("3d" if "Fy" in ds else "2d")
    if name not in SCHEMAS:
        raise InputError("force series", f"unknown schema {name!r}; known: {', '.join(SCHEMAS)}")
    return SCHEMAS[name]


def components(ds: xr.Dataset, torques: bool = False) -> tuple[str, ...]:
    """The force components of ``ds`` (and, with ``torques``, its torque components that
    are present), in schema order."""
    sc = schema_of(ds)
    return sc.forces + (tuple(t for t in sc.torques if t in ds) if torques else ())


def _version() -> str:
    from . import __version__

    return __version__


def force_series(coord: str, values, Fx, Fz, torque=None, *, model: str, inputs: dict[str, Any],
                 time=None, extra: dict[str, Any] | None = None) -> xr.Dataset:
    """Build a 2D force series. ``values``: (S,) coordinate values (deg for theta, s for
    time); Fx, Fz, torque: (S,) N / N m; ``inputs``: JSON-serialisable description of the
    full input; ``extra``: more data variables (name -> (S,) array) with units in ``UNITS``."""
    comps = {"Fx": Fx, "Fz": Fz}
    if torque is not None:
        comps["torque"] = torque
    return make_series(coord, values, comps, schema="2d", model=model, inputs=inputs, time=time,
                       extra=extra)


def make_series(coord: str, values, data: dict[str, Any], *, schema: str = "2d", model: str,
                inputs: dict[str, Any], time=None, extra: dict[str, Any] | None = None) -> xr.Dataset:
    """Build a force series of any schema: ``data`` maps each of the schema's force
    components (and optionally all its torque components) to (S,) values."""
    if coord not in COORDS:
        raise InputError("coord", f"must be one of {COORDS}, got {coord!r}")
    if schema not in SCHEMAS:
        raise InputError("schema", f"unknown schema {schema!r}; known: {', '.join(SCHEMAS)}")
    sc = SCHEMAS[schema]
    unknown = set(data) - set(sc.components)
    if unknown:
        raise InputError("force series", f"{sorted(unknown)} are not components of schema {schema!r} "
                                         f"({', '.join(sc.components)})")
    data = {k: (coord, np.asarray(data[k], float)) for k in sc.components if k in data}
    for k, v in (extra or {}).items():
        data[k] = (coord, np.asarray(v, float))
    coords = {coord: np.asarray(values, float)}
    if time is not None and coord != "time":
        coords["time"] = (coord, np.asarray(time, float))
    ds = xr.Dataset(data, coords=coords)
    for name in list(ds.data_vars) + list(ds.coords):
        if name in UNITS:
            ds[name].attrs.update(units=UNITS[name], long_name=LONG_NAMES.get(name, name))
    ds.attrs.update(
        model=model,
        leg=str(inputs.get("leg", {}).get("shape", "")) if isinstance(inputs.get("leg"), dict) else "",
        medium=str(inputs.get("medium", "")),
        terradyn_version=_version(),
        created=_dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        input=json.dumps(inputs, sort_keys=True, default=_json_default),
        Conventions="CF-1.10",
    )
    if schema != "2d":
        ds.attrs["schema"] = schema
    validate(ds)
    return ds


def _json_default(o):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    return str(o)


def inputs_of(ds: xr.Dataset) -> dict:
    """The full input recorded in a series."""
    return json.loads(ds.attrs.get("input", "{}"))


def coord_of(ds: xr.Dataset) -> str:
    """The motion coordinate of a series: 'theta' or 'time'."""
    for c in COORDS:
        if c in ds.dims:
            return c
    raise InputError("force series", f"has no motion dimension (one of {COORDS}); dims: {list(ds.dims)}")


def validate(ds: xr.Dataset) -> xr.Dataset:
    """Check that ``ds`` is a force series; raise :class:`InputError` naming what is wrong."""
    if not isinstance(ds, xr.Dataset):
        raise InputError("force series", f"must be an xarray.Dataset, got {type(ds).__name__}")
    c = coord_of(ds)
    sc = schema_of(ds)
    present = [t for t in sc.torques if t in ds]
    if present and len(present) != len(sc.torques):
        raise InputError("force series", f"has {present} but not all torque components {list(sc.torques)}")
    for v in sc.forces:
        if v not in ds:
            raise InputError("force series", f"missing variable {v!r}")
        if c not in ds[v].dims:
            raise InputError("force series", f"{v} does not vary along {c!r}")
        if not np.isfinite(ds[v].values).all():
            raise InputError("force series", f"{v} contains NaN or inf")
    vals = ds[c].values
    if len(vals) > 1 and not (np.all(np.diff(vals) > 0) or np.all(np.diff(vals) < 0)):
        raise InputError("force series", f"coordinate {c!r} must be strictly monotonic")
    return ds


def stack(series: list[xr.Dataset], case_coords: dict[str, Any] | None = None) -> xr.Dataset:
    """Stack force series on the same motion grid along a new ``case`` dimension.
    ``case_coords``: name -> (n_cases,) values labelling each case (e.g. omega)."""
    if not series:
        raise InputError("series", "nothing to stack")
    c = coord_of(series[0])
    for i, s in enumerate(series):
        validate(s)
        if coord_of(s) != c or len(s[c]) != len(series[0][c]) or not np.allclose(s[c], series[0][c]):
            raise InputError("series", f"series {i} is not on the same {c} grid as series 0")
    ds = xr.concat([s.drop_attrs() if hasattr(s, "drop_attrs") else s for s in series], dim="case",
                   coords="minimal", compat="override", join="override")
    ds = ds.assign_coords(case=np.arange(len(series)))
    for k, v in (case_coords or {}).items():
        ds = ds.assign_coords({k: ("case", np.asarray(v))})
    ds.attrs.update(series[0].attrs)
    ds.attrs["inputs"] = json.dumps([inputs_of(s) for s in series])
    return ds
