"""Grain-leg friction (issue 17, build item 3): what the Coulomb cap on the leg's surface
(``SPHConfig.leg_friction``, ``--leg-friction-deg``) does to the rig's sliding plate.

Li 2013's small plate (3.81 x 2.54 x 0.64 cm) dragged along itself at 3 cm depth (Table S5's
beta = 0, gamma = 0 point: the friction on its two faces plus the push on its 0.64 cm nose),
in each medium at its shipped (plate-calibrated) friction angle, with the rough (no-slip)
default leg and with grain-leg friction angles from 0 deg up; the measured alpha_x and
alpha_z there beside it. The brief gives no measured grain-plate friction for Li's plate or
legs, so nothing here calibrates anything: it shows how far the surface friction moves the
one rig point where it matters most.

    python benchmarks/sph_leg_friction.py [--media M ...] [--angles 0 10 20 30]
        [--realizations 2] [--dx-mm 4] [--threads 1] [--figure docs/figures/sph_leg_friction.png]

Writes benchmarks/results/sph_leg_friction.json when every point is done; each finished
point is kept in benchmarks/results/sph_leg_friction.partial.json, so an interrupted study
resumes (``--out FILE``: another result file, its partial file beside it). ``--offsets-um``
instead of ``--realizations``: one run per sub-particle start offset of the plate (docs/sph.md,
"Run-to-run scatter"). A study, not a timing benchmark (the wall time of each point is
recorded).

    python benchmarks/sph_leg_friction.py --legs "poppy LP:flat" ... [--leg-angles 0 20]

instead runs those legs in the rotating-leg test as the validation does (2.5 mm, omega
1.1 rad/s, 6 cm bed, one run; each finished run kept in .sph-runs) with each grain-leg
friction angle, scored against Li 2013 Fig. S5 (benchmarks/results/sph_leg_friction_legs.json;
the rough leg's single runs are in sph_legs_single_runs.json).

    python benchmarks/sph_leg_friction.py --plate "poppy LP" [--leg-angles 0 20]

runs the plate test (pushed straight down, the calibration's scene, 2.5 mm, two runs) rough
and with each grain-leg friction angle (benchmarks/results/sph_leg_friction_plate.json): the
plate-calibrated friction angle depends on the plate's surface friction."""
from __future__ import annotations

import argparse
import json
import math
import os
import time
from pathlib import Path

RES = Path(__file__).parent / "results"
MEDIA = ("poppy LP", "poppy CP", "0.3 mm glass LP", "0.3 mm glass CP", "3 mm glass CP")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--media", nargs="+", default=list(MEDIA))
    ap.add_argument("--angles", nargs="+", type=float, default=[0.0, 10.0, 20.0, 30.0],
                    help="grain-leg friction angles, deg (the rough leg is always run)")
    ap.add_argument("--realizations", type=int, help="runs a point, 10 nm apart (default 2)")
    ap.add_argument("--offsets-um", nargs="+", type=float,
                    help="instead of --realizations: one run per start offset of the plate "
                         "(um, upward; a fraction of a particle spacing samples the flow, "
                         "10 nm does not at this point)")
    ap.add_argument("--dx-mm", type=float, default=4.0)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--figure", type=Path)
    ap.add_argument("--out", type=Path, default=RES / "sph_leg_friction.json",
                    help="the rig study's result file (its partial file beside it)")
    ap.add_argument("--legs", nargs="+", help='"MEDIUM:LEG" pairs: run the leg test instead')
    ap.add_argument("--leg-angles", nargs="+", type=float, default=[0.0, 20.0])
    ap.add_argument("--plate", nargs="+", help="media: run the plate test instead")
    a = ap.parse_args()
    if a.offsets_um is not None and a.realizations is not None:
        ap.error("--offsets-um and --realizations: give one of them (the offsets are the runs)")
    if a.offsets_um is not None and (len(a.offsets_um) < 2 or any(x < 0 for x in a.offsets_um)):
        ap.error("--offsets-um: at least two offsets, each >= 0 um")
    a.realizations = 2 if a.realizations is None else a.realizations
    os.environ["NUMBA_NUM_THREADS"] = str(a.threads)  # before numba is imported
    if a.legs:
        return legs(a)
    if a.plate:
        return plates(a)

    import numpy as np

    from terradyn.io import atomic_write_text
    from terradyn.media import stress_model
    from terradyn.sph.materials import from_medium
    from terradyn.sph.state import SPHConfig
    from terradyn.sph.suite import rig_point
    from terradyn.units import DEG, G, N_PER_CM3

    dx = a.dx_mm * 1e-3
    settings = {"dx_mm": a.dx_mm, "media": a.media, "angles_deg": a.angles,
                "realizations": a.realizations, "threads": a.threads,
                **({"offsets_um": a.offsets_um} if a.offsets_um else {}),
                "command": "python benchmarks/sph_leg_friction.py --media "
                           + " ".join(f'"{m}"' for m in a.media) + " --angles "
                           + " ".join(f"{x:g}" for x in a.angles)
                           + (" --offsets-um " + " ".join(f"{x:g}" for x in a.offsets_um) if a.offsets_um
                              else f" --realizations {a.realizations}") + f" --dx-mm {a.dx_mm:g}"
                           + ("" if a.out == RES / "sph_leg_friction.json" else f" --out {a.out}")}
    final = a.out
    partial = final.with_name(final.stem + ".partial.json")
    done = {}
    for f in (final, partial):  # a finished study only redraws; an unfinished one resumes
        old = json.loads(f.read_text()) if f.exists() else {}
        if old.get("settings") == settings and "points" in old:
            done = old["points"]
            print(f"reading {f.name}: {len(done)} points done", flush=True)
    cases = [None] + list(a.angles)
    rows = []
    for m in a.media:
        mat = from_medium(m)
        mx, mz = stress_model(m, "table").alpha(0.0, 0.0)
        row = {"medium": m, "friction_deg": round(mat.friction / DEG, 3),
               "density_kg_m3": mat.density,
               "alpha_x_measured": float(mx) / N_PER_CM3, "alpha_z_measured": float(mz) / N_PER_CM3,
               "cases": []}
        for ang in cases:
            runs = []
            # rig_point's realization k starts the plate k x 10 nm higher
            starts = ([(f"off{x:g}um", round(100 * x)) for x in a.offsets_um] if a.offsets_um
                      else [(str(r), r) for r in range(a.realizations)])
            for tag, r in starts:
                key = f"{m}|{'rough' if ang is None else f'{ang:g}'}|{tag}"
                if key not in done:
                    cfg = SPHConfig(dx=dx, leg_friction=None if ang is None else ang * DEG)
                    t0 = time.perf_counter()
                    az, ax = rig_point(mat, 0.0, 0.0, dx=dx, config=cfg, realization=r)
                    done[key] = {"alpha_z": az / N_PER_CM3, "alpha_x": ax / N_PER_CM3,
                                 "wall_s": round(time.perf_counter() - t0, 1)}
                    atomic_write_text(partial, json.dumps({"settings": settings, "points": done},
                                                          indent=1))
                    print(key, done[key], flush=True)
                runs.append(done[key])
            axs = [p["alpha_x"] for p in runs]
            azs = [p["alpha_z"] for p in runs]
            mu = None if ang is None else math.tan(ang * DEG)
            row["cases"].append({
                "leg_friction_deg": ang, "alpha_x": float(np.mean(axs)),
                "alpha_x_runs": axs, "alpha_x_std": float(np.std(axs, ddof=1)) if len(axs) > 1 else None,
                "alpha_z": float(np.mean(azs)), "alpha_z_runs": azs,
                "alpha_x_over_measured": float(np.mean(axs)) / row["alpha_x_measured"],
                # both faces at the geostatic stress of the plate's centre depth
                "faces_geostatic_N_per_cm3": (None if mu is None
                                              else 2.0 * mu * mat.density * G / N_PER_CM3)})
        rows.append(row)
    out = {"settings": settings, "point": {"beta_rad": 0.0, "gamma_rad": 0.0, "depth_m": 0.03},
           "rows": rows, "points": done}
    atomic_write_text(final, json.dumps(out, indent=1))
    partial.unlink(missing_ok=True)
    for row in rows:
        cs = ", ".join(("rough" if c["leg_friction_deg"] is None else f"{c['leg_friction_deg']:g} deg")
                       + f" {c['alpha_x']:.4f}" for c in row["cases"])
        print(f"{row['medium']} (phi {row['friction_deg']:g}): measured alpha_x "
              f"{row['alpha_x_measured']:.4f} N/cm^3; SPH {cs}")
    if a.figure:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(6.4, 4.2))
        for k, row in enumerate(rows):
            col = f"C{k}"
            cs = [c for c in row["cases"] if c["leg_friction_deg"] is not None]
            bars = a.offsets_um is not None  # the runs sample the flow: show their spread
            ax.errorbar([c["leg_friction_deg"] for c in cs], [c["alpha_x"] for c in cs],
                        yerr=[c["alpha_x_std"] for c in cs] if bars else None, fmt="o-", capsize=3,
                        color=col, label=f"{row['medium']} (phi = {row['friction_deg']:.1f} deg)")
            r0 = row["cases"][0]
            ax.errorbar([max(a.angles) + 8], [r0["alpha_x"]], yerr=[r0["alpha_x_std"]] if bars else None,
                        fmt="s", color=col, mfc="none", capsize=3)
            ax.axhline(row["alpha_x_measured"], color=col, ls=":", lw=1)
        ax.set_xticks(list(a.angles) + [max(a.angles) + 8])
        ax.set_xticklabels([f"{x:g}" for x in a.angles] + ["rough"])
        ax.set_xlabel("grain-leg friction angle (deg)")
        ax.set_ylabel(r"$\alpha_x(\beta=0, \gamma=0)$ (N/cm$^3$)")
        runs = (f"mean and std of {len(a.offsets_um)} start offsets" if a.offsets_um
                else f"mean of {a.realizations}")
        ax.set_title(f"Rig plate dragged along itself, 3 cm deep (SPH, {a.dx_mm:g} mm, {runs});\n"
                     "open squares: rough (no-slip) leg; dotted: measured (Li 2013 Table S5)",
                     fontsize=8)
        ax.legend(fontsize=7, loc="upper left")
        fig.tight_layout()
        fig.savefig(a.figure, dpi=200)
        print(f"wrote {a.figure}")


def legs(a) -> None:
    """The rotating-leg test with each grain-leg friction angle (see the module docstring)."""
    from terradyn.io import atomic_write_text
    from terradyn.sph.state import SPHConfig
    from terradyn.sph.suite import leg_vs_measured
    from terradyn.units import DEG

    out_file = RES / "sph_leg_friction_legs.json"
    old = json.loads(out_file.read_text()) if out_file.exists() else {"runs": []}
    rows = [r for r in old["runs"]]
    for pair in a.legs:
        medium, leg = pair.split(":")
        for ang in a.leg_angles:
            if any(r["medium"] == medium and r["leg"] == leg and r["leg_friction_deg"] == ang
                   for r in rows):
                continue
            cfg = SPHConfig(dx=2.5e-3, leg_friction=ang * DEG)
            t0 = time.perf_counter()
            r = leg_vs_measured(leg, medium, omega=1.1, config=cfg, store=".sph-runs")
            row = {"medium": medium, "leg": leg, "leg_friction_deg": ang, "dx_mm": 2.5,
                   "omega": 1.1, "wall_s": round(time.perf_counter() - t0, 1)}
            for comp, nm in (("Fz", "lift"), ("Fx", "thrust")):
                c = r[comp]
                row[f"peak_{nm}_N"] = round(c["peak_sph"], 4)
                row[f"peak_{nm}_measured_N"] = round(c["peak_measured"], 4)
                row[f"peak_{nm}_rel"] = round(c["peak_sph"] / c["peak_measured"] - 1.0, 4)
                row[f"rms_{nm}_N"] = round(c["rms_sph"], 4)
                row[f"rms_{nm}_rft_N"] = round(c["rms_rft"], 4)
            rows.append(row)
            atomic_write_text(out_file, json.dumps({"command": "python benchmarks/sph_leg_friction.py --legs ...",
                                                    "runs": rows}, indent=1))
            print(row, flush=True)


def plates(a) -> None:
    """The plate test, rough and with each grain-leg friction angle (module docstring)."""
    from terradyn.io import atomic_write_text
    from terradyn.sph.calibration import plate_slope
    from terradyn.sph.materials import from_medium
    from terradyn.sph.state import SPHConfig
    from terradyn.units import DEG, N_PER_CM3

    out_file = RES / "sph_leg_friction_plate.json"
    old = json.loads(out_file.read_text()) if out_file.exists() else {"runs": []}
    rows = list(old["runs"])
    for medium in a.plate:
        mat = from_medium(medium)
        for ang in [None] + list(a.leg_angles):
            if any(r["medium"] == medium and r["leg_friction_deg"] == ang for r in rows):
                continue
            t0 = time.perf_counter()
            r = plate_slope(mat, dx=2.5e-3, realizations=2,
                            config=SPHConfig(dx=2.5e-3, leg_friction=None if ang is None else ang * DEG))
            rows.append({"medium": medium, "friction_deg": round(mat.friction / DEG, 3),
                         "leg_friction_deg": ang, "dx_mm": 2.5, "realizations": 2,
                         "alpha_z_N_per_cm3": r["alpha_z"] / N_PER_CM3,
                         "wall_s": round(time.perf_counter() - t0)})
            atomic_write_text(out_file, json.dumps({"command": "python benchmarks/sph_leg_friction.py --plate ...",
                                                    "runs": rows}, indent=1))
            print(rows[-1], flush=True)


if __name__ == "__main__":
    main()
