"""Figures of the SPH validation scenes (matplotlib, Agg backend). Each returns the figure and
saves it when given ``path``."""
from __future__ import annotations

import matplotlib

matplotlib.use("Agg", force=False)
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from ..plots import STYLE, _save, forces  # noqa: E402


def bed(r: dict, path=None):
    """Scene 1: -sigma_zz and -sigma_xx (kPa) against depth (cm) with the geostatic lines."""
    with plt.rc_context(STYLE):
        fig, ax = plt.subplots(figsize=(3.4, 3.0))
        d = r["depth"] * 100
        ax.plot(-r["szz"] / 1e3, d, "o", label=r"SPH $-\sigma_{zz}$")
        ax.plot(-r["sxx"] / 1e3, d, "s", label=r"SPH $-\sigma_{xx}$")
        ax.plot(r["geostatic"] / 1e3, d, "-", color="k", label=r"$\rho g d$")
        ax.plot(r["lateral_ratio_dp_limit"] * r["geostatic"] / 1e3, d, "--", color="k",
                label="Drucker-Prager limit ratio")
        ax.invert_yaxis()
        ax.set_xlabel("stress (kPa)")
        ax.set_ylabel("depth (cm)")
        ax.legend(frameon=False)
        return _save(fig, path)


def columns(rows: list[dict], path=None):
    """Scene 2: final deposits and run-out / final height against Lube et al. (2005)."""
    from .validation import lube2005

    with plt.rc_context(STYLE):
        fig, (a1, a2) = plt.subplots(1, 2, figsize=(7.0, 2.8))
        # the tallest column first, so that the smaller deposits are drawn over it
        order = sorted(range(len(rows)), key=lambda k: -rows[k]["aspect"])
        handles = {}
        for k in order:
            r = rows[k]
            base = r["base"]
            handles[k], = a1.plot(r["x"] / base, r["z"] / base, ".", ms=1.5, color=f"C{k}",
                                  label=f"a = {r['aspect']:g}")
        walls = rows[0].get("channel_width") if rows else None
        if walls:
            a1.set_title(f"deposits, side walls {walls * 100:g} cm apart", fontsize="medium", loc="left")
        a1.set_xlabel(r"$x / L_i$")
        a1.set_ylabel(r"$z / L_i$")
        a1.set_aspect("equal")
        a1.legend([handles[k] for k in range(len(rows))], [f"a = {r['aspect']:g}" for r in rows],
                  frameon=False, markerscale=6, loc="upper left", bbox_to_anchor=(1.0, 1.0))
        aa = np.linspace(0.2, max(r["aspect"] for r in rows) * 1.2, 100)
        lr, lh = lube2005(aa)
        a2.plot(aa, lr, "-", color="C0", label="run-out, Lube 2005")
        a2.plot(aa, lh, "--", color="C1", label="final height, Lube 2005")
        a2.plot([r["aspect"] for r in rows], [r["runout"] for r in rows], "o", color="C0", label="run-out, SPH")
        a2.plot([r["aspect"] for r in rows], [r["height"] for r in rows], "s", color="C1", label="final height, SPH")
        a2.set_xlabel("aspect ratio a")
        a2.set_ylabel(r"$(L_f - L_i)/L_i$,  $H_f / L_i$")
        a2.legend(frameon=False)
        return _save(fig, path)


def plate(r: dict, path=None):
    """Scene 3: stress on a horizontal plate (kPa) against depth, with the measured slope."""
    with plt.rc_context(STYLE):
        fig, ax = plt.subplots(figsize=(3.4, 2.8))
        d = r["depth"]
        ax.plot(d * 100, r["stress"] / 1e3, ".", label=f"SPH (slope {r['alpha_z'] / 1e6:.3f} N/cm$^3$)")
        dd = np.clip(d, 0, None)
        if r.get("alpha_z_measured"):
            ax.plot(d * 100, r["alpha_z_measured"] * dd / 1e3, "k-",
                    label=f"Li 2013 measured {r['alpha_z_measured'] / 1e6:.2f} N/cm$^3$")
        ax.set_xlabel("plate depth (cm)")
        ax.set_ylabel(r"vertical stress $F_z / A$ (kPa)")
        ax.legend(frameon=False)
        return _save(fig, path)


def leg_comparison(sph, rft, path=None, title: str = ""):
    """Scene 4/5: SPH and RFT forces of one leg."""
    return forces({"SPH": sph, "RFT": rft}, path, title=title,
                  styles={"SPH": {"color": "#d1495b"}, "RFT": {"color": "k", "ls": "--"}})


def _lift_thrust(curves, measured, path=None, title: str = ""):
    """Lift and thrust against the leg angle: ``curves`` [(theta deg, {"Fz": N, "Fx": N},
    plot keywords with the label)], ``measured`` {"Fz": (theta deg, N), "Fx": (...)} (Li 2013
    Fig. S5, drawn as dots)."""
    with plt.rc_context(STYLE):
        fig, axes = plt.subplots(1, 2, figsize=(7.0, 3.2), sharex=True, layout="constrained")
        for ax, comp, what in ((axes[0], "Fz", "lift $F_z$ (N)"), (axes[1], "Fx", "thrust $F_x$ (N)")):
            for th, f, kw in curves:
                ax.plot(th, f[comp], **kw)
            th, y = measured[comp]
            ax.plot(th, y, ".", color="0.45", ms=2.5, label="measured (Li 2013 Fig. S5)")
            ax.axhline(0, color="0.8", lw=0.6)
            ax.set_xlabel(r"leg angle $\theta$ (deg)")
            ax.set_ylabel(what)
            ax.set_xlim(-135, 135)
        fig.legend(*axes[0].get_legend_handles_labels(), frameon=False, fontsize=7.5,
                   loc="outside lower center", ncol=3)
        if title:
            fig.suptitle(title, fontsize=9)
        return _save(fig, path)


def leg_vs_measured(r: dict, path=None, title: str = ""):
    """One leg: SPH, RFT (measured grid, linear) and Li 2013 Fig. S5's measured curve, lift
    and thrust against the leg angle (:func:`terradyn.sph.suite.leg_vs_measured`)."""
    curves = [(r["sph"].theta, r["sph"], {"color": "#d1495b", "label": "SPH"}),
              (r["rft"].theta, r["rft"], {"color": "k", "ls": "--", "label": "RFT (Table S5, linear)"})]
    return _lift_thrust(curves, {c: (r[c]["theta"], r[c]["measured"]) for c in ("Fz", "Fx")},
                        path, title)


def rig_maps(r: dict, path=None, title: str = ""):
    """The virtual plate rig: SPH's alpha_z and alpha_x (N/cm^3) against the intrusion angle
    gamma, one line per attack angle beta, beside Li 2013 Table S5's measured values
    (:func:`terradyn.sph.suite.plate_rig`)."""
    betas = np.asarray(r["beta"])
    gam = np.degrees(np.asarray(r["gamma"]))
    colors = plt.cm.viridis(np.linspace(0, 0.9, len(betas)))
    with plt.rc_context(STYLE):
        fig, axes = plt.subplots(1, 2, figsize=(7.0, 3.0), sharex=True, layout="constrained")
        for ax, comp in ((axes[0], "z"), (axes[1], "x")):
            sim = np.asarray(r[f"alpha_{comp}"])
            mea = np.asarray(r[f"alpha_{comp}_measured"])
            for i, b in enumerate(betas):
                ax.plot(gam, sim[i], "-o", ms=2.5, color=colors[i],
                        label=rf"$\beta$ = {np.degrees(b):.0f}$^\circ$")
                ax.plot(gam, mea[i], ":", color=colors[i])
            ax.axhline(0, color="0.8", lw=0.6)
            ax.set_xlabel(r"intrusion angle $\gamma$ (deg)")
            ax.set_ylabel(rf"$\alpha_{comp}$ (N/cm$^3$)")
            ax.set_xlim(-90, 90)
        axes[0].plot([], [], "k-o", ms=2.5, label="SPH (solid)")
        axes[0].plot([], [], "k:", label="Li 2013 Table S5 (dotted)")
        fig.legend(*axes[0].get_legend_handles_labels(), frameon=False, fontsize=7,
                   loc="outside right center")
        if title:
            fig.suptitle(title, fontsize=9)
        return _save(fig, path)


def leg3d(points: list[dict], measured: dict, path=None, title: str = ""):
    """A leg in 3D (``benchmarks/sph_leg3d.py`` points: ``kind`` slab or finite, ``dx_mm``,
    ``theta_deg``, ``Fx_N``, ``Fz_N``; None past ``partial_to_deg`` for a run read part-way)
    beside the measured curve (``measured``: {"Fz": (theta deg, N), "Fx": (...)}), lift and
    thrust against the leg angle. Points at several spacings are labelled by spacing."""
    styles = {"finite": {"color": "#d1495b", "label": "SPH 3D, 2.54 cm wide leg"},
              "slab": {"color": "#30638e", "ls": "--", "label": "SPH 3D, plane-strain slab"}}
    spacings = sorted({p["dx_mm"] for p in points if p.get("dx_mm") is not None}, reverse=True)
    shades = ["#d1495b", "#edae49", "#00798c", "#30638e"]
    curves = []
    for p in points:
        kw = dict(styles[p["kind"]])
        if len(spacings) > 1 and p.get("dx_mm") is not None:  # short: the legend has 3 columns
            kw["label"] = (f"SPH 3D{' slab' if p['kind'] == 'slab' else ''}, "
                           f"{p['dx_mm']:g} mm particles")
            if p["kind"] == "finite":
                kw["color"] = shades[spacings.index(p["dx_mm"]) % len(shades)]
        if p.get("partial_to_deg") is not None:
            kw["label"] += f" (to {p['partial_to_deg']:.0f} deg)"
        curves.append((p["theta_deg"], {c: np.asarray(p[f"{c}_N"], float) for c in ("Fz", "Fx")},
                       kw))
    return _lift_thrust(curves, measured, path, title)
