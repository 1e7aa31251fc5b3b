"""RFT analyses behind the studies: interpolator hold-out comparison, qualitative features of
force curves, calibration of zeta to measured curves. Pure computation (no files, no plots)."""
from __future__ import annotations

import numpy as np
import pandas as pd
import xarray as xr

from ..errors import InputError
from ..geometry import Leg, make_leg
from ..media import FITS, INTERPOLATORS, StressTable, generic, packaged_tables
from ..motion import Trajectory
from .engine import net_forces


def interpolator_holdout(tables: dict[str, StressTable] | None = None,
                         methods=INTERPOLATORS, include_fit: bool = True) -> xr.Dataset:
    """Leave-one-line-out comparison of the grid interpolators (and the Fourier fit).

    For every interior grid line (each interior beta row and each interior gamma column) the
    line is removed, every interpolator is rebuilt on the remaining (still regular) grid and
    predicts the removed values. Returns RMSE (N/cm^3) with dims (medium, method, component).
    The Fourier fit was fitted by Li et al. to all the data, held-out points included, so its
    error is an in-sample error (an advantage it keeps here).
    """
    tables = tables or packaged_tables()
    names = list(methods) + (["fit"] if include_fit else [])
    rmse = np.full((len(tables), len(names), 2), np.nan)
    npts = np.zeros(len(tables), int)
    for im, (med, t) in enumerate(tables.items()):
        errs = {m: [] for m in names}
        for axis, n in ((0, len(t.beta)), (1, len(t.gamma))):
            for k in range(1, n - 1):
                keep = np.arange(n) != k
                b = t.beta[keep] if axis == 0 else t.beta
                g = t.gamma[keep] if axis == 1 else t.gamma
                az = np.compress(keep, t.alpha_z, axis=axis)
                ax = np.compress(keep, t.alpha_x, axis=axis)
                qb, qg = (np.full(len(t.gamma), t.beta[k]), t.gamma) if axis == 0 else \
                    (t.beta, np.full(len(t.beta), t.gamma[k]))
                truth_z = np.take(t.alpha_z, k, axis=axis)
                truth_x = np.take(t.alpha_x, k, axis=axis)
                for m in names:
                    if m == "fit":
                        if med not in FITS:
                            continue
                        px, pz = FITS[med].alpha(qb, qg)
                    else:
                        need = {"cubic": 4, "quintic": 6}.get(m, 2)
                        if min(len(b), len(g)) < need:
                            continue
                        sub = StressTable(med, b, g, az, ax, m)
                        px, pz = sub.alpha(qb, qg)
                    errs[m].append(np.stack([px - truth_x, pz - truth_z], -1))
        for j, m in enumerate(names):
            if errs[m]:
                e = np.concatenate(errs[m]) / 1e6  # N/m^3 -> N/cm^3
                rmse[im, j] = np.sqrt((e ** 2).mean(0))
                npts[im] = len(e)
    return xr.Dataset(
        {"rmse": (("medium", "method", "component"), rmse, {"units": "N/cm^3",
                  "long_name": "hold-out RMS error of alpha"}),
         "n_points": ("medium", npts)},
        coords={"medium": list(tables), "method": names, "component": ["alpha_x", "alpha_z"]},
        attrs={"protocol": "leave-one-grid-line-out (interior beta rows and gamma columns)",
               "source": "Li, Zhang & Goldman 2013, supplement Table S5 (measured), Table S2 (fit)"})


def features(ds: xr.Dataset) -> dict:
    """Qualitative features of a rotating-leg force series (theta in deg): peak lift and where,
    peak lift in intrusion and in extraction, peak thrust, most negative lift (suction) and
    the theta span over which lift is negative."""
    th = ds["theta"].values
    fz, fx = ds["Fz"].values, ds["Fx"].values
    intr, extr = th < 0, th > 0
    neg = fz < -1e-3 * max(abs(fz).max(), 1e-12)
    dth = np.abs(np.gradient(th))
    return {
        "peak_lift_N": float(fz.max()), "peak_lift_theta_deg": float(th[fz.argmax()]),
        "peak_lift_intrusion_N": float(fz[intr].max()) if intr.any() else 0.0,
        "peak_lift_extraction_N": float(fz[extr].max()) if extr.any() else 0.0,
        "peak_thrust_N": float(fx.max()), "peak_thrust_theta_deg": float(th[fx.argmax()]),
        "min_lift_N": float(fz.min()), "suction_span_deg": float(dth[neg].sum()),
    }


def calibrate_zeta(measured: pd.DataFrame, n_elements: int = 100, hip_height: float = 0.02,
                   omega: float = 0.2) -> tuple[float, float]:
    """Least-squares zeta for generic x zeta against measured rotating-leg curves.

    ``measured``: rows with columns leg, force ('Fx'/'Fz'), theta_rad, force_N. Forces are
    linear in zeta, so the fit is closed-form: zeta = <p, m> / <p, p>, with its standard error
    from the residuals. Returns (zeta, standard error).
    """
    p, m = [], []
    for (leg, force), d in measured.groupby(["leg", "force"]):
        fx, fz = curve_at(make_leg(leg, n=n_elements), d["theta_rad"].values, generic(1.0),
                          hip_height, omega)
        p.append(fz if force == "Fz" else fx)
        m.append(d["force_N"].values)
    p, m = np.concatenate(p), np.concatenate(m)
    if not (p @ p) > 0:
        raise InputError("measured", "the model predicts no force at the measured angles")
    z = float(p @ m / (p @ p))
    dof = max(len(m) - 1, 1)
    se = float(np.sqrt(((m - z * p) ** 2).sum() / dof / (p @ p)))
    return z, se


def curve_at(leg: Leg, theta_rad: np.ndarray, model, hip_height: float = 0.02, omega: float = 0.2):
    """(Fx, Fz) of a leg rotating about a fixed hip, at arbitrary angles theta_rad (any order)."""
    th = np.asarray(theta_rad, dtype=float)
    z = np.zeros_like(th)
    traj = Trajectory(time=z, hip_x=z, hip_z=z + hip_height, hip_vx=z, hip_vz=z, angle=th,
                      angular_velocity=z + omega)
    fx, fz, _ = net_forces(leg, traj, model)
    return fx, fz
