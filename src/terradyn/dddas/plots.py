"""Figures for the DDDAS surrogate, cross-validation, assimilation and experiment trials
(matplotlib, Agg backend). Every function writes one file and returns its path."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import xarray as xr

from ..io import atomic_save

from ..series import LONG_NAMES as _LONG, UNITS  # noqa: E402  (the schema's units)

LABELS = {"Fx": "horizontal force Fx", "Fz": "vertical force Fz", "torque": "torque"}
LABELS.update({c: f"{_LONG.get(c, c)} {c}" for c in ("Fy", "Tx", "Ty", "Tz")})


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _xlabel(coord: str) -> str:
    return "leg angle theta (deg)" if coord == "theta" else "time (s)"


_COND_UNITS = {"_rad_s": "rad/s", "_cm": "cm", "_deg": "deg", "_m": "m"}
_COND_NAMES = {"omega": "angular speed omega", "length": "foot length", "hip_height": "hip height"}


def condition_label(name: str) -> str:
    """A condition coordinate for an axis: ``omega_rad_s`` -> 'angular speed omega (rad/s)'."""
    suffix = next((u for u in _COND_UNITS if name.endswith(u)), "")
    base = name[:len(name) - len(suffix)]
    words = _COND_NAMES.get(base, base.replace("_", " "))
    return f"{words} ({_COND_UNITS[suffix]})" if suffix else words


def explained_variance(surrogate, path, title: str = "") -> Path:
    """Cumulative explained variance per HOSVD mode, with the energy threshold and the kept ranks."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6, 4), constrained_layout=True)
    names = ("mode 1 (conditions)", "mode 2 (steps)", "mode 3 (components)")
    for k, (cv, r) in enumerate(zip(surrogate.explained_variance_, surrogate.ranks_)):
        n = min(len(cv), 20)
        ax.plot(np.arange(1, n + 1), cv[:n], "o-", ms=3, label=f"{names[k]}: kept {r}")
    ax.axhline(surrogate.energy, color="k", ls=":", lw=1, label=f"threshold {surrogate.energy:g}")
    ax.set_xlabel("number of singular vectors kept")
    ax.set_ylabel("cumulative explained variance (-)")
    ax.set_title(title or "HOSVD explained variance")
    ax.legend(fontsize=8)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_save(path, lambda t: fig.savefig(t, dpi=130))
    plt.close(fig)
    return path


def _band(ax, x, y, std, color, alpha, label) -> bool:
    """A +-2 std band, drawn and named in the legend only where it is wider than the line
    (about 0.5 % of the curve's range): a legend must not name a band nobody can see."""
    y, std = np.asarray(y, float), np.asarray(std, float)
    span = float(np.ptp(y)) or 1.0
    if not np.isfinite(std).any() or np.nanmax(4 * std) < 0.005 * span:
        return False
    ax.fill_between(x, y - 2 * std, y + 2 * std, color=color, alpha=alpha, lw=0, label=label)
    return True


def prediction(pred: xr.Dataset, path, truth: xr.Dataset | None = None, title: str = "",
               observations: xr.Dataset | None = None, prior: xr.Dataset | None = None,
               truth_label: str = "truth") -> Path:
    """Predicted force components (of the series' schema: Fx and Fz in 2D) with +-2 std
    bands; optional truth, prior and observations."""
    plt = _plt()
    from ..series import components, coord_of

    c = coord_of(pred)
    comps = components(pred)
    fig, axes = plt.subplots(1, len(comps), figsize=(5.5 * len(comps), 4), constrained_layout=True,
                             squeeze=False)
    for ax, v in zip(axes[0], comps):
        x = pred[c].values
        if prior is not None:
            ax.plot(x, prior[v].values, color="0.5", ls="--", lw=1, label="prior (surrogate)")
            if f"{v}_std" in prior:
                _band(ax, x, prior[v].values, prior[f"{v}_std"].values, "0.5", 0.15, "prior +-2 std")
        if observations is not None and v in observations:
            ax.plot(observations[c].values, observations[v].values, ".", ms=2, color="tab:orange",
                    alpha=0.6, label="observations")
        name = pred.attrs.get("model", "prediction")
        if f"{v}_std" in pred:
            drawn = _band(ax, x, pred[v].values, pred[f"{v}_std"].values, "tab:blue", 0.3, f"{name} +-2 std")
            if not drawn:
                name += " (+-2 std band narrower than the line)"
        ax.plot(x, pred[v].values, color="tab:blue", label=name)
        if truth is not None:
            ax.plot(truth[c].values, truth[v].values, color="k", lw=1, label=truth_label)
        ax.set_xlabel(_xlabel(c))
        ax.set_ylabel(f"{LABELS[v]} ({UNITS[v]})")
        ax.legend(fontsize=8)
    fig.suptitle(title)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_save(path, lambda t: fig.savefig(t, dpi=130))
    plt.close(fig)
    return path


def cv_errors(cv: xr.Dataset, path, title: str = "", reported: float | None = None) -> Path:
    """Leave-one-out mean square error per held-out case and component (bars), with the
    nearest-case baseline and, when given, a reference line (e.g. the thesis's reported MSE)."""
    plt = _plt()
    names = [n for n in cv.coords if n not in ("case", "component", "mode") and cv[n].dims == ("case",)]
    label = names[0] if names else "case"
    xv = cv[label].values if names else cv["case"].values
    comps = list(cv["component"].values)
    fig, axes = plt.subplots(1, len(comps), figsize=(5 * len(comps), 4.4), layout="constrained", squeeze=False)
    idx = np.arange(len(xv))
    for ax, comp in zip(axes[0], comps):
        ax.bar(idx - 0.2, cv["mse"].sel(component=comp).values, 0.4, label="surrogate (held out)")
        ax.bar(idx + 0.2, cv["mse_nearest"].sel(component=comp).values, 0.4, label="nearest training case",
               color="0.6")
        if "mse_baseline" in cv:
            ax.plot(idx, cv["mse_baseline"].sel(component=comp).values, "k^", label=cv["mse_baseline"].attrs.get("source", "baseline"))
        if reported is not None:
            ax.axhline(reported, color="tab:red", ls=":", label=f"thesis reported ~{reported:g} (SPH, ten speeds)")
        ax.set_xticks(idx, [f"{v:g}" for v in xv], rotation=45, fontsize=8)
        ax.set_xlabel(f"held-out condition: {condition_label(label)}")
        ax.set_ylabel(f"mean square error of {comp} ({UNITS.get(comp, 'N')}^2)")
        ax.set_yscale("log")
    handles, labels = axes[0][0].get_legend_handles_labels()  # below the panels, off the bars
    fig.legend(handles, labels, loc="outside lower center", ncols=len(labels), fontsize=8, frameon=False)
    fig.suptitle(title or "leave-one-condition-out cross-validation")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_save(path, lambda t: fig.savefig(t, dpi=130))
    plt.close(fig)
    return path


def trial_comparison(cmp: xr.Dataset, path, title: str = "") -> Path:
    """Raw, filtered and RFT-model normal force (and torque) against time."""
    plt = _plt()
    vars_ = [v for v in ("normal_force", "torque") if f"{v}_raw" in cmp]
    fig, axes = plt.subplots(1, len(vars_), figsize=(5.5 * len(vars_), 4), constrained_layout=True, squeeze=False)
    t = cmp["time"].values
    for ax, v in zip(axes[0], vars_):
        unit = "N" if v == "normal_force" else "N m"
        ax.plot(t, cmp[f"{v}_raw"], color="0.7", lw=0.6, label="raw")
        ax.plot(t, cmp[f"{v}_filtered"], color="tab:blue", label="filtered (zero-phase Butterworth)")
        ax.plot(t, cmp[f"{v}_model"], color="tab:red", ls="--", label="RFT at the actual angles")
        ax.set_xlabel("time (s)")
        ax.set_ylabel(f"{v.replace('_', ' ')} ({unit})")
        ax.legend(fontsize=8)
    syn = " [SYNTHETIC DATA]" if int(cmp.attrs.get("synthetic", 0)) else ""
    fig.suptitle((title or "trial vs RFT") + syn)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_save(path, lambda t: fig.savefig(t, dpi=130))
    plt.close(fig)
    return path


def ess_trace(ess: np.ndarray, x: np.ndarray, path, n_particles: int, xlabel: str, title: str = "") -> Path:
    """Effective sample size after each assimilated sample."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6, 3.5), constrained_layout=True)
    ax.plot(x, ess, lw=1, label="ESS after update")
    ax.axhline(n_particles / 2, color="k", ls=":", lw=1, label="resampling threshold (N/2)")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("effective sample size (particles)")
    ax.set_title(title or "particle filter")
    ax.legend(fontsize=8)
    path = Path(path)
    atomic_save(path, lambda t: fig.savefig(t, dpi=130))
    plt.close(fig)
    return path


_METHOD_STYLE = {"prior": ("prior (surrogate, no data)", "0.5", "--"),
                 "terrain": ("terrain filter (RB + resample-move)", "C3", "-"),
                 "grid": ("exact Bayes (quadrature)", "C4", (0, (5, 2))),
                 "pf": ("present particle filter (coefficients)", "C0", "-."),
                 "exact": ("exact posterior (linear model)", "C2", ":"),
                 "oracle": ("oracle (surrogate at the true condition)", "k", "-"),
                 "naive": ("naive (hold last value)", "C1", (0, (1, 2)))}


def forecast_mse(ds: xr.Dataset, path, title: str = "") -> Path:
    """Forecast MSE of the rest of the stroke (mean over trials) against the stroke fraction
    observed: one panel per leg and component, one line per method (log scale)."""
    plt = _plt()
    legs, comps = list(ds.leg.values), list(ds.component.values)
    fig, axes = plt.subplots(len(legs), len(comps), figsize=(3.4 * len(comps), 2.6 * len(legs)),
                             constrained_layout=True, squeeze=False)
    frac = 100 * np.asarray(ds.fraction.values, float)
    for i, leg in enumerate(legs):
        for j, c in enumerate(comps):
            ax = axes[i, j]
            for m in ds.estimator.values:
                label, color, ls = _METHOD_STYLE.get(str(m), (str(m), None, "-"))
                y = ds["mse"].sel(leg=leg, component=c, estimator=m).mean("trial").values
                ax.semilogy(frac, y, color=color, ls=ls, marker="o", ms=3, label=label)
            u = UNITS.get(str(c), "")
            ax.set_title(f"{leg}: {c}", fontsize=9)
            ax.set_xlabel("stroke observed (%)")
            ax.set_ylabel(f"forecast MSE ({u}$^2$)")
            ax.grid(True, which="both", alpha=0.3)
    h, lab = axes[0, 0].get_legend_handles_labels()
    fig.legend(h, lab, loc="outside lower center", ncol=4, fontsize=8)
    fig.suptitle(title or f"Forecast of the rest of the stroke vs noise-free truth "
                 f"({ds.sizes['trial']} RFT trials per leg, {100 * float(ds.attrs.get('noise_fraction', 0)):g} % noise)",
                 fontsize=10)
    path = Path(path)
    fig.savefig(path, dpi=150)
    plt.close(fig)
    return path


_SPEED_STYLE = {"pf": ("particle filter, jitter (thesis setting)", "C0", "s"),
                "pf_move": ("particle filter + resample-move", "C3", "o"),
                "exact": ("exact posterior (linear model)", "C2", "^")}


def speed_study(result: dict, path, score: str = "assimilation", title: str = "") -> Path:
    """The thesis's speed study (:func:`terradyn.dddas.studies.speed_study`): posterior MSE over
    the prior's (the surrogate alone) for every held-out condition, mean over the noise seeds,
    one panel per leg and component, one marker per estimator; the dashed line at 1 is the prior,
    the legend gives each estimator's ratio of the mean MSEs (the target: at most 1)."""
    plt = _plt()
    legs = list(result["legs"])
    comps = ("Fx", "Fz")
    nseed = max(len(result.get("seeds", [0])), 1)
    fig, axes = plt.subplots(len(comps), len(legs), figsize=(3.7 * len(legs), 2.8 * len(comps)),
                             constrained_layout=True, squeeze=False)
    for j, leg in enumerate(legs):
        d = result["legs"][leg]
        name = d["inputs"][0]
        x = np.asarray(d["held_out"][name], float)
        for i, c in enumerate(comps):
            ax = axes[i, j]
            prior = np.asarray(d["mse_N2"][score]["prior"][c], float).reshape(len(x), nseed).mean(1)
            means = []
            for m, (label, color, marker) in _SPEED_STYLE.items():
                y = np.asarray(d["mse_N2"][score][m][c], float).reshape(len(x), nseed).mean(1)
                means.append(d["mean_over_prior"][score][m][c])
                ax.plot(x, y / prior, ls="none", marker=marker, ms=4, color=color, label=label)
            ax.axhline(1.0, color="0.5", ls="--", lw=1, label="prior (surrogate alone)")
            ax.set_title(f"{leg}: {c}; ratio of the means " + " / ".join(f"{r:.2f}" for r in means), fontsize=8)
            ax.set_xlabel(f"held-out {condition_label(name)}")
            ax.set_ylabel("posterior MSE / prior MSE")
            ax.grid(True, alpha=0.3)
    h, lab = axes[0, 0].get_legend_handles_labels()
    fig.legend(h, lab, loc="outside lower center", ncol=4, fontsize=7,
               title="markers: mean over the noise seeds; title: ratios of the mean MSEs in legend order", title_fontsize=7)
    fig.suptitle(title or f"Speed study ({score}): every held-out case, {nseed} noise seed(s), "
                 f"{100 * float(result.get('noise_fraction', 0)):g} % noise, N = {result.get('particles')}",
                 fontsize=10)
    path = Path(path)
    atomic_save(path, lambda t: fig.savefig(t, dpi=150))
    plt.close(fig)
    return path


def identification(ds: xr.Dataset, path, title: str = "") -> Path:
    """Left: fraction of trials whose most probable medium is the true one, against the stroke
    fraction observed, per leg. Right: one trial per leg, the posterior mean of zeta with its
    95 % credible interval and the true zeta."""
    plt = _plt()
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 3.8), constrained_layout=True)
    frac = 100 * np.asarray(ds.fraction.values, float)
    for i, leg in enumerate(ds.leg.values):
        c = f"C{i}"
        a1.plot(frac, 100 * ds["correct"].sel(leg=leg).mean("trial"), "o-", color=c, ms=3, label=str(leg))
        a1.plot(frac, 100 * ds["p_true_medium"].sel(leg=leg).mean("trial"), ":", color=c, lw=1)
        z = ds.sel(leg=leg, trial=0)
        a2.fill_between(frac, z["zeta_lo"], z["zeta_hi"], color=c, alpha=0.2)
        a2.plot(frac, z["zeta_mean"], "o-", color=c, ms=3,
                label=f"{leg} (true {z['true_medium'].item()})")
        a2.axhline(float(z["zeta_true"]), color=c, ls="--", lw=1)
    a1.axhline(95, color="k", ls="--", lw=1, label="target 95 %")
    a1.set_xlabel("stroke observed (%)")
    a1.set_ylabel("trials (%)")
    a1.set_title("medium identified (solid: MAP correct; dotted: mean P(true))", fontsize=9)
    a1.set_ylim(0, 102)
    a1.legend(fontsize=7)
    a2.set_xlabel("stroke observed (%)")
    a2.set_ylabel("zeta (-)")
    a2.set_title("zeta posterior mean, 95 % credible interval (band), truth (dashed)", fontsize=9)
    a2.legend(fontsize=7)
    if title:
        fig.suptitle(title)
    path = Path(path)
    fig.savefig(path, dpi=150)
    plt.close(fig)
    return path


def terrain_trace(ds: xr.Dataset, path, title: str = "") -> Path:
    """The terrain posterior as the stroke goes on (from :func:`terradyn.dddas.terrain.trace`):
    medium probabilities and zeta with its credible interval against the leg angle."""
    plt = _plt()
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(6.5, 5.5), sharex=True, constrained_layout=True)
    th = ds["theta"].values
    for m in ds.medium.values:
        a1.plot(th, ds["p_medium"].sel(medium=m), label=str(m))
    a1.set_ylabel("posterior probability (-)")
    a1.set_ylim(-0.02, 1.02)
    a1.legend(fontsize=7)
    a2.fill_between(th, ds["zeta_lo"], ds["zeta_hi"], alpha=0.3, label="95 % credible interval")
    a2.plot(th, ds["zeta_mean"], label="posterior mean")
    a2.set_ylabel("zeta (-)")
    a2.set_xlabel(_xlabel("theta"))
    a2.legend(fontsize=7)
    fig.suptitle(title or "terrain posterior during the stroke")
    path = Path(path)
    fig.savefig(path, dpi=150)
    plt.close(fig)
    return path
