"""Forecast skill and terrain identification studies (RFT trials, scored on the noise-free truth).

A trial: one of the legs (or the foot) steps into one of Li 2013's five media with an
unknown strength factor k ~ N(1, k_std^2), an unknown condition drawn uniformly in the
training box (hip height; foot length and sinkage), and sensors with 5 % noise (of each
channel's RMS over the stroke) and a constant bias ~ N(0, (bias x RMS)^2). At stroke
fractions 10 %, 20 %, ..., 90 % every method has seen the samples before the cut and
forecasts the force components after it; the error is scored against the noise-free RFT
truth. Methods:

* ``prior``: the terrain model's prior predictive mean (no data);
* ``terrain``: :class:`~terradyn.dddas.terrain.TerrainFilter` (conditions in the state,
  Rao-Blackwellised strength and biases, resample-move);
* ``grid``: the exact Bayesian posterior of the same model by quadrature (every medium x a
  regular grid of conditions, strength and biases integrated out exactly): what the
  terrain filter approximates, and the best any method can do with that model and data;
* ``pf`` and ``exact``: the present coefficient-space filters on a linear model (one HOSVD
  basis pooled over all media and conditions, a Gaussian prior from the training
  coefficients): :class:`~terradyn.dddas.filter.ParticleFilter` and its exact Gaussian
  posterior :class:`~terradyn.dddas.filter.GaussianPosterior`;
* ``oracle``: the surrogate of the true medium at the true condition x the true k;
* ``naive``: hold the last filtered value (mean of the last 3 samples of each component).
"""
from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
import xarray as xr

from ..errors import InputError, choice, in_range, integer, positive
from .filter import GaussianPosterior, ParticleFilter, warmup
from .hosvd import hosvd
from .terrain import COMPONENTS, LEG_KINDS, MEDIA, Channel, TerrainFilter, TerrainModel, rft_forces, training_stack

FRACTIONS = tuple(np.round(np.arange(0.1, 0.91, 0.1), 2))
METHODS = ("prior", "terrain", "grid", "pf", "exact", "oracle", "naive")
#: Lever arm of the foot's load cell (m): it reads torque / lever arm.
FOOT_LEVER_ARM = 0.10


def sensor_channels(leg: str) -> list[tuple[str, dict]]:
    """Channel names and component weights of a leg's sensors: Fx, Fz, torque for the legs;
    Fx, Fz and a load cell at :data:`FOOT_LEVER_ARM` for the foot (the thesis's foot trial)."""
    if leg == "foot":
        return [("Fx", {"Fx": 1.0}), ("Fz", {"Fz": 1.0}), ("load_cell", {"torque": 1.0 / FOOT_LEVER_ARM})]
    return [(c, {c: 1.0}) for c in COMPONENTS]


class PooledLinear:
    """The present filters' linear model: one HOSVD basis over a pooled stack (all media,
    conditions and k in {0.85, 1, 1.15}), Gaussian prior = the training coefficients'
    mean and covariance. Channel rows h (S, D), offsets (S,) and representation error (S,)."""

    def __init__(self, Y: np.ndarray, energy: float = 0.999):
        scale = np.sqrt((Y ** 2).mean(axis=(0, 1)))
        scale = np.where(scale > 0, scale, 1.0)
        h = hosvd(Y / scale, energy=(energy, 0.9999, 0.9999), center=True)
        self.B, self.M, self.scale = h.basis, h.mean, scale
        c = h.coefficients
        self.mean = c.mean(0)
        self.cov = np.cov(c.T).reshape(len(self.mean), len(self.mean)) + 1e-12 * np.eye(len(self.mean))
        rec = (np.tensordot(c, self.B, axes=(1, 0)) + self.M) * scale
        self.res = np.sqrt(((Y - rec) ** 2).mean(0))   # (S, C)

    def rows(self, weights: dict):
        H = 0.0
        off = 0.0
        var = 0.0
        for comp, w in weights.items():
            j = COMPONENTS.index(comp)
            H = H + w * self.B[:, :, j].T * self.scale[j]
            off = off + w * self.M[:, j] * self.scale[j]
            var = var + (w * self.res[:, j]) ** 2
        return np.ascontiguousarray(H), off, np.sqrt(var)

    def forces(self, c: np.ndarray) -> np.ndarray:
        return (np.tensordot(c, self.B, axes=(0, 0)) + self.M) * self.scale


def _pooled(leg: str, model: TerrainModel, n_theta: int) -> PooledLinear:
    Ys = []
    for m in model.media:
        ds = training_stack(leg, m, None, n_theta)
        Y = np.stack([ds[c].transpose("case", "theta").values for c in COMPONENTS], -1)
        Ys += [Y * f for f in (0.85, 1.0, 1.15)]
    return PooledLinear(np.concatenate(Ys))


def prior_rms(model: TerrainModel, channels, seed: int = 0) -> dict:
    """RMS over the stroke of each channel's prior predictive mean force (the scale of the
    sensor-bias prior): ``channels`` (name, weights) pairs -> {name: RMS}."""
    F0 = TerrainFilter(model, [Channel("Fz")], n_particles=2000, seed=seed).forecast()
    comp = {c: F0[:, j] for j, c in enumerate(COMPONENTS)}
    return {n: float(np.sqrt(np.mean(Channel(n, w, 1.0).of(comp) ** 2))) for n, w in channels}


def make_trial(leg: str, model: TerrainModel, rng: np.random.Generator, medium: str | None = None,
               noise: float = 0.05, bias: float = 0.02, k_std: float = 0.1, n_theta: int | None = None) -> dict:
    """One synthetic RFT trial: truth (S, C), channel readings, the hidden terrain."""
    medium = medium or MEDIA[int(rng.integers(len(MEDIA)))]
    u = rng.random(len(model.inputs))
    cond = {n: float(model.lo[j] + u[j] * (model.hi[j] - model.lo[j])) for j, n in enumerate(model.inputs)}
    k = float(max(1.0 + k_std * rng.standard_normal(), 0.5))
    ds = rft_forces(leg, medium, cond, k, n_theta or len(model.theta))
    truth = np.stack([ds[c].values for c in COMPONENTS], -1)
    F = {c: truth[:, j] for j, c in enumerate(COMPONENTS)}
    chans, obs = [], {}
    for name, w in sensor_channels(leg):
        ch0 = Channel(name, w, 1.0)
        clean = ch0.of(F)
        rms = float(np.sqrt(np.mean(clean ** 2)))
        sd = max(noise * rms, 1e-9)
        b = bias * rms * rng.standard_normal()
        obs[name] = clean + b + sd * rng.standard_normal(len(clean))
        chans.append((name, w, sd))
    return {"leg": leg, "medium": medium, "condition": cond, "k": k, "theta": ds["theta"].values,
            "truth": truth, "obs": obs, "channels": chans}


def in_contact(truth: np.ndarray, level: float = 0.01) -> np.ndarray:
    """(S,) True where the noise-free force magnitude exceeds ``level`` x its stroke maximum:
    the samples that carry information about the terrain."""
    mag = np.hypot(truth[:, COMPONENTS.index("Fx")], truth[:, COMPONENTS.index("Fz")])
    return mag > level * max(float(mag.max()), 1e-300)


def _naive(obs: dict, n: int, S: int, leg: str) -> np.ndarray:
    out = np.zeros((S, len(COMPONENTS)))
    chans = dict(sensor_channels(leg))
    for name, w in chans.items():
        hold = float(np.mean(obs[name][max(0, n - 3):n]))
        for comp, f in w.items():
            out[:, COMPONENTS.index(comp)] = hold / f
    return out


def run_trial(tr: dict, model: TerrainModel, lin: PooledLinear, fractions=FRACTIONS, particles: int = 5000,
              seed: int = 0, bias_prior: float = 0.05, k_std: float = 0.1, move_sweeps: int = 1,
              rms_prior: dict | None = None) -> dict:
    """Run every method through one trial; forecasts scored after each fraction's cut."""
    S = len(tr["theta"])
    cuts = [int(round(f * S)) for f in fractions]
    rms_prior = rms_prior or {}
    channels = [Channel(n, w, sd, bias_prior * rms_prior.get(n, 1.0)) for n, w, sd in tr["channels"]]
    filt = TerrainFilter(model, channels, k_std=k_std, n_particles=particles, seed=seed, move_sweeps=move_sweeps)
    prior_fc = filt.forecast()
    grid = TerrainFilter.on_grid(model, channels, k_std=k_std)
    pf = ParticleFilter(lin.mean, lin.cov, n_particles=particles, rng=seed, jitter_floor=0.01)
    rows = {n: lin.rows(w) for n, w, _ in tr["channels"]}
    sig = {n: np.sqrt(sd ** 2 + rows[n][2] ** 2) for n, _, sd in tr["channels"]}
    mi = model.media.index(tr["medium"])
    oracle = model.forces(mi, tr["condition"], tr["k"])
    truth = tr["truth"]
    th = tr["theta"]
    nf, nc = len(fractions), len(COMPONENTS)
    mse = np.full((nf, len(METHODS), nc), np.nan)
    ident = {"p_true": np.zeros(nf), "map": [], "p_true_grid": np.zeros(nf), "map_grid": [], "zeta_mean": np.zeros(nf), "zeta_lo": np.zeros(nf),
             "zeta_hi": np.zeros(nf)}
    t_steps = []
    done = 0
    for fi, cut in enumerate(cuts):
        for i in range(done, cut):
            vals = {n: tr["obs"][n][i] for n in tr["obs"]}
            t0 = time.perf_counter()
            filt.update(th[i], vals)
            t_steps.append(time.perf_counter() - t0)
            grid.update(th[i], vals)
            for n, (H, off, _) in rows.items():
                pf.update(H[i], off[i], vals[n], sig[n][i])
        done = cut
        ex = GaussianPosterior(lin.mean, lin.cov)
        Hs = np.concatenate([rows[n][0][:cut] for n in rows])
        offs = np.concatenate([rows[n][1][:cut] for n in rows])
        ys = np.concatenate([tr["obs"][n][:cut] for n in rows])
        ss = np.concatenate([sig[n][:cut] for n in rows])
        ex.update_many(Hs, offs, ys, ss)
        fc = {"prior": prior_fc, "terrain": filt.forecast(), "grid": grid.forecast(), "pf": lin.forces(pf.mean), "exact": lin.forces(ex.mean),
              "oracle": oracle, "naive": _naive(tr["obs"], cut, S, tr["leg"])}
        for mj, m in enumerate(METHODS):
            mse[fi, mj] = np.mean((fc[m][cut:] - truth[cut:]) ** 2, axis=0)
        p = filt.medium_probabilities()
        ident["p_true"][fi] = p[tr["medium"]]
        ident["map"].append(max(p, key=p.get))
        pg = grid.medium_probabilities()
        ident["p_true_grid"][fi] = pg[tr["medium"]]
        ident["map_grid"].append(max(pg, key=pg.get))
        z = filt.zeta_posterior()
        ident["zeta_mean"][fi], ident["zeta_lo"][fi], ident["zeta_hi"][fi] = z["mean"], z["lo"], z["hi"]
    return {"mse": mse, "ident": ident, "step_us": np.array(t_steps) * 1e6, "resamples": filt.n_resamples,
            "contact": np.array([int(np.count_nonzero(in_contact(truth)[:cut])) for cut in cuts])}


def forecast_study(out: str | Path | None = None, legs: Sequence[str] = LEG_KINDS, trials_per_medium: int = 20,
                   noise: float = 0.05, bias: float = 0.02, k_std: float = 0.1, particles: int = 5000,
                   seed: int = 0, move_sweeps: int = 1, fractions=FRACTIONS,
                   progress: Callable[[str], None] | None = None) -> xr.Dataset:
    """Forecast skill and terrain identification over RFT trials (see the module docstring).
    Returns a Dataset (and with ``out`` writes ``forecast.nc``, ``summary.json`` and the
    figures ``forecast_mse.png``, ``identification.png``)."""
    legs = [choice("leg", l, LEG_KINDS) for l in legs]
    if not legs:
        raise InputError("leg", "give at least one leg")
    n_tr = integer("trials", trials_per_medium, 1)
    if n_tr > 10_000:
        raise InputError("trials", f"must be <= 10000 per medium, got {n_tr}")
    noise = in_range("noise", noise, 1e-6, 1.0)
    bias = in_range("bias", bias, 0.0, 1.0)
    k_std = in_range("k-std", k_std, 1e-6, 0.5)
    integer("particles", particles, 2)
    if out is not None:
        from ..io import check_writable

        check_writable(out, "out", directory=True)
    warmup()
    rng = np.random.default_rng(seed)
    n_t = len(MEDIA) * n_tr
    res = {k: [] for k in ("mse", "p_true", "correct", "p_true_grid", "correct_grid", "zeta_mean", "zeta_lo", "zeta_hi", "zeta_true", "medium",
                           "step_us", "resamples", "map", "map_grid", "contact", "k_true", "cond")}
    cond_names = []
    t_start = time.perf_counter()
    for leg in legs:
        t0 = time.perf_counter()
        model = TerrainModel.from_rft(leg, seed=seed)
        lin = _pooled(leg, model, len(model.theta))
        rms_prior = prior_rms(model, sensor_channels(leg), seed)
        per = {k: [] for k in res}
        cond_names += [n for n in model.inputs if n not in cond_names]
        for t in range(n_t):
            tr = make_trial(leg, model, rng, MEDIA[t % len(MEDIA)], noise, bias, k_std)
            r = run_trial(tr, model, lin, fractions, particles, seed + t, k_std=k_std, move_sweeps=move_sweeps,
                          rms_prior=rms_prior)
            per["mse"].append(r["mse"])
            per["p_true"].append(r["ident"]["p_true"])
            per["correct"].append([m == tr["medium"] for m in r["ident"]["map"]])
            per["p_true_grid"].append(r["ident"]["p_true_grid"])
            per["correct_grid"].append([m == tr["medium"] for m in r["ident"]["map_grid"]])
            for z in ("zeta_mean", "zeta_lo", "zeta_hi"):
                per[z].append(r["ident"][z])
            per["zeta_true"].append(tr["k"] * model.zeta[model.media.index(tr["medium"])])
            per["medium"].append(tr["medium"])
            per["step_us"].append(float(np.mean(r["step_us"])))
            per["resamples"].append(r["resamples"])
            per["map"].append(r["ident"]["map"])
            per["map_grid"].append(r["ident"]["map_grid"])
            per["contact"].append(r["contact"])
            per["k_true"].append(tr["k"])
            per["cond"].append(dict(tr["condition"]))
        for k in res:
            res[k].append(per[k])
        if progress:
            acc = np.mean(np.array(per["correct"])[:, list(fractions).index(0.3)]) if 0.3 in fractions else np.nan
            progress(f"{leg}: {n_t} trials in {time.perf_counter() - t0:.1f} s; medium correct at 30 %: {acc:.1%}")
    ds = xr.Dataset(
        {"mse": (("leg", "trial", "fraction", "estimator", "component"), np.array(res["mse"])),
         "p_true_medium": (("leg", "trial", "fraction"), np.array(res["p_true"])),
         "correct": (("leg", "trial", "fraction"), np.array(res["correct"])),
         "p_true_medium_grid": (("leg", "trial", "fraction"), np.array(res["p_true_grid"])),
         "correct_grid": (("leg", "trial", "fraction"), np.array(res["correct_grid"])),
         "zeta_mean": (("leg", "trial", "fraction"), np.array(res["zeta_mean"])),
         "zeta_lo": (("leg", "trial", "fraction"), np.array(res["zeta_lo"])),
         "zeta_hi": (("leg", "trial", "fraction"), np.array(res["zeta_hi"])),
         "zeta_true": (("leg", "trial"), np.array(res["zeta_true"])),
         "true_medium": (("leg", "trial"), np.array(res["medium"], dtype=object).astype(str)),
         "step_us_mean": (("leg", "trial"), np.array(res["step_us"])),
         "resamples": (("leg", "trial"), np.array(res["resamples"])),
         "map_medium": (("leg", "trial", "fraction"), np.array(res["map"], dtype=object).astype(str)),
         "map_medium_grid": (("leg", "trial", "fraction"), np.array(res["map_grid"], dtype=object).astype(str)),
         "contact_samples": (("leg", "trial", "fraction"), np.array(res["contact"])),
         "k_true": (("leg", "trial"), np.array(res["k_true"]))},
        coords={"leg": legs, "trial": np.arange(n_t), "fraction": list(fractions), "estimator": list(METHODS),
                "component": list(COMPONENTS)})
    for n in cond_names:  # the hidden condition of each trial (NaN where a leg has no such condition)
        ds[f"true_{n}"] = (("leg", "trial"), np.array([[c.get(n, np.nan) for c in per_leg] for per_leg in res["cond"]]))
    ds["contact_samples"].attrs["long_name"] = "samples before the cut with force above 1 % of the stroke maximum"
    ds["mse"].attrs.update(units="N^2 (N^2 m^2 for torque)",
                           long_name="forecast MSE of the rest of the stroke vs the noise-free truth")
    ds.attrs.update(study="dddas-forecast", noise_fraction=noise, bias_fraction=bias, k_std=k_std,
                    particles=particles, seed=seed, move_sweeps=move_sweeps, trials_per_medium=n_tr,
                    seconds=time.perf_counter() - t_start,
                    note="RFT trials (Li 2013 five media x strength k, unknown hip height / foot length and "
                         "sinkage); forecasts of the part of the stroke after each cut scored against the "
                         "noise-free RFT truth")
    if out is not None:
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        from ..io import atomic_write_text

        tmp = out / ".forecast.nc.tmp"
        ds.to_netcdf(tmp, engine="h5netcdf")
        tmp.replace(out / "forecast.nc")
        atomic_write_text(out / "summary.json", json.dumps(summarise(ds), indent=2))
        from . import plots

        plots.forecast_mse(ds, out / "forecast_mse.png")
        plots.identification(ds, out / "identification.png")
    return ds


def summarise(ds: xr.Dataset, at: float = 0.3) -> dict:
    """Headline numbers per leg at stroke fraction ``at``: mean forecast MSE per method and
    component, ratios terrain/prior and terrain/oracle, identification rate, zeta coverage."""
    out = {"fraction": at, "attrs": {k: (v.item() if hasattr(v, "item") else v) for k, v in ds.attrs.items()},
           "legs": {}}
    f = ds.sel(fraction=at)
    for leg in ds.leg.values:
        m = f.sel(leg=leg)["mse"].mean("trial")
        mse = {str(meth): {str(c): float(m.sel(estimator=meth, component=c)) for c in ds.component.values}
               for meth in ds.estimator.values}
        ratio = {name: {str(c): mse["terrain"][str(c)] / mse[name][str(c)] for c in ds.component.values}
                 for name in ("prior", "oracle", "grid", "pf", "exact", "naive")}
        z = f.sel(leg=leg)
        cover = float(((z["zeta_lo"] <= ds["zeta_true"].sel(leg=leg)) & (ds["zeta_true"].sel(leg=leg) <= z["zeta_hi"])).mean())
        out["legs"][str(leg)] = {
            "mse_mean": mse, "terrain_over": ratio,
            "medium_correct": float(z["correct"].mean()),
            "medium_correct_exact_bayes_grid": float(z["correct_grid"].mean()),
            "p_true_medium_mean": float(z["p_true_medium"].mean()),
            "medium_correct_by_fraction": {float(fr): float(ds["correct"].sel(leg=leg, fraction=fr).mean())
                                          for fr in ds.fraction.values},
            "zeta_ci95_coverage": cover,
            "zeta_ci95_width_mean": float((z["zeta_hi"] - z["zeta_lo"]).mean()),
            "step_us_mean": float(ds["step_us_mean"].sel(leg=leg).mean()),
            "trials": int(ds.sizes["trial"])}
        out["legs"][str(leg)].update(_ceiling(ds, leg, at))
    return out


def _ceiling(ds: xr.Dataset, leg, at: float) -> dict:
    """What limits the scores (the Bayes ceiling): the exact Bayes (grid) forecast's MSE over
    the oracle's at every fraction, the grid's confusion matrix at ``at``, and the
    identification rates of trials split by how many samples before the cut touched the
    medium (terciles)."""
    L = ds.sel(leg=leg)
    mse = L["mse"].mean("trial")
    comps = [str(c) for c in ds.component.values]

    def by_frac(a, b):
        return {float(fr): {c: float(mse.sel(fraction=fr, estimator=a, component=c)
                                     / mse.sel(fraction=fr, estimator=b, component=c)) for c in comps}
                for fr in ds.fraction.values}

    out = {"grid_over_oracle_by_fraction": by_frac("grid", "oracle"),
           "terrain_over_oracle_by_fraction": by_frac("terrain", "oracle"),
           "terrain_over_grid_by_fraction": by_frac("terrain", "grid")}
    if "map_medium_grid" not in ds:
        return out
    f = L.sel(fraction=at)
    true = [str(v) for v in L["true_medium"].values]
    media = sorted(set(true), key=list(MEDIA).index)
    out["confusion_grid"] = {t: {m: int(sum(1 for a, b in zip(true, f["map_medium_grid"].values) if a == t and str(b) == m))
                                 for m in media} for t in media}
    nc = f["contact_samples"].values.astype(float)
    edges = np.quantile(nc, [0, 1 / 3, 2 / 3, 1])
    bins = []
    for lo, hi, last in zip(edges[:-1], edges[1:], (False, False, True)):
        sel = (nc >= lo) & ((nc <= hi) if last else (nc < hi))
        if sel.any():
            bins.append({"contact_samples": [int(lo), int(hi)], "trials": int(sel.sum()),
                         "medium_correct": float(f["correct"].values[sel].mean()),
                         "medium_correct_exact_bayes_grid": float(f["correct_grid"].values[sel].mean())})
    out["identification_by_contact_samples"] = bins
    return out
