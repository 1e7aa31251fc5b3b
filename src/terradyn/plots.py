"""Publication-quality figures of force series and RFT analyses (matplotlib, Agg backend).

Every function returns the :class:`matplotlib.figure.Figure` and, given ``path``, saves it
(format from the suffix: .png at 200 dpi, .pdf, .svg).
"""
from __future__ import annotations

import matplotlib

matplotlib.use("Agg", force=False)
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import xarray as xr  # noqa: E402

from .series import components as schema_components, coord_of  # noqa: E402

STYLE = {
    "font.size": 9, "axes.labelsize": 9, "axes.titlesize": 9, "legend.fontsize": 8,
    "xtick.labelsize": 8, "ytick.labelsize": 8, "axes.spines.top": False,
    "axes.spines.right": False, "figure.constrained_layout.use": True, "lines.linewidth": 1.4,
}
LEG_COLORS = {"c": "#1b6ca8", "flat": "#d1495b", "reverse-c": "#2a9d8f", "foot": "#6a4c93"}
AXIS_LABEL = {"theta": r"leg angle $\theta$ (deg)", "time": "time (s)"}
FORCE_LABEL = {"Fz": r"lift $F_z$ (N)", "Fx": r"thrust $F_x$ (N)", "Fy": r"lateral force $F_y$ (N)",
               "torque": r"torque (N m)", "Tx": r"torque $T_x$ (N m)", "Ty": r"torque $T_y$ (N m)",
               "Tz": r"torque $T_z$ (N m)"}


def _save(fig, path, tight: bool = False):
    """Save at 200 dpi; ``tight`` crops to the drawn artists (for figures whose fixed aspect
    ratio keeps the layout engine from fitting the labels)."""
    if path is not None:
        from .io import atomic_save

        kw = {"bbox_inches": "tight", "pad_inches": 0.04} if tight else {}
        atomic_save(path, lambda t: fig.savefig(t, dpi=200, **kw))
    return fig


def _shade_phases(ax, coord):
    if coord == "theta":
        lo, hi = ax.get_xlim()
        ax.axvspan(lo, 0, color="0.93", zorder=0, lw=0)
        ax.set_xlim(lo, hi)  # the span must not widen the axis (shared axes grew by a margin each)
        ax.axhline(0, color="0.5", lw=0.6, zorder=1)
        ax.text(0.02, 0.97, "intrusion", transform=ax.transAxes, va="top", fontsize=7, color="0.4")
        ax.text(0.98, 0.97, "extraction", transform=ax.transAxes, va="top", ha="right",
                fontsize=7, color="0.4")


def forces(series: dict[str, xr.Dataset], path=None, components=None, title: str = "",
           styles: dict[str, dict] | None = None):
    """Force components against the motion coordinate for several labelled series; bands
    where a series carries ``<component>_std`` (mean +- 2 std). ``components``: default the
    force components of the first series' schema, lift first (2D: Fz, Fx; 3D: Fz, Fx, Fy)."""
    if components is None:
        comps = schema_components(next(iter(series.values())))
        components = ("Fz",) + tuple(c for c in comps if c != "Fz")
    with plt.rc_context(STYLE):
        fig, axes = plt.subplots(1, len(components), figsize=(3.4 * len(components), 2.8), squeeze=False)
        coord = coord_of(next(iter(series.values())))
        for ax, comp in zip(axes[0], components):
            for label, ds in series.items():
                st = dict((styles or {}).get(label, {}))
                st.setdefault("color", LEG_COLORS.get(label))
                x = ds[coord].values
                (line,) = ax.plot(x, ds[comp].values, label=label, **st)
                if f"{comp}_std" in ds:
                    s = ds[f"{comp}_std"].values
                    ax.fill_between(x, ds[comp] - 2 * s, ds[comp] + 2 * s, color=line.get_color(),
                                    alpha=0.2, lw=0)
            ax.set_xlabel(AXIS_LABEL[coord])
            ax.set_ylabel(FORCE_LABEL.get(comp, comp))
            ax.margins(x=0)
            _shade_phases(ax, coord)
        axes[0][0].legend(frameon=False, loc="center left")
        if title:
            fig.suptitle(title)
        return _save(fig, path)


def alpha_maps(models: dict[str, object], path=None, n: int = 91, title: str = ""):
    """alpha_z and alpha_x (N/cm^3) over beta x gamma in [-90, 90] deg for several stress
    models (columns), rows alpha_z and alpha_x, shared colour scales per row."""
    b = np.linspace(-np.pi / 2, np.pi / 2, n)
    g = np.linspace(-np.pi / 2, np.pi / 2, n)
    B, G = np.meshgrid(b, g, indexing="ij")
    vals = {k: [a / 1e6 for a in m.alpha(B, G)] for k, m in models.items()}
    with plt.rc_context(STYLE):
        fig, axes = plt.subplots(2, len(models), figsize=(1.9 * len(models) + 0.8, 3.6),
                                 sharex=True, sharey=True, squeeze=False)
        for row, (comp, idx) in enumerate((("alpha_z", 1), ("alpha_x", 0))):
            allv = np.concatenate([v[idx].ravel() for v in vals.values()])
            lim = np.abs(allv).max()
            for col, (name, v) in enumerate(vals.items()):
                ax = axes[row][col]
                im = ax.pcolormesh(np.degrees(g), np.degrees(b), v[idx], cmap="RdBu_r",
                                   vmin=-lim, vmax=lim, shading="auto", rasterized=True)
                if row == 0:
                    ax.set_title(name)
                if row == 1:
                    ax.set_xlabel(r"$\gamma$ (deg)")
                if col == 0:
                    ax.set_ylabel(r"$\beta$ (deg)")
                ax.set_xticks([-90, 0, 90])
                ax.set_yticks([-90, 0, 90])
            cb = fig.colorbar(im, ax=axes[row].tolist(), shrink=0.9)
            cb.set_label(rf"$\{comp}$ (N/cm$^3$)")
        if title:
            fig.suptitle(title)
        return _save(fig, path)


def holdout_errors(ds: xr.Dataset, path=None):
    """Bar chart of hold-out RMS errors per method, grouped by medium, for alpha_z and alpha_x."""
    with plt.rc_context(STYLE):
        fig, axes = plt.subplots(1, 2, figsize=(7.2, 2.8), sharey=True)
        meds, methods = list(ds.medium.values), list(ds.method.values)
        w = 0.8 / len(methods)
        cmap = plt.get_cmap("viridis", len(methods))
        for ax, comp in zip(axes, ("alpha_z", "alpha_x")):
            for j, m in enumerate(methods):
                ax.bar(np.arange(len(meds)) + (j - (len(methods) - 1) / 2) * w,
                       ds.rmse.sel({"method": m, "component": comp}), w, label=m, color=cmap(j))
            ax.set_xticks(range(len(meds)), meds, rotation=25, ha="right")
            ax.set_title(rf"$\{comp}$")
        axes[0].set_ylabel("hold-out RMS error (N/cm$^3$)")
        axes[1].legend(frameon=False, ncols=2)
        return _save(fig, path)


def frames(leg, theta_deg, fx, fz, x, z, path=None, title: str = "", hip_height: float = 0.02):
    """Snapshots of a leg at several angles with element force arrows.

    theta_deg (K,); fx, fz, x, z: (K, n) per-element forces (N) and positions (m)."""
    K = len(theta_deg)
    with plt.rc_context(STYLE):
        fig, axes = plt.subplots(1, K, figsize=(1.7 * K + 0.4, 3.0), sharey=True)
        axes = np.atleast_1d(axes)
        fmax = np.hypot(fx, fz).max() or 1.0
        L = np.hypot(x, z - hip_height).max()
        scale = 0.5 * L / fmax  # longest arrow = half the leg's reach
        for k, ax in enumerate(axes):
            ax.axhspan(-150 * L, 0, color="#e9d8a6", zorder=0, lw=0)
            ax.plot(x[k] * 100, z[k] * 100, color=LEG_COLORS.get(getattr(leg, "name", ""), "k"), lw=2.5)
            ax.plot([0], [hip_height * 100], "ko", ms=3)
            m = np.hypot(fx[k], fz[k]) > 0
            ax.quiver(x[k][m] * 100, z[k][m] * 100, fx[k][m] * scale * 100, fz[k][m] * scale * 100,
                      angles="xy", scale_units="xy", scale=1, width=0.012, color="#9b2226")
            ax.set_aspect("equal")
            ax.set_xlim(-L * 110, L * 110)
            ax.set_ylim(-L * 110, L * 100 + hip_height * 100)
            ax.set_title(rf"$\theta$ = {theta_deg[k]:.0f}$^\circ$")
            ax.set_xlabel("x (cm)")
        axes[0].set_ylabel("z (cm)")
        note = f"force arrows: 1 cm = {1 / (scale * 100):.2g} N; sand shaded"
        fig.suptitle(f"{title}\n{note}" if title else note)
        return _save(fig, path, tight=True)


def foot_forces(ds: xr.Dataset, path=None, title: str = ""):
    """Foot study: Fz and Fx against rotation for each length (case dim ``length_cm``)."""
    with plt.rc_context(STYLE):
        fig, axes = plt.subplots(1, 3, figsize=(9.6, 2.8))
        cmap = plt.get_cmap("viridis", ds.sizes["case"])
        for i in range(ds.sizes["case"]):
            d = ds.isel(case=i)
            lab = f"{float(d.length_cm):.0f} cm"
            axes[0].plot(d.theta, d.Fz, color=cmap(i), label=lab)
            axes[1].plot(d.theta, d.Fx, color=cmap(i), label=lab)
        for ax, comp in zip(axes[:2], ("Fz", "Fx")):
            ax.set_xlabel("foot rotation (deg)")
            ax.set_ylabel({"Fz": r"vertical force $F_z$ (N)", "Fx": r"horizontal force $F_x$ (N)"}[comp])
        axes[0].legend(frameon=False, ncols=2, fontsize=7)
        end = ds.isel(theta=-1)
        axes[2].plot(ds.length_cm, end.Fz, "o-", label=r"$F_z$")
        axes[2].plot(ds.length_cm, end.Fx, "s-", label=r"$F_x$")
        axes[2].set_xlabel("foot length (cm)")
        axes[2].set_ylabel(f"force at {float(ds.theta[-1]):.1f} deg (N)")
        axes[2].legend(frameon=False)
        if title:
            fig.suptitle(title)
        return _save(fig, path)


def model_vs_measured(pred: dict, meas: dict, path=None, title: str = ""):
    """Grid of panels (rows: media, cols: Fz, Fx) with model curves and measured points.
    pred/meas: {(medium, leg, comp): (theta_deg, force_N)}."""
    media = sorted({k[0] for k in meas})
    with plt.rc_context(STYLE):
        fig, axes = plt.subplots(len(media), 2, figsize=(7.0, 2.3 * len(media)), squeeze=False,
                                 sharex=True)
        for r, med in enumerate(media):
            for c, comp in enumerate(("Fz", "Fx")):
                ax = axes[r][c]
                for (m, leg, cp), (th, f) in pred.items():
                    if m == med and cp == comp:
                        ax.plot(th, f, color=LEG_COLORS[leg], label=f"{leg} RFT")
                for (m, leg, cp), (th, f) in meas.items():
                    if m == med and cp == comp:
                        ax.plot(th, f, "o", ms=3.5, mfc="none", color=LEG_COLORS[leg],
                                label=f"{leg} measured")
                ax.set_ylabel(FORCE_LABEL[comp])
                ax.set_title(med, loc="left")
                ax.set_xlim(-135, 135)  # the test's range of theta
                _shade_phases(ax, "theta")
                if r == len(media) - 1:
                    ax.set_xlabel(AXIS_LABEL["theta"])
        handles, labels = axes[0][0].get_legend_handles_labels()
        fig.legend(handles, labels, loc="outside lower center", ncols=3, frameon=False, fontsize=7)
        if title:
            fig.suptitle(title)
        return _save(fig, path)
