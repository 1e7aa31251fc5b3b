"""Figures of the report that no study draws: RFT beside SPH, and the mean square error bars."""
from __future__ import annotations

import numpy as np

from ..plots import AXIS_LABEL, FORCE_LABEL, LEG_COLORS, STYLE, _save, _shade_phases, plt


def rft_vs_sph(rft: dict, sph: dict, path, title: str = ""):
    """Per leg (columns), lift and thrust (rows): RFT (solid) and SPH (dashed) against theta.
    rft, sph: {leg: force series}."""
    legs = list(rft)
    with plt.rc_context(STYLE):
        fig, axes = plt.subplots(2, len(legs), figsize=(3.1 * len(legs), 4.6), sharex=True, squeeze=False)
        for j, leg in enumerate(legs):
            for i, comp in enumerate(("Fz", "Fx")):
                ax = axes[i][j]
                ax.plot(rft[leg].theta, rft[leg][comp], color=LEG_COLORS[leg], label="RFT")
                if leg in sph:
                    ax.plot(sph[leg].theta, sph[leg][comp], color="k", ls="--", lw=1.0, label="SPH")
                ax.set_xlim(-135, 135)
                _shade_phases(ax, "theta")
                if j == 0:
                    ax.set_ylabel(FORCE_LABEL[comp])
                if i == 0:
                    ax.set_title(f"{leg} leg", loc="left")
                else:
                    ax.set_xlabel(AXIS_LABEL["theta"])
        h, lab = axes[0][0].get_legend_handles_labels()
        fig.legend(h, lab, loc="outside lower center", ncols=2, frameon=False)
        if title:
            fig.suptitle(title)
        return _save(fig, path)


def mse_bars(rows: list[dict], path, title: str = ""):
    """Grouped bars of mean square error against the measured curves: one panel per medium,
    groups (leg, component), one bar per model. rows: dicts with medium, leg, component,
    model, mse_N2."""
    media = list(dict.fromkeys(r["medium"] for r in rows))
    models = list(dict.fromkeys(r["model"] for r in rows))
    groups = list(dict.fromkeys((r["leg"], r["component"]) for r in rows))
    colors = {"RFT": "#1b6ca8", "SPH": "#e07a1f"}
    with plt.rc_context(STYLE):
        fig, axes = plt.subplots(1, len(media), figsize=(3.6 * len(media), 3.2), squeeze=False, sharey=True)
        w = 0.8 / max(len(models), 1)
        for ax, med in zip(axes[0], media):
            for k, model in enumerate(models):
                vals = []
                for g in groups:
                    v = [r["mse_N2"] for r in rows if r["medium"] == med and r["model"] == model
                         and (r["leg"], r["component"]) == g]
                    vals.append(v[0] if v else np.nan)
                ax.bar(np.arange(len(groups)) + (k - (len(models) - 1) / 2) * w, vals, w,
                       color=colors.get(model, None), label=model)
            ax.set_xticks(np.arange(len(groups)), [f"{leg}\n{c}" for leg, c in groups], fontsize=7)
            ax.set_title(med, loc="left")
            ax.set_xlabel("leg and force component")
        axes[0][0].set_ylabel(r"mean square error vs measured (N$^2$)")
        h, lab = axes[0][0].get_legend_handles_labels()
        fig.legend(h, lab, loc="outside lower center", ncols=len(models), frameon=False)
        if title:
            fig.suptitle(title)
        return _save(fig, path)


def claims_chart(rows, path, title: str = ""):
    """Ours beside the published number for rows that have one (a dot pair per row, on a log
    axis when the values span more than a decade); for cards that no study draws a figure for."""
    rows = [r for r in rows if r.ours is not None]
    with plt.rc_context(STYLE):
        fig, ax = plt.subplots(figsize=(6.4, 0.45 * len(rows) + 1.4), layout="constrained")
        y = np.arange(len(rows))[::-1]
        ours = np.array([r.ours for r in rows], float)
        ref = np.array([np.nan if r.reference is None else r.reference for r in rows], float)
        ax.plot(ref, y, "s", mfc="none", color="k", ms=7, label="published / reference")
        ax.plot(ours, y, "o", color="#1b6ca8", ms=5, label="terradyn")
        for yi, r in zip(y, rows):
            ax.annotate("matches" if r.passed else "differs" if r.passed is False else "", (r.ours, yi),
                        textcoords="offset points", xytext=(6, 3), fontsize=7,
                        color="#1e7b34" if r.passed else "#b3261e")
        ax.set_yticks(y, [r.quantity for r in rows], fontsize=7)
        ax.margins(x=0.15)
        unit = next((r.unit for r in rows if r.unit), "")
        ax.set_xlabel(f"value ({unit})" if unit else "value (dimensionless)")
        fig.legend(*ax.get_legend_handles_labels(), frameon=False, fontsize=7, loc="outside lower center", ncols=2)
        if title:
            ax.set_title(title, loc="left")
        return _save(fig, path)
