"""Comparing force series: peak differences and mean square errors on a common grid.

Works on any two force series (RFT, SPH, experiment, surrogate, posterior) whatever made
them: the second is interpolated linearly onto the first's motion coordinate, over the
overlap of the two ranges.
"""
from __future__ import annotations

import numpy as np
import xarray as xr

from .errors import InputError
from .series import coord_of

COMPONENTS = ("Fx", "Fz")


def align(a: xr.Dataset, b: xr.Dataset, components=COMPONENTS) -> tuple[xr.Dataset, xr.Dataset]:
    """``a`` and ``b`` restricted to their common coordinate range, ``b`` interpolated onto
    ``a``'s samples."""
    c = coord_of(a)
    if coord_of(b) != c:
        raise InputError("series", f"cannot compare a {c!r} series with a {coord_of(b)!r} series")
    lo = max(float(a[c].min()), float(b[c].min()))
    hi = min(float(a[c].max()), float(b[c].max()))
    if not lo < hi:
        raise InputError("series", f"the two series do not overlap in {c}")
    a2 = a[list(components)].sel({c: slice(lo, hi)}) if a[c][0] < a[c][-1] else \
        a[list(components)].where((a[c] >= lo) & (a[c] <= hi), drop=True)
    b2 = b[list(components)].sortby(c).interp({c: a2[c].values})
    return a2, b2


def mse(a: xr.Dataset, b: xr.Dataset, components=COMPONENTS) -> dict[str, float]:
    """Mean square error (N^2) between two series per component."""
    a2, b2 = align(a, b, components)
    return {k: float(((a2[k] - b2[k]) ** 2).mean()) for k in components}


def peak_difference(a: xr.Dataset, b: xr.Dataset, components=COMPONENTS) -> dict[str, dict]:
    """Peak (maximum) of each component in ``a`` and ``b`` and the relative difference
    |peak_b - peak_a| / |peak_a| (the thesis's RFT-vs-SPH measure), plus where they occur."""
    c = coord_of(a)
    out = {}
    for k in components:
        pa, pb = float(a[k].max()), float(b[k].max())
        out[k] = {"peak_a": pa, "peak_b": pb,
                  "rel_diff": abs(pb - pa) / abs(pa) if pa != 0 else float("inf"),
                  f"at_a_{c}": float(a[c].values[int(np.argmax(a[k].values))]),
                  f"at_b_{c}": float(b[c].values[int(np.argmax(b[k].values))])}
    return out


def table(series: dict[str, xr.Dataset], reference: str, components=COMPONENTS) -> xr.Dataset:
    """MSE and relative peak difference of every series against ``series[reference]``, as a
    small Dataset indexed by source and component."""
    if reference not in series:
        raise InputError("reference", f"{reference!r} is not one of {list(series)}")
    names = [n for n in series if n != reference]
    m = np.array([[mse(series[reference], series[n], components)[k] for k in components] for n in names])
    p = np.array([[peak_difference(series[reference], series[n], components)[k]["rel_diff"]
                   for k in components] for n in names])
    return xr.Dataset({"mse": (("source", "component"), m, {"units": "N^2"}),
                       "peak_rel_diff": (("source", "component"), p, {"units": "1"})},
                      coords={"source": names, "component": list(components)},
                      attrs={"reference": reference})
