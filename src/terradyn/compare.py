"""Comparing force series: peak differences and mean square errors on a common grid.

The one peak / MSE comparison of terradyn (SPH vs RFT, experiment vs model, surrogate vs
truth all call it). Works on any two force series whatever made them: the second is
interpolated linearly onto the first's motion coordinate, over the overlap of the two
ranges. The components compared default to the force components of the first series'
schema (:func:`terradyn.series.components`), so 3D series compare Fx, Fy, Fz.
"""
from __future__ import annotations

import numpy as np
import xarray as xr

from .errors import InputError
from .series import components as _components, coord_of


def _comps(a: xr.Dataset, components) -> tuple[str, ...]:
    comps = tuple(components) if components is not None else _components(a)
    return comps


def align(a: xr.Dataset, b: xr.Dataset, components=None) -> tuple[xr.Dataset, xr.Dataset]:
    """``a`` and ``b`` restricted to their common coordinate range, ``b`` interpolated onto
    ``a``'s samples."""
    components = _comps(a, components)
    c = coord_of(a)
    if coord_of(b) != c:
        raise InputError("series", f"cannot compare a {c!r} series with a {coord_of(b)!r} series")
    for k in components:
        for name, s in (("first", a), ("second", b)):
            if k not in s:
                raise InputError("components", f"the {name} series has no {k!r}")
    lo = max(float(a[c].min()), float(b[c].min()))
    hi = min(float(a[c].max()), float(b[c].max()))
    if not lo < hi:
        raise InputError("series", f"the two series do not overlap in {c}")
    a2 = a[list(components)].sel({c: slice(lo, hi)}) if a[c][0] < a[c][-1] else \
        a[list(components)].where((a[c] >= lo) & (a[c] <= hi), drop=True)
    b2 = b[list(components)].sortby(c).interp({c: a2[c].values})
    return a2, b2


def mse_values(a, b) -> float:
    """Mean square difference of two equal-length arrays (their units squared)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    if a.shape != b.shape:
        raise InputError("series", f"cannot compare shapes {a.shape} and {b.shape}")
    return float(np.mean((a - b) ** 2))


def peak_of(x, absolute: bool = False) -> tuple[float, int]:
    """(peak value, index): the maximum, or with ``absolute`` the signed value of largest
    magnitude."""
    x = np.asarray(x, float)
    i = int(np.argmax(np.abs(x) if absolute else x))
    return float(x[i]), i


def mse(a: xr.Dataset, b: xr.Dataset, components=None) -> dict[str, float]:
    """Mean square error (N^2) between two series per component."""
    components = _comps(a, components)
    a2, b2 = align(a, b, components)
    return {k: mse_values(a2[k].values, b2[k].values) for k in components}


def peak_difference(a: xr.Dataset, b: xr.Dataset, components=None,
                    absolute: bool = False) -> dict[str, dict]:
    """Peak of each component in ``a`` and ``b`` and the relative difference
    |peak_b - peak_a| / |peak_a| (the thesis's RFT-vs-SPH measure), plus where they occur.
    ``absolute``: peaks by magnitude (signed value of the largest |F|; the relative
    difference compares magnitudes)."""
    components = _comps(a, components)
    c = coord_of(a)
    out = {}
    for k in components:
        (pa, ia), (pb, ib) = peak_of(a[k].values, absolute), peak_of(b[k].values, absolute)
        ma, mb = (abs(pa), abs(pb)) if absolute else (pa, pb)
        out[k] = {"peak_a": pa, "peak_b": pb,
                  "rel_diff": abs(mb - ma) / abs(ma) if ma != 0 else float("inf"),
                  f"at_a_{c}": float(a[c].values[ia]), f"at_b_{c}": float(b[c].values[ib])}
    return out


def table(series: dict[str, xr.Dataset], reference: str, components=None) -> xr.Dataset:
    """MSE and relative peak difference of every series against ``series[reference]``, as a
    small Dataset indexed by source and component."""
    if reference not in series:
        raise InputError("reference", f"{reference!r} is not one of {list(series)}")
    components = _comps(series[reference], components)
    names = [n for n in series if n != reference]
    m = np.array([[mse(series[reference], series[n], components)[k] for k in components] for n in names])
    p = np.array([[peak_difference(series[reference], series[n], components)[k]["rel_diff"]
                   for k in components] for n in names])
    return xr.Dataset({"mse": (("source", "component"), m, {"units": "N^2"}),
                       "peak_rel_diff": (("source", "component"), p, {"units": "1"})},
                      coords={"source": names, "component": list(components)},
                      attrs={"reference": reference})
