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
