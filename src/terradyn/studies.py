"""The RFT studies of the brief (section 2), each writing datasets and figures to a folder.

Each study is a function ``<name>_study(out, ...) -> dict`` returning a JSON-able summary;
:func:`run_all` runs them all (the README's main job). Computation lives in
:mod:`terradyn.rft`; this module only arranges inputs, files and figures.
"""
from __future__ import annotations

import json
from importlib import resources
from pathlib import Path

import numpy as np
import pandas as pd
import xarray as xr

from . import io, models, plots
from .geometry import foot, make_leg
from .media import FITS, INTERPOLATOR_NAMES, generic, packaged_tables, stress_model
from .motion import Trajectory, foot_rotation, standard_rotation
from .rft import element_forces
from .rft.analysis import calibrate_zeta, curve_at, features, interpolator_holdout
from .series import stack
from .units import CM, DEG

LEGS = ("c", "flat", "reverse-c")


def _out(out) -> Path:
    p = Path(out)
    p.mkdir(parents=True, exist_ok=True)
    return p


def _write_json(path: Path, obj) -> None:
    io.atomic_write_text(path, json.dumps(obj, indent=2, sort_keys=True) + "\n")


def interp_study(out, map_medium: str = "3 mm glass CP") -> dict:
    """Hold-out comparison of the five grid interpolators and the Fourier fit, all media."""
    out = _out(out)
    ds = interpolator_holdout()
    io.write(ds, out / "interp_holdout.nc")
    plots.holdout_errors(ds, out / "interp_holdout.png")
    tabs = {m: packaged_tables(m)[map_medium] for m in ("linear", "nearest", "slinear", "cubic", "quintic")}
    models = {INTERPOLATOR_NAMES[m]: t for m, t in tabs.items()}
    models["Fourier fit"] = FITS[map_medium]
    plots.alpha_maps(models, out / "alpha_maps.png", title=f"{map_medium}: stress per depth")
    mean = ds.rmse.mean("medium")
    best = {c: str(mean.sel(component=c).idxmin("method").item()) for c in ("alpha_z", "alpha_x")}
    summary = {"rmse_N_per_cm3_mean_over_media": {
        m: {c: round(float(mean.sel({"method": m, "component": c})), 5) for c in ("alpha_z", "alpha_x")}
        for m in ds.method.values}, "best": best}
    _write_json(out / "interp_holdout.json", summary)
    return summary


def legs_study(out, medium: str = "3 mm glass CP", alpha: str = "table", interp: str = "linear",
               zeta: float | None = None, n_theta: int = 271, n_elements: int = 100,
               model: str = "rft") -> dict:
    """The three legs of the standard rotating-leg test, each alone and together (``model``:
    a registered model, :mod:`terradyn.models`)."""
    out = _out(out)
    opts = {"alpha": alpha, "zeta": zeta, "interp": interp if alpha == "table" else None}
    rot = standard_rotation(n_theta)
    series = {leg: models.simulate(model, make_leg(leg, n=n_elements), rot, medium, **opts) for leg in LEGS}
    for leg, ds in series.items():
        io.write(ds, out / f"rft_{leg}.nc")
        plots.forces({leg: ds}, out / f"rft_{leg}.png", title=f"RFT, {leg} leg, {medium} ({alpha})")
    both = stack(list(series.values()), {"leg": list(LEGS)})
    io.write(both, out / "rft_legs.nc")
    plots.forces(series, out / "rft_legs.png", title=f"RFT, three legs, {medium} ({alpha}"
                 + (f", {interp}" if alpha == "table" else "") + ")")
    feats = {leg: features(ds) for leg, ds in series.items()}
    _write_json(out / "rft_legs_features.json", feats)
    return {"medium": medium, "alpha": alpha, "features": feats}


def frames_study(out, medium: str = "3 mm glass CP", alpha: str = "table",
                 thetas_deg=(-90, -60, -30, 0, 30, 60), n_elements: int = 24) -> dict:
    """Snapshots of each leg at several angles with element force arrows; the element
    positions and forces go to ``frames.nc`` (dims leg, theta, element)."""
    out = _out(out)
    model = stress_model(medium, alpha)
    th = np.asarray(thetas_deg, float) * DEG
    h = 2.0 * CM
    z0 = np.zeros_like(th)
    traj = Trajectory(z0, z0, z0 + h, z0, z0, th, z0 + 0.2)
    data = {k: [] for k in ("x", "z", "fx", "fz")}
    for leg_name in LEGS:
        leg = make_leg(leg_name, n=n_elements)
        fx, fz, st = element_forces(leg.elements(), traj, model)
        for k, v in (("x", st.x), ("z", st.z), ("fx", fx), ("fz", fz)):
            data[k].append(v)
        plots.frames(leg, np.degrees(th), fx, fz, st.x, st.z, out / f"frames_{leg_name}.png",
                     title=f"{leg_name} leg in {medium}: element forces", hip_height=h)
    units = {"x": "m", "z": "m", "fx": "N", "fz": "N"}
    ds = xr.Dataset({k: (("leg", "theta", "element"), np.array(v), {"units": units[k]})
                     for k, v in data.items()},
                    coords={"leg": list(LEGS), "theta": ("theta", np.degrees(th), {"units": "deg"}),
                            "element": np.arange(n_elements)},
                    attrs={"medium": medium, "alpha": alpha, "hip_height_m": h,
                           "description": "element centres (world frame) and element forces"})
    io.write(ds, out / "frames.nc")
    return {"thetas_deg": list(map(float, thetas_deg))}


def foot_study(out, lengths_cm=tuple(range(25, 34)), medium: str = "poppy LP", alpha: str = "fit",
               max_deg: float = 3.0, n_theta: int = 61, width_cm: float = 8.5, model: str = "rft") -> dict:
    """Human-sized foot (thesis 2.4): forces against rotation for lengths 25-33 cm."""
    out = _out(out)
    rot = foot_rotation(max_deg, n_theta)
    series = [models.simulate(model, foot(L * CM, width_cm * CM), rot, medium, alpha=alpha)
              for L in lengths_cm]
    ds = stack(series, {"length_cm": np.asarray(lengths_cm, float)})
    io.write(ds, out / "rft_foot.nc")
    plots.foot_forces(ds, out / "rft_foot.png", title=f"RFT foot ({width_cm:g} cm wide) in {medium}")
    end = ds.isel(theta=-1)
    arm = (end.torque / end.Fz).values  # lever arm of the net vertical force about the ankle
    summary = {"length_cm": list(map(float, lengths_cm)),
               "Fz_at_max_N": end.Fz.values.round(4).tolist(),
               "Fx_at_max_N": end.Fx.values.round(4).tolist(),
               "resultant_from_ankle_cm": (np.abs(arm) / CM).round(3).tolist()}
    _write_json(out / "rft_foot.json", summary)
    return summary


def read_fig_s12() -> pd.DataFrame:
    """Li 2013 supplement Fig. S12: measured lift and thrust on the three legs in three sands."""
    ref = resources.files("terradyn") / "data" / "li2013_fig_s12_experiments.csv"
    with ref.open("r") as fh:
        return pd.read_csv(fh)


def experiment_study(out, n_elements: int = 100) -> dict:
    """RFT against the measured curves of Li 2013 Fig. S12: generic x zeta with one zeta per
    sand fitted by least squares (the sands' plate tests are not published), then MSE and
    peak differences per leg and component."""
    out = _out(out)
    df = read_fig_s12()
    th = np.linspace(-135, 135, 271) * DEG
    pred, meas, rows = {}, {}, []
    for med, d in df.groupby("medium"):
        z, se = calibrate_zeta(d, n_elements)
        for (leg, comp), e in d.groupby(["leg", "force"]):
            fx, fz = curve_at(make_leg(leg, n=n_elements), th, generic(z))
            pred[(med, leg, comp)] = (np.degrees(th), fz if comp == "Fz" else fx)
            meas[(med, leg, comp)] = (np.degrees(e.theta_rad.values), e.force_N.values)
            px, pz = curve_at(make_leg(leg, n=n_elements), e.theta_rad.values, generic(z))
            p = pz if comp == "Fz" else px
            m = e.force_N.values
            rows.append({"medium": med, "leg": leg, "component": comp, "zeta": z, "zeta_se": se,
                         "mse_N2": float(np.mean((p - m) ** 2)), "peak_measured_N": float(m.max()),
                         "peak_rft_N": float(np.max(pred[(med, leg, comp)][1])),
                         "peak_rel_diff": float(abs(np.max(pred[(med, leg, comp)][1]) - m.max()) / m.max())})
    tab = pd.DataFrame(rows)
    tab.to_csv(out / "rft_vs_li2013_s12.csv", index=False, float_format="%.5g")
    plots.model_vs_measured(pred, meas, out / "rft_vs_li2013_s12.png",
                            title="RFT (generic x fitted zeta) vs Li 2013 Fig. S12 measurements")
    mse = tab.groupby(["leg", "component"]).mse_N2.mean()
    return {"zeta": tab.groupby("medium").zeta.first().round(4).to_dict(),
            "mse_N2_mean_over_sands": {f"{leg} {c}": round(float(v), 3) for (leg, c), v in mse.items()}}


def dddas_foot_study(out, **kwargs) -> dict:
    """DDDAS on the human-sized foot (thesis 4): RFT lengths 25-35 cm, surrogate at 29 cm,
    assimilation of a synthetic trial's normal force. Writes to ``out/dddas_foot``."""
    from .dddas import studies as ds

    return ds.foot_study(Path(out) / "dddas_foot", **kwargs)


def dddas_legs_study(out, **kwargs) -> dict:
    """DDDAS on the three legs: surrogate, cross-validation and assimilation. On the shipped
    SPH training set ``datasets/sph_legs_speeds.nc`` (ten speeds per leg); where it cannot be
    found, on RFT-generated data (hip height varies; RFT is rate-independent), which every
    output then says (:func:`terradyn.dddas.studies.legs_study`). Writes to ``out/dddas_legs``."""
    from .dddas import studies as ds

    return ds.legs_study(Path(out) / "dddas_legs", **kwargs)


STUDIES = {"interp": interp_study, "legs": legs_study, "frames": frames_study,
           "foot": foot_study, "experiment": experiment_study, "dddas-foot": dddas_foot_study,
           "dddas-legs": dddas_legs_study}


def run_all(out, progress=None, quick: bool = False) -> dict:
    """Run every study into ``out``; ``progress(name)`` is called before each."""
    out = _out(out)
    summary = {}
    for name, fn in STUDIES.items():
        if progress:
            progress(name)
        kwargs = {}
        if quick and name == "legs":
            kwargs = {"n_theta": 91, "n_elements": 40}
        if quick and name == "dddas-legs":
            kwargs = {"n_theta": 91, "particles": 1000, "legs": ("flat",)}
        if quick and name == "dddas-foot":
            kwargs = {"particles": 1000}
        summary[name] = fn(out, **kwargs)
    _write_json(out / "summary.json", summary)
    return summary

