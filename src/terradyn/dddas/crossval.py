"""Leave-one-condition-out cross-validation of the surrogate (the thesis's ten-fold CV over
ten speeds: each condition in turn is the unseen test case)."""
from __future__ import annotations

import time
from typing import Callable

import numpy as np
import xarray as xr
from sklearn.base import clone

from ..errors import InputError
from .surrogate import Surrogate, training_arrays


def cross_validate(data: xr.Dataset, estimator: Surrogate | None = None,
                   baseline: xr.Dataset | None = None,
                   progress: Callable[[int, int], None] | None = None) -> xr.Dataset:
    """Hold out each case of the stack ``data`` in turn, fit a clone of ``estimator`` on the
    others and predict the held-out one.

    Returns a Dataset with ``mse`` (case, component) in N^2 (N^2 m^2 for torque): mean square
    error over the motion coordinate between prediction and truth; ``mse_nearest``: the error
    of simply reusing the nearest training condition's curve (a naive baseline); with
    ``baseline`` (a stack on the same cases, e.g. RFT at each condition) also
    ``mse_baseline``; and ``predicted``, ``predicted_std``, ``truth`` (case, coord,
    component); ``ranks`` (case, mode). attrs: ``seconds`` (wall time)."""
    est = estimator if estimator is not None else Surrogate()
    from ..series import components

    comps = list(est.components) if est.components is not None else list(components(data))
    X, Y, coord, values, names = training_arrays(data, est.inputs, comps)
    n = len(X)
    if n < 4:
        raise InputError("data", f"cross-validation needs at least 4 cases, got {n}")
    t0 = time.perf_counter()
    pred = np.empty_like(Y)
    pstd = np.empty_like(Y)
    near = np.empty_like(Y)
    ranks = np.zeros((n, 3), int)
    xs = X.std(0)
    for i in range(n):
        keep = np.arange(n) != i
        sub = data.isel(case=keep)
        m = clone(est).fit(sub)
        mu, sd = m.predict_arrays(X[i:i + 1])
        pred[i], pstd[i] = mu[0], sd[0]
        ranks[i] = m.ranks_
        d = np.linalg.norm((X[keep] - X[i]) / xs, axis=1)
        near[i] = Y[keep][int(np.argmin(d))]
        if progress:
            progress(i + 1, n)
    secs = time.perf_counter() - t0
    cases = data["case"].values
    out = xr.Dataset(
        {"mse": (("case", "component"), ((pred - Y) ** 2).mean(1)),
         "mse_nearest": (("case", "component"), ((near - Y) ** 2).mean(1)),
         "predicted": (("case", coord, "component"), pred),
         "predicted_std": (("case", coord, "component"), pstd),
         "truth": (("case", coord, "component"), Y),
         "ranks": (("case", "mode"), ranks)},
        coords={"case": cases, coord: values, "component": comps, "mode": [1, 2, 3],
                **{nm: ("case", X[:, k]) for k, nm in enumerate(names)}})
    if baseline is not None:
        _, Yb, _, vb, _ = training_arrays(baseline, names, comps)
        if Yb.shape != Y.shape or not np.allclose(vb, values):
            raise InputError("baseline", f"must have the same cases and {coord} grid as the data")
        out["mse_baseline"] = (("case", "component"), ((Yb - Y) ** 2).mean(1))
        out["mse_baseline"].attrs["source"] = baseline.attrs.get("model", "baseline")
    out["mse"].attrs.update(units="N^2", long_name="leave-one-out mean square error of the surrogate")
    out["mse_nearest"].attrs.update(units="N^2", long_name="mean square error of the nearest training case")
    out.attrs.update(seconds=secs, inputs=",".join(names), data_model=data.attrs.get("model", ""),
                     note=data.attrs.get("dddas_note", ""))
    return out


def mse_table(cv: xr.Dataset):
    """The cross-validation errors as a pandas DataFrame, one row per held-out case."""
    import pandas as pd

    names = [n for n in cv.coords if n not in ("case", "component", "mode") and cv[n].dims == ("case",)]
    rows = []
    for i in range(cv.sizes["case"]):
        r = {n: float(cv[n].values[i]) for n in names}
        for c in cv["component"].values:
            r[f"mse_{c}"] = float(cv["mse"].sel(component=c).values[i])
            r[f"mse_nearest_{c}"] = float(cv["mse_nearest"].sel(component=c).values[i])
            if "mse_baseline" in cv:
                r[f"mse_baseline_{c}"] = float(cv["mse_baseline"].sel(component=c).values[i])
        r["D"] = int(cv["ranks"].values[i, 0])
        rows.append(r)
    return pd.DataFrame(rows)
