"""The DDDAS studies of the brief (sec. 5): the three legs across ten conditions, and the
human-sized foot. Each writes datasets (NetCDF), tables (CSV), figures (PNG), a model file
per surrogate and a ``summary.json`` to an output folder, and returns the summary dict.

Physics caveat (legs study): RFT is quasi-static, so RFT forces at different angular speeds
are identical and a speed-conditioned surrogate trained on RFT would be degenerate. Without
SPH data the legs study therefore runs on an **RFT stand-in** whose condition is the hip
height (which RFT resolves), not omega, and says so in every output. Given stacked datasets
(e.g. SPH at omega = 0.2..1.1 rad/s, a ``case`` dimension with an ``omega`` coordinate) it
runs on those exactly as the thesis did.
"""
from __future__ import annotations

import json
import math
import time
from pathlib import Path
from typing import Callable

import numpy as np
import xarray as xr

from ..errors import InputError, integer, positive
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


def _say(progress, msg):
    if progress:
        progress(msg)


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
                      jitter_floor: float = 0.0):
    """Assimilate ``obs`` with the particle filter and the exact posterior; returns the two
    posterior series, the prior, the ESS trace and the mean time per PF update."""
    coord = sur.coord_
    pf = Assimilation(sur, cond, obs_std, "pf", prior_floor=prior_floor, n_particles=particles, rng=seed,
                      resample=resample, jitter_floor=jitter_floor)
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


def _mse(a: xr.Dataset, b: xr.Dataset, v: str) -> float:
    return float(np.mean((a[v].values - b[v].values) ** 2))


def legs_study(out: str | Path, data: dict | None = None, legs=LEGS, noise: float = 0.05,
               particles: int = 5000, seed: int = 0, energy: float = 0.95, test_case: int | None = None,
               n_theta: int = 271, obs_every: int = 1, jitter_floor: float = 0.01,
               progress: Callable[[str], None] | None = None) -> dict:
    """Surrogate, cross-validation and assimilation for the three legs.

    ``data``: optional mapping leg shape -> stacked dataset (or file) with conditions along
    ``case`` (SPH at ten speeds, coordinate ``omega``); legs without data use the RFT
    stand-in (:func:`rft_standin`, hip height 1.0-3.25 cm). ``noise``: Gaussian observation
    noise std as a fraction of the test case's RMS force per component; ``test_case``: index of
    the held-out case to assimilate (default: the middle one); ``obs_every``: assimilate every
    k-th sample; ``jitter_floor``: the particle filter's process noise (fraction of the prior
    std; see :class:`ParticleFilter`). Writes per leg ``<leg>_data.nc``, ``<leg>_model.nc``, ``<leg>_cv.nc``,
    ``<leg>_cv.csv``, ``<leg>_posterior_pf.nc``, ``<leg>_posterior_exact.nc`` and figures."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    noise = positive("noise", noise)
    obs_every = integer("obs-every", obs_every, 1)
    data = split_by_leg(data)
    unknown = [k for k in data if k not in LEGS]
    if unknown:
        raise InputError("data", f"unknown leg(s) {unknown}; allowed: {', '.join(LEGS)}")
    rng = np.random.default_rng(seed)
    summary = {"study": "dddas-legs", "legs": {}, "reported_cv_mse_N2": REPORTED_CV_MSE,
               "noise_fraction": noise, "particles": particles, "seed": seed, "jitter_floor": jitter_floor}
    from .. import io

    for shape in legs:
        t0 = time.perf_counter()
        if shape in data:
            ds = _load(data[shape])
            source = ds.attrs.get("model", "given")
            note = ds.attrs.get("dddas_note", f"{source} data given by the user")
        else:
            _say(progress, f"{shape}: RFT stand-in data (hip height varies; see note)")
            ds = rft_standin(shape, n_theta=n_theta)
            source, note = "rft-standin", STANDIN_NOTE
        ds.attrs["dddas_note"] = note
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
                                 f"{shape} leg: HOSVD explained variance ({source})")
        _say(progress, f"{shape}: cross-validation over {ds.sizes['case']} conditions")
        cv = cross_validate(ds, Surrogate(inputs=inputs, energy=energy, random_state=seed))
        io_cv = cv.copy()
        io_cv.attrs["note"] = note
        io_cv.to_netcdf(out / f"{shape}_cv.nc", engine="h5netcdf")
        mse_table(cv).to_csv(out / f"{shape}_cv.csv", index=False)
        plots.cv_errors(cv, out / f"{shape}_cv.png", f"{shape} leg: leave-one-out CV ({source})",
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
                                                                      jitter_floor=jitter_floor)
        io.write(post_pf, out / f"{shape}_posterior_pf.nc")
        io.write(post_ex, out / f"{shape}_posterior_exact.nc")
        obs.to_netcdf(out / f"{shape}_observations.nc", engine="h5netcdf")
        plots.prediction(post_pf, out / f"{shape}_assimilation.png", truth=truth, observations=obs, prior=prior,
                         truth_label="held-out case (truth)",
                         title=f"{shape} leg, held-out {cond}: particle filter posterior ({source})")
        plots.ess_trace(ess, obs[coord].values, out / f"{shape}_ess.png", particles, plots._xlabel(coord),
                        f"{shape} leg: particle filter ESS")
        cvm = {c: float(cv["mse"].sel(component=c).mean()) for c in cv["component"].values}
        summary["legs"][shape] = {
            "source": source, "note": note, "inputs": inputs, "n_conditions": int(n),
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
    (out / "summary.json").write_text(json.dumps(summary, indent=2, default=float))
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
    cv.to_netcdf(out / "foot_cv.nc", engine="h5netcdf")
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
    (out / "summary_foot.json").write_text(json.dumps(summary, indent=2, default=float))
    return summary
