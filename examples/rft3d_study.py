"""3D-RFT study for docs/rft3d.md: the standard legs as 3D bodies against the 2D engine and Li
2013 Fig. S5, where speed starts to matter, the plate-drag form against the shipped SPH, and
figures of bodies with their element tractions.

Usage: python examples/rft3d_study.py [OUTDIR]   (default docs/figures; ~1 min on 2 cores)
Writes OUTDIR/rft3d_legs_vs_li2013.png, rft3d_speed_onset.png, rft3d_<body>.png and
OUTDIR/rft3d_study.json (the numbers quoted in docs/rft3d.md).
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import terradyn as td  # noqa: E402
from terradyn.plots import STYLE  # noqa: E402
from terradyn.rft3d import studies  # noqa: E402


def legs_figure(out: Path) -> None:
    meas = studies.measured_legs()
    mot = td.standard_rotation()
    with plt.rc_context(STYLE):
        fig, axes = plt.subplots(2, 6, figsize=(15, 5), sharex=True)
        for r, (medium, dm) in enumerate(meas.groupby("medium")):
            models = studies.leg_models(medium)
            models.pop("3D Agarwal, xi_n from friction")
            for c, shape in enumerate(studies.LEGS):
                curves = {k: f(shape, mot) for k, f in models.items()}
                for k, force in enumerate(("Fz", "Fx")):
                    ax = axes[r, 2 * c + k]
                    d = dm[(dm.leg == shape) & (dm.force == force)].sort_values("theta_deg")
                    ax.plot(d.theta_deg, d.force_N, "k.", ms=2, label="Li 2013 (measured)")
                    for name, (th, fx, fz) in curves.items():
                        ax.plot(th, fz if force == "Fz" else fx, label=name)
                    ax.set_title(f"{medium}, {shape}: {force}")
                    ax.set_xlabel(r"leg angle $\theta$ (deg)")
                    ax.set_ylabel(f"{force} (N)")
        axes[0, 0].legend(fontsize=6)
        fig.savefig(out, dpi=160)
        plt.close(fig)


def speed_figure(df, out: Path) -> None:
    with plt.rc_context(STYLE):
        fig, ax = plt.subplots(figsize=(5, 3.5))
        for shape, d in df.groupby("leg"):
            ax.semilogx(d.omega_rad_s, 100 * (d.peak_ratio - 1), label=f"{shape} leg")
        ax.axvline(df.attrs["froude_omega_rad_s"], color="0.4", ls=":", label=r"$\sqrt{g/L}$")
        ax.axhline(5, color="0.6", lw=0.6)
        ax.set_xlabel(r"rotation speed $\omega$ (rad/s)")
        ax.set_ylabel("peak |F| above quasi-static (%)")
        ax.set_title(r"dynamic RFT, 3 mm glass CP, $\lambda$ = 1.1")
        ax.legend()
        fig.savefig(out, dpi=160)
        plt.close(fig)


def main() -> None:
    out = Path(sys.argv[1] if len(sys.argv) > 1 else "docs/figures")
    out.mkdir(parents=True, exist_ok=True)
    table = studies.legs_vs_experiment()
    legs_figure(out / "rft3d_legs_vs_li2013.png")
    sp = studies.speed_onset()
    speed_figure(sp, out / "rft3d_speed_onset.png")
    sph = studies.plate_drag_vs_sph()
    from terradyn.api3d import rft3d_series
    from terradyn.plots_rft3d import body_tractions

    for body, kw in (("c", {}), ("foot", {"center_cm": "0,0,0.5", "angle_start_deg": 0.0,
                                          "angle_end_deg": 3.0, "n_angles": 31, "medium": "poppy LP"}),
                     ("wheel", {"center_cm": "0,0,4", "angle_start_deg": 0.0, "angle_end_deg": 90.0,
                                "n_angles": 31})):
        ds, frame, b = rft3d_series(body=body, want_frame=True, **kw)
        body_tractions(b, frame, ds, out / f"rft3d_{body}.png",
                       title=f"{b.name}, {kw.get('medium', '3 mm glass CP')} (Agarwal 3D-RFT)")
    summary = {
        "legs_vs_li2013": table.round(4).to_dict(orient="records"),
        "mean_rms_frac_by_model": table.groupby("model").rms_frac.mean().round(4).to_dict(),
        "speed_onset_rad_s": sp.attrs["onset"], "froude_rad_s": sp.attrs["froude_omega_rad_s"],
        "plate_drag_vs_sph": sph,
    }
    (out / "rft3d_study.json").write_text(json.dumps(summary, indent=2, default=float))
    print(table.pivot_table(index=["medium", "leg", "force"], columns="model", values="rms_frac").round(3).to_string())
    print(json.dumps({k: v for k, v in summary.items() if k != "legs_vs_li2013"}, indent=1, default=float))


if __name__ == "__main__":
    main()
