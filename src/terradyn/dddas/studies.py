"""The DDDAS studies of the brief (sec. 5): the three legs across ten conditions, and the
human-sized foot. Each writes datasets (NetCDF), tables (CSV), figures (PNG), a model file
per surrogate and a ``summary.json`` to an output folder, and returns the summary dict.

Data of the legs study: by default the shipped SPH training set ``datasets/sph_legs_speeds.nc``
(30 SPH runs: flat, C and reverse-C legs at omega = 0.2..1.1 rad/s), as in the thesis. It is
found next to the package in a source checkout, or in ``$TERRADYN_DATASETS``
(:func:`find_sph_dataset`). Where it cannot be found (e.g. an installed wheel without the
repository's ``datasets/`` folder) the study falls back to RFT-generated data and says so in
its messages, its saved metadata and its figures. ``data="rft"`` asks for RFT data explicitly.

Physics caveat (RFT data): RFT is quasi-static, so RFT forces at different angular speeds are
identical and a speed-conditioned surrogate trained on RFT would be degenerate. RFT data are
therefore an **RFT stand-in** whose condition is the hip height (which RFT resolves), not omega,
and every output says so.
"""
from __future__ import annotations

import json
import math
import os
import time
import warnings
from pathlib import Path
from typing import Callable

import numpy as np
import xarray as xr

from ..errors import InputError, integer, positive
from ..io import atomic_write_text, write_netcdf
from ..units import CM, DEG
from . import plots
from .crossval import cross_validate, mse_table
from .filter import warmup
from .online import Assimilation
from .surrogate import Surrogate, condition_names

#: Thesis-reported cross-validation MSE (N^2): below 0.05 for flat and reverse C, just
#: below 0.1 for the C-shaped leg (brief sec. 5).
REPORTED_CV_MSE = {"flat": 0.05, "reverse-c": 0.05, "c": 0.1}
LEGS = ("flat", "c", "reverse-c")
STANDIN_NOTE = ("RFT stand-in: RFT is quasi-static, so angular speed does not change its forces; "
                "the condition varied here is the hip height (cm), not omega. Not comparable "
                "one-to-one with the thesis's SPH speed study.")


#: The shipped SPH training set of the legs study (``datasets/README.md``).
SPH_DATASET = "sph_legs_speeds.nc"
#: Environment variable naming a folder that holds :data:`SPH_DATASET` (for installs without
#: the repository's ``datasets/`` folder).
DATASETS_ENV = "TERRADYN_DATASETS"
#: What ``data`` may say instead of a file: the default (shipped SPH data, else RFT with a
#: warning), the shipped SPH data (an error if missing), or RFT-generated data.
DATA_KEYWORDS = ("default", "sph", "rft")
RFT_LABEL = "RFT-generated stand-in"


def _say(progress, msg):
    if progress:
        progress(msg)


def dataset_dirs() -> list[Path]:
    """Folders searched for the shipped datasets, in order: ``$TERRADYN_DATASETS``, the
    package's ``data/`` folder, and ``datasets/`` of the source checkout the package lives in
    (the folder holding ``pyproject.toml`` and ``src/terradyn``)."""
    dirs = []
    env = os.environ.get(DATASETS_ENV, "").strip()
    if env:
        dirs.append(Path(env).expanduser())
    pkg = Path(__file__).resolve().parent.parent  # .../terradyn
    dirs.append(pkg / "data")
    root = pkg.parent.parent  # src/terradyn -> the repository root in a source checkout
    if pkg.parent.name == "src" and (root / "pyproject.toml").is_file():
        dirs.append(root / "datasets")
    return dirs


def find_sph_dataset() -> Path | None:
    """Path of the shipped SPH training set :data:`SPH_DATASET`, or None if not found in
    :func:`dataset_dirs`."""
    for d in dataset_dirs():
        p = d / SPH_DATASET
        if p.is_file():
            return p
    return None


def _keyword(v) -> str | None:
    if isinstance(v, str) and v.strip().lower() in DATA_KEYWORDS:
        return v.strip().lower()
    return None


def _rft_record(fallback_msg: str = "", why: str = "SPH dataset not found") -> dict:
    note = f"{fallback_msg} {STANDIN_NOTE}".strip() if fallback_msg else STANDIN_NOTE
    label = f"{RFT_LABEL}: {why}" if fallback_msg else RFT_LABEL
    return {"data": None, "source": "rft-standin", "label": label, "file": None,
            "fallback": bool(fallback_msg), "note": note}


def _short(model: str) -> str:
    return model.upper() if model.lower() in ("sph", "rft") else model


def _span(ds, name) -> str:
    v = np.asarray(ds[name].values, float)
    return f"{name} {v.min():g}..{v.max():g}"


def resolve_legs_data(data=None, legs=LEGS) -> tuple[dict, dict]:
    """Which data each leg of :func:`legs_study` uses, without running anything.

    ``data``: None or ``"default"`` (the shipped SPH set :data:`SPH_DATASET` if
    :func:`find_sph_dataset` finds it, else RFT-generated data, with a fallback message),
    ``"sph"`` (the shipped SPH set; an error if missing), ``"rft"`` (RFT-generated stand-in),
    a file or Dataset stacking all legs with a ``shape`` coordinate, or a mapping leg ->
    file / Dataset / keyword (key ``"all"`` for a file or keyword covering all legs); legs the
    mapping leaves out get the default.

    Returns ``(per_leg, info)``: per leg a dict with ``data`` (a Dataset, or None for the RFT
    stand-in generated by the study), ``source`` (``"sph"``, the data's ``model`` attribute,
    or ``"rft-standin"``), ``label`` (for titles), ``file``, ``fallback`` and ``note``; ``info``
    says what was asked, where the SPH set was found and whether the study fell back to RFT."""
    if not isinstance(data, dict):
        data = {} if data is None else {"all": data}
    data = dict(data)
    if not data:
        requested = "default"
    elif list(data) == ["all"]:
        requested = _keyword(data["all"]) or "file"
    else:
        requested = "per-leg"
    base = "default"
    if "all" in data and _keyword(data["all"]):
        base = _keyword(data.pop("all"))
    kw = {k: _keyword(v) for k, v in data.items() if _keyword(v)}
    files = {k: v for k, v in data.items() if k not in kw}
    unknown = [k for k in kw if k not in LEGS]
    if unknown:
        raise InputError("data", f"unknown leg(s) {unknown}; allowed: {', '.join(LEGS)}")
    all_file = files.get("all")
    given = split_by_leg(files)
    unknown = [k for k in given if k not in LEGS]
    if unknown:
        raise InputError("data", f"unknown leg(s) {unknown}; allowed: {', '.join(LEGS)}")
    wanted = {leg: kw.get(leg, base) for leg in legs if leg not in given}
    info = {"requested": requested, "sph_dataset": None,
            "fallback_to_rft": False, "message": ""}
    out = {}
    for leg in legs:
        if leg not in given:
            continue
        v = given[leg]
        f = v if isinstance(v, (str, Path)) else (all_file if isinstance(all_file, (str, Path)) else None)
        ds = _load(v)
        model = str(ds.attrs.get("model", "given"))
        name = _short(model)
        label = f"{name} data: {Path(f).name}" if f is not None else f"{name} data (given dataset)"
        out[leg] = {"data": ds, "source": model, "label": label, "file": str(f) if f is not None else None,
                    "fallback": False, "note": ds.attrs.get("dddas_note", f"{model} data given by the user"
                                                        + (f" ({Path(f).name})" if f is not None else ""))}
    sph = None
    if any(m in ("default", "sph") for m in wanted.values()):
        path = find_sph_dataset()
        info["sph_dataset"] = str(path) if path else None
        if path is None:
            where = ", ".join(str(d) for d in dataset_dirs())
            msg = (f"SPH training dataset {SPH_DATASET} not found (looked in {where}; e.g. an installed "
                   f"package without the repository's datasets/ folder): falling back to RFT-generated "
                   f"data. Set {DATASETS_ENV}=DIR or pass data=FILE (--data FILE) to use the SPH data.")
            if "sph" in wanted.values():
                raise InputError("data", msg.split(": falling back")[0])
            info.update(fallback_to_rft=True, message=msg)
        else:
            sph = split_by_leg(_load(path))
    for leg, mode in wanted.items():
        if mode == "rft":
            out[leg] = _rft_record()
        elif sph is None:
            out[leg] = _rft_record(info["message"])
        elif leg not in sph:
            if mode == "sph":
                raise InputError("data", f"{SPH_DATASET} has no '{leg}' leg (has {', '.join(sph)})")
            msg = f"{SPH_DATASET} has no '{leg}' leg: falling back to RFT-generated data."
            info.update(fallback_to_rft=True, message=(info["message"] + " " + msg).strip())
            out[leg] = _rft_record(msg, f"no {leg} leg in the SPH dataset")
        else:
            ds = sph[leg]
            speed = [n for n in ("omega", "omega_rad_s") if n in ds.coords]
            span = f", {_span(ds, speed[0])} rad/s" if speed else ""
            out[leg] = {"data": ds, "source": "sph", "label": f"SPH data: {SPH_DATASET}", "file": str(path),
                        "fallback": False,
                        "note": (f"SPH training data from the shipped {SPH_DATASET} ({ds.sizes['case']} runs of "
                                 f"the {leg} leg{span}), as in the thesis's speed study.")}
    return {leg: out[leg] for leg in legs}, info


def rft_standin(shape: str, hip_heights_cm=None, n_theta: int = 271, medium: str = "3 mm glass CP") -> xr.Dataset:
    """RFT force series of a standard leg at several hip heights (cm), stacked along ``case``
    with coordinate ``hip_height_cm``; attrs carry the stand-in note."""
    from .. import geometry, rft
    from ..media import stress_model
    from ..motion import standard_rotation, Rotation
    from ..series import stack

    hs = np.linspace(1.0, 3.25, 10) if hip_heights_cm is None else np.asarray(hip_heights_cm, float)
    leg = geometry.make_leg(shape)
    base = standard_rotation(n_theta)
    model = stress_model(medium)
    series = [rft.simulate(leg, Rotation(base.omega, h * CM, base.theta_start, base.theta_end, n_theta),
                           model, medium=medium) for h in hs]
    ds = stack(series, {"hip_height_cm": hs})
    ds.attrs["dddas_note"] = STANDIN_NOTE
    return ds


def _load(data) -> xr.Dataset:
    if isinstance(data, xr.Dataset):
        return data
    from .. import io

    return io.read(data)


def split_by_leg(data) -> dict:
    """``data`` as a mapping leg shape -> dataset. A dataset (or file) stacking several legs
    along ``case`` with a ``shape`` coordinate (what ``terradyn sweep collect`` writes for
    ``datasets/sph_legs_speeds.toml``), given alone or under the key ``"all"``, is split into
    one dataset per leg."""
    if data is None:
        return {}
    if not isinstance(data, dict):
        data = {"all": data}
    data = dict(data)
    if "all" not in data:
        return data
    ds = _load(data.pop("all"))
    if "shape" not in ds.coords or "case" not in ds["shape"].dims:
        raise InputError("data", "a dataset for all legs needs a 'shape' coordinate along 'case' "
                                 "(as written by `terradyn sweep collect`); else give LEG=FILE")
    shapes = [str(v) for v in ds["shape"].values]
    for shape in dict.fromkeys(shapes):
        if shape not in data:
            part = ds.isel(case=[i for i, v in enumerate(shapes) if v == shape]).drop_vars("shape")
            data[shape] = part.assign_coords(case=np.arange(part.sizes["case"]))
    return data


def _assimilation_run(sur: Surrogate, cond: dict, obs: xr.Dataset, obs_std: dict, particles: int,
                      seed: int, resample: str = "systematic", prior_floor: float = 1.0,
                      jitter_floor: float = 0.0, move_sweeps: int = 0):
    """Assimilate ``obs`` with the particle filter and the exact posterior; returns the two
    posterior series, the prior, the ESS trace and the mean time per PF update."""
    coord = sur.coord_
    moving = {"move_sweeps": move_sweeps, "jitter": 0.0} if move_sweeps else {}
    pf = Assimilation(sur, cond, obs_std, "pf", prior_floor=prior_floor, n_particles=particles, rng=seed,
                      resample=resample, jitter_floor=0.0 if move_sweeps else jitter_floor, **moving)
    ex = Assimilation(sur, cond, obs_std, "exact", prior_floor=prior_floor)
    warmup()  # compile / load the kernels outside the timed loop
    prior = pf.prediction()
    x = obs[coord].values
    vals = {c: obs[c].values if c in obs else np.full(len(x), np.nan) for c in ("Fx", "Fz")}
    ess = np.empty(len(x))
    t0 = time.perf_counter()
    for i in range(len(x)):
        ess[i] = pf.update(x[i], vals["Fx"][i], vals["Fz"][i])
    t_pf = (time.perf_counter() - t0) / max(len(x), 1)
    for i in range(len(x)):
        ex.update(x[i], vals["Fx"][i], vals["Fz"][i])
    return prior, pf.prediction(), ex.prediction(), ess, t_pf, pf.post.n_resamples


_LEG_TITLE = {"flat": "Flat", "c": "C", "reverse-c": "Reverse-C"}


def _cond_text(cond: dict) -> str:
    """An operating condition for a figure title: omega_rad_s=0.7 -> 'omega = 0.7 rad/s'."""
    units = {"_rad_s": "rad/s", "_cm": "cm", "_deg": "deg", "_m": "m"}
    parts = []
    for k, v in cond.items():
        suffix = next((u for u in units if k.endswith(u)), "")
        name = k[:len(k) - len(suffix)].replace("_", " ")
        parts.append(f"{name} = {v:g} {units.get(suffix, '')}".rstrip())
    return ", ".join(parts)


def _mse(a: xr.Dataset, b: xr.Dataset, v: str) -> float:
    from ..compare import mse_values

    return mse_values(a[v].values, b[v].values)


def legs_study(out: str | Path, data=None, legs=LEGS, noise: float = 0.05,
               particles: int = 5000, seed: int = 0, energy: float = 0.95, test_case: int | None = None,
               n_theta: int = 271, obs_every: int = 1, jitter_floor: float = 0.01, move_sweeps: int = 1,
               progress: Callable[[str], None] | None = None) -> dict:
    """Surrogate, cross-validation and assimilation for the three legs.

    ``data`` (see :func:`resolve_legs_data`): None (default) for the shipped SPH training set
    :data:`SPH_DATASET` (ten speeds per leg, coordinate ``omega_rad_s``), falling back to the
    RFT stand-in (:func:`rft_standin`, hip height 1.0-3.25 cm, ``n_theta`` angles) with a
    warning where it cannot be found; ``"sph"`` or ``"rft"`` to insist on one; a file or
    Dataset stacking all legs with a ``shape`` coordinate; or a mapping leg -> file / Dataset
    / keyword. Each output names its data (summary ``data`` and per leg ``source``,
    ``data_label``, ``data_file``, ``note``; attrs ``dddas_source``, ``dddas_data``,
    ``dddas_note`` of the NetCDF files; figure titles). ``noise``: Gaussian observation
    noise std as a fraction of the test case's RMS force per component; ``test_case``: index of
    the held-out case to assimilate (default: the middle one); ``obs_every``: assimilate every
    k-th sample; ``jitter_floor``: the particle filter's process noise (fraction of the prior
    std; see :class:`ParticleFilter`; used only without moves); ``move_sweeps``: resample-move
    sweeps of the particle filter (Gilks & Berzuini 2001; 0: the thesis's filter). Writes per leg ``<leg>_data.nc``, ``<leg>_model.nc``, ``<leg>_cv.nc``,
    ``<leg>_cv.csv``, ``<leg>_posterior_pf.nc``, ``<leg>_posterior_exact.nc`` and figures."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    noise = positive("noise", noise)
    obs_every = integer("obs-every", obs_every, 1)
    resolved, info = resolve_legs_data(data, legs)
    if info["fallback_to_rft"]:
        _say(progress, f"WARNING: {info['message']}")
        if not progress:
            warnings.warn(info["message"], UserWarning, stacklevel=2)
    rng = np.random.default_rng(seed)
    summary = {"study": "dddas-legs", "data": info, "legs": {}, "reported_cv_mse_N2": REPORTED_CV_MSE,
               "noise_fraction": noise, "particles": particles, "seed": seed, "jitter_floor": jitter_floor,
               "move_sweeps": move_sweeps}
    from .. import io

    def tag(d: xr.Dataset) -> xr.Dataset:
        d.attrs.update(dddas_source=source, dddas_data=label, dddas_note=note)
        if rec["file"]:
            d.attrs["dddas_data_file"] = Path(rec["file"]).name
        return d

    for shape in legs:
        t0 = time.perf_counter()
        rec = resolved[shape]
        source, label, note = rec["source"], rec["label"], rec["note"]
        if rec["data"] is not None:
            ds = rec["data"].copy()
            _say(progress, f"{shape}: {label}" + (f" ({rec['file']})" if rec["file"] else ""))
        else:
            _say(progress, f"{shape}: {label} (hip height varies, not omega; see note)")
            ds = rft_standin(shape, n_theta=n_theta)
        tag(ds)
        names = condition_names(ds)
        # speed first: 'omega' (hand-made stacks) or 'omega_rad_s' (sweep collect)
        speed = [n for n in ("omega", "omega_rad_s") if n in names]
        inputs = speed[:1] if speed else names[:1]
        if not inputs:
            raise InputError("data", f"{shape}: no numeric condition coordinate along 'case'")
        est = Surrogate(inputs=inputs, energy=energy, random_state=seed)
        io.write(ds, out / f"{shape}_data.nc")
        sur = est.fit(ds)
        sur.save(out / f"{shape}_model.nc")
        plots.explained_variance(sur, out / f"{shape}_explained_variance.png",
                                 f"{shape} leg: HOSVD explained variance ({label})")
        _say(progress, f"{shape}: cross-validation over {ds.sizes['case']} conditions")
        cv = cross_validate(ds, Surrogate(inputs=inputs, energy=energy, random_state=seed))
        io_cv = cv.copy()
        io_cv.attrs["note"] = note
        tag(io_cv)
        write_netcdf(io_cv, out / f"{shape}_cv.nc")
        mse_table(cv).to_csv(out / f"{shape}_cv.csv", index=False)
        plots.cv_errors(cv, out / f"{shape}_cv.png", f"{shape} leg: leave-one-out CV ({label})",
                        REPORTED_CV_MSE.get(shape))
        # Assimilation on the held-out test case.
        n = ds.sizes["case"]
        k = n // 2 if test_case is None else integer("test-case", test_case, 0)
        if k >= n:
            raise InputError("test-case", f"must be < {n}")
        train = ds.isel(case=np.arange(n) != k)
        sur_k = Surrogate(inputs=inputs, energy=energy, random_state=seed).fit(train)
        truth = ds.isel(case=k)
        cond = {nm: float(truth[nm].values) for nm in inputs}
        coord = sur_k.coord_
        sel = np.arange(0, truth.sizes[coord], obs_every)
        obs_std = {}
        obs = xr.Dataset(coords={coord: truth[coord].values[sel]})
        for v in ("Fx", "Fz"):
            sd = noise * float(np.sqrt(np.mean(truth[v].values ** 2)))
            obs_std[v] = max(sd, 1e-6)
            obs[v] = (coord, truth[v].values[sel] + obs_std[v] * rng.standard_normal(len(sel)))
        _say(progress, f"{shape}: assimilating {len(sel)} noisy samples of case {k} ({cond})")
        prior, post_pf, post_ex, ess, t_pf, n_res = _assimilation_run(sur_k, cond, obs, obs_std, particles, seed,
                                                                      jitter_floor=jitter_floor,
                                                                      move_sweeps=move_sweeps)
        io.write(tag(post_pf), out / f"{shape}_posterior_pf.nc")
        io.write(tag(post_ex), out / f"{shape}_posterior_exact.nc")
        write_netcdf(tag(obs), out / f"{shape}_observations.nc")
        plots.prediction(post_pf, out / f"{shape}_assimilation.png", truth=truth, observations=obs, prior=prior,
                         truth_label=f"held-out case (truth, {'RFT' if rec['data'] is None else _short(source)})",
                         title=f"{_LEG_TITLE.get(shape, shape)} leg, held out: {_cond_text(cond)}; "
                               f"particle filter posterior ({label})")
        plots.ess_trace(ess, obs[coord].values, out / f"{shape}_ess.png", particles, plots._xlabel(coord),
                        f"{shape} leg: particle filter ESS ({label})")
        cvm = {c: float(cv["mse"].sel(component=c).mean()) for c in cv["component"].values}
        summary["legs"][shape] = {
            "source": source, "data_label": label, "data_file": rec["file"], "fallback_to_rft": rec["fallback"],
            "note": note, "inputs": inputs, "n_conditions": int(n),
            "conditions": {nm: ds[nm].values.tolist() for nm in inputs},
            "ranks": list(map(int, sur.ranks_)),
            "cv_mse_mean_N2": cvm,
            "cv_mse_max_N2": {c: float(cv["mse"].sel(component=c).max()) for c in cv["component"].values},
            "cv_mse_nearest_mean_N2": {c: float(cv["mse_nearest"].sel(component=c).mean()) for c in cv["component"].values},
            "cv_seconds": float(cv.attrs["seconds"]),
            "reported_cv_mse_N2": REPORTED_CV_MSE[shape],
            "assimilation": {
                "test_case": int(k), "condition": cond, "samples": int(len(sel)), "obs_std_N": obs_std,
                "mse_prior_N2": {v: _mse(prior, truth, v) for v in ("Fx", "Fz")},
                "mse_pf_N2": {v: _mse(post_pf, truth, v) for v in ("Fx", "Fz")},
                "mse_exact_N2": {v: _mse(post_ex, truth, v) for v in ("Fx", "Fz")},
                "pf_us_per_sample": t_pf * 1e6, "resamples": int(n_res),
                "ess_min": float(ess.min())},
            "seconds": time.perf_counter() - t0}
    atomic_write_text(out / "summary.json", json.dumps(summary, indent=2, default=float))
    return summary


def foot_study(out: str | Path, lengths_cm=None, test_cm: float = 29.0, max_deg: float = 3.0,
               n_theta: int = 61, medium: str = "poppy LP", trial=None, trial_length_cm: float = 27.0,
               particles: int = 5000, seed: int = 0, energy: float = 0.95, cutoff_hz: float = 10.0,
               jitter_floor: float = 0.01, progress: Callable[[str], None] | None = None) -> dict:
    """Human-sized foot: RFT data for lengths 25-35 cm (test length held out), surrogate at
    ``test_cm``, and assimilation of a trial's normal force.

    ``trial``: a trial file/Dataset (:func:`terradyn.experiment.read_trial`); default a
    SYNTHETIC trial (commanded 12 deg, reached ~2.6 deg) from an RFT foot of nominal length
    ``trial_length_cm`` plus noise, bias and lag. The sensor offset is removed with the mean
    of the samples before the foot moves; the raw normal force is assimilated (Fz only, as in
    the experiments) with the noise level estimated from the data; the particle filter uses
    process noise ``jitter_floor`` (fraction of the prior std) so that early samples, which
    carry the sensor's offset error relative to small forces, cannot pin it."""
    from .. import experiment as ex
    from .. import geometry, io, rft
    from ..media import ZETA, stress_model
    from ..motion import foot_rotation
    from ..series import stack

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    Ls = np.arange(25.0, 35.0 + 1e-9, 1.0) if lengths_cm is None else np.asarray(lengths_cm, float)
    test_cm = positive("test-length", test_cm, "cm")
    model = stress_model(medium, alpha="generic", zeta=ZETA.get(medium, 1.0)) if medium in ZETA else stress_model(medium)
    motion = foot_rotation(max_deg, n_theta)

    def sim(L):
        return rft.simulate(geometry.foot(L * CM), motion, model, medium=medium)

    _say(progress, f"foot: RFT for lengths {Ls.min():g}-{Ls.max():g} cm")
    train_L = Ls[np.abs(Ls - test_cm) > 1e-9]
    ds = stack([sim(L) for L in train_L], {"length_cm": train_L})
    ds.attrs["dddas_note"] = f"RFT foot, {medium}, lengths {train_L.tolist()} cm; {test_cm:g} cm held out"
    io.write(ds, out / "foot_data.nc")
    sur = Surrogate(inputs=["length_cm"], energy=energy, random_state=seed).fit(ds)
    sur.save(out / "foot_model.nc")
    plots.explained_variance(sur, out / "foot_explained_variance.png", "foot: HOSVD explained variance")
    cv = cross_validate(ds, Surrogate(inputs=["length_cm"], energy=energy, random_state=seed))
    mse_table(cv).to_csv(out / "foot_cv.csv", index=False)
    write_netcdf(cv, out / "foot_cv.nc")
    plots.cv_errors(cv, out / "foot_cv.png", "foot: leave-one-length-out CV (RFT data)")
    truth_test = sim(test_cm)
    pred = sur.predict({"length_cm": test_cm})
    io.write(pred, out / "foot_surrogate_29cm.nc" if test_cm == 29 else out / f"foot_surrogate_{test_cm:g}cm.nc")
    plots.prediction(pred, out / "foot_surrogate.png", truth=truth_test, truth_label=f"RFT {test_cm:g} cm (held out)",
                     title=f"foot surrogate at {test_cm:g} cm vs RFT (held out)")
    # The trial.
    if trial is None:
        tr = ex.synthetic_trial(12.0, length=trial_length_cm * CM, medium=medium, seed=seed)
        trial_src = "synthetic"
    else:
        tr = trial if isinstance(trial, xr.Dataset) else ex.read_trial(trial)
        trial_src = "synthetic" if int(tr.attrs.get("synthetic", 0)) else str(tr.attrs.get("source", "file"))
    ex.write_trial(tr, out / "foot_trial.csv")
    cmpd = ex.compare(tr, test_cm * CM, medium=medium, cutoff_hz=cutoff_hz)
    plots.trial_comparison(cmpd, out / "foot_trial_vs_rft.png", f"trial vs RFT foot {test_cm:g} cm")
    a = tr["angle"].values
    still = a < 0.02 * max(float(a.max()), 1e-9)
    offset = float(tr["normal_force"].values[still].mean()) if still.sum() >= 5 else 0.0
    fs = ex.sampling_rate(tr)
    raw = tr["normal_force"].values
    noise = float(np.std(raw - ex.butter_lowpass(raw, fs, min(fs / 20, 0.45 * fs))))
    tr_c = tr.copy()
    tr_c["normal_force"] = tr["normal_force"] - offset
    obs = ex.to_force_series(tr_c)
    obs = obs.where((obs.theta >= sur.coord_values_.min()) & (obs.theta <= sur.coord_values_.max()), drop=True)
    if obs.sizes["theta"] < 2:
        raise InputError("trial", "its angles do not overlap the surrogate's theta range")
    _say(progress, f"foot: assimilating {obs.sizes['theta']} normal-force samples (noise {noise:.3g} N)")
    prior, post_pf, post_ex, ess, t_pf, n_res = _assimilation_run(sur, {"length_cm": test_cm}, obs,
                                                                  {"Fz": noise, "Fx": noise}, particles, seed,
                                                                  jitter_floor=jitter_floor)
    io.write(post_pf, out / "foot_posterior_pf.nc")
    io.write(post_ex, out / "foot_posterior_exact.nc")
    truth_trial = None
    summary_truth = {}
    if trial is None:
        truth_trial = sim(trial_length_cm)
        summary_truth = {"trial_truth_length_cm": trial_length_cm,
                         "mse_vs_trial_truth_N2": {
                             "prior": {v: _mse(prior, truth_trial, v) for v in ("Fx", "Fz")},
                             "pf": {v: _mse(post_pf, truth_trial, v) for v in ("Fx", "Fz")},
                             "exact": {v: _mse(post_ex, truth_trial, v) for v in ("Fx", "Fz")}}}
    plots.prediction(post_pf, out / "foot_assimilation.png", truth=truth_trial, observations=obs, prior=prior,
                     truth_label=f"trial's truth (RFT, {trial_length_cm:g} cm foot)",
                     title=f"foot {test_cm:g} cm: assimilating the {trial_src} trial's normal force")
    plots.ess_trace(ess, obs["theta"].values, out / "foot_ess.png", particles, "foot angle theta (deg)")
    summary = {
        "study": "dddas-foot", "medium": medium, "particles": particles, "jitter_floor": jitter_floor, "train_lengths_cm": train_L.tolist(), "test_cm": test_cm,
        "ranks": list(map(int, sur.ranks_)),
        "cv_mse_mean_N2": {c: float(cv["mse"].sel(component=c).mean()) for c in cv["component"].values},
        "surrogate_vs_rft_at_test_N2": {v: _mse(pred, truth_test, v) for v in ("Fx", "Fz")},
        "surrogate_peak_Fz_N": float(pred["Fz"].max()), "rft_peak_Fz_N": float(truth_test["Fz"].max()),
        "trial": trial_src, "trial_offset_removed_N": offset, "trial_noise_N": noise,
        "trial_vs_rft": {k: v for k, v in cmpd.attrs.items() if k.endswith(("_mse", "_difference"))},
        "samples_assimilated": int(obs.sizes["theta"]), "pf_us_per_sample": t_pf * 1e6,
        "resamples": int(n_res), "ess_min": float(ess.min()), **summary_truth}
    atomic_write_text(out / "summary_foot.json", json.dumps(summary, indent=2, default=float))
    return summary


#: Estimators of :func:`speed_study`: the surrogate alone, the present particle filter
#: (thesis setting: jitter + 1 % process noise), the particle filter with resample-move
#: (Gilks & Berzuini 2001) and the exact Gaussian posterior.
SPEED_METHODS = ("prior", "pf", "pf_move", "exact")


def speed_study(out: str | Path | None = None, data=None, legs=LEGS, seeds=(0, 1), noise: float = 0.05,
                particles: int = 5000, energy: float = 0.95, forecast_at: float = 0.3,
                progress: Callable[[str], None] | None = None) -> dict:
    """The thesis's speed study over every held-out condition (ten speeds per leg on the
    shipped SPH set; see :func:`resolve_legs_data` for ``data``) and several noise seeds.
    For each held-out case a surrogate is fitted on the others and the case is observed with
    Gaussian noise (``noise`` x its RMS per component). Two scores against the held-out
    curve: ``assimilation`` (all samples assimilated, the thesis's score) and ``forecast``
    (the first ``forecast_at`` of the samples assimilated, the rest predicted). Estimators:
    :data:`SPEED_METHODS`. Returns (and writes ``speed_study.json`` to ``out``) the mean MSE
    per leg, score, estimator and component, and whether each filter is never worse than
    the prior on average."""
    noise = positive("noise", noise)
    forecast_at = float(forecast_at)
    if not 0 < forecast_at < 1:
        raise InputError("forecast-at", f"must be in (0, 1), got {forecast_at!r}")
    resolved, info = resolve_legs_data(data, legs)
    warmup()
    result = {"study": "dddas-speed", "data": info, "noise_fraction": noise, "seeds": list(seeds),
              "particles": particles, "forecast_at": forecast_at, "legs": {}}
    for shape in legs:
        t0 = time.perf_counter()
        rec = resolved[shape]
        ds = rec["data"] if rec["data"] is not None else rft_standin(shape)
        names = condition_names(ds)
        speed = [n for n in ("omega", "omega_rad_s") if n in names]
        inputs = speed[:1] if speed else names[:1]
        n = ds.sizes["case"]
        comps = ("Fx", "Fz")
        mse = {sc: {m: {c: [] for c in comps} for m in SPEED_METHODS} for sc in ("assimilation", "forecast")}
        for k in range(n):
            sur = Surrogate(inputs=inputs, energy=energy, random_state=0).fit(ds.isel(case=np.arange(n) != k))
            truth = ds.isel(case=k)
            cond = {nm: float(truth[nm].values) for nm in inputs}
            coord = sur.coord_
            x = truth[coord].values
            cut = int(round(forecast_at * len(x)))
            for seed in seeds:
                rng = np.random.default_rng([seed, k])
                sd = {c: max(noise * float(np.sqrt(np.mean(truth[c].values ** 2))), 1e-6) for c in comps}
                y = {c: truth[c].values + sd[c] * rng.standard_normal(len(x)) for c in comps}
                runs = {"pf": Assimilation(sur, cond, sd, "pf", prior_floor=1.0, n_particles=particles, rng=seed,
                                           jitter_floor=0.01),
                        "pf_move": Assimilation(sur, cond, sd, "pf", prior_floor=1.0, n_particles=particles,
                                                rng=seed, jitter=0.0, move_sweeps=1),
                        "exact": Assimilation(sur, cond, sd, "exact", prior_floor=1.0)}
                prior = runs["exact"].prediction()
                fc = {}
                for i in range(len(x)):
                    if i == cut:
                        fc = {m: a.prediction() for m, a in runs.items()}
                    for a in runs.values():
                        a.update(x[i], y["Fx"][i], y["Fz"][i])
                post = {m: a.prediction() for m, a in runs.items()}
                fc["prior"] = post["prior"] = prior
                for m in SPEED_METHODS:
                    for c in comps:
                        t = truth[c].values
                        mse["assimilation"][m][c].append(float(np.mean((post[m][c].values - t) ** 2)))
                        mse["forecast"][m][c].append(float(np.mean((fc[m][c].values[cut:] - t[cut:]) ** 2)))
        mean = {sc: {m: {c: float(np.mean(v)) for c, v in d.items()} for m, d in s.items()} for sc, s in mse.items()}
        never_worse = {sc: {m: all(mean[sc][m][c] <= mean[sc]["prior"][c] for c in comps)
                            for m in ("pf", "pf_move", "exact")} for sc in mse}
        held = {nm: [float(v) for v in np.atleast_1d(ds[nm].values)] for nm in inputs}
        ratio = {sc: {m: {c: mean[sc][m][c] / mean[sc]["prior"][c] for c in comps} for m in ("pf", "pf_move", "exact")}
                 for sc in mse}
        result["legs"][shape] = {"source": rec["source"], "data_label": rec["label"], "inputs": inputs,
                                 "held_out_cases": int(n), "held_out": held, "mse_mean_N2": mean,
                                 "mean_over_prior": ratio, "never_worse_than_prior": never_worse,
                                 "mse_N2": mse, "seconds": time.perf_counter() - t0}
        _say(progress, f"{shape}: " + "; ".join(
            f"{sc} MSE Fx/Fz prior {mean[sc]['prior']['Fx']:.4f}/{mean[sc]['prior']['Fz']:.4f}, pf "
            f"{mean[sc]['pf']['Fx']:.4f}/{mean[sc]['pf']['Fz']:.4f}, pf+move {mean[sc]['pf_move']['Fx']:.4f}/"
            f"{mean[sc]['pf_move']['Fz']:.4f}, exact {mean[sc]['exact']['Fx']:.4f}/{mean[sc]['exact']['Fz']:.4f}"
            for sc in mse))
    if out is not None:
        from ..io import atomic_write_text

        Path(out).mkdir(parents=True, exist_ok=True)
        atomic_write_text(Path(out) / "speed_study.json", json.dumps(result, indent=2))
        plots.speed_study(result, Path(out) / "speed_study.png")
    return result
