"""Where does the SPH leg's speed dependence come from? Peaks at two speeds, with and without
the artificial viscosity.

The material law is rate-independent (Drucker-Prager) and the leg's inertial stress is tiny
(rho (omega L)^2 is 0.5 % of the bearing stress at 1.1 rad/s), yet the flat leg's peaks were
measured 6-17 % higher at the validation's 1.1 rad/s than at the standard 0.2 rad/s
(docs/sph.md, "Convergence"). The one velocity-proportional term of the model is Monaghan's
artificial viscosity between granular particles (alpha = 0.1; its stress ~ alpha rho c h
|grad v| grows with the speed). This study runs the same leg at each speed with the preset
alpha and with the ones given, side by side: if the speed effect is the viscosity's, it
shrinks with alpha.

    NUMBA_NUM_THREADS=1 python benchmarks/sph_rate.py [--medium "poppy LP"] [--dx-mm 4]
        [--leg flat] [--omega 0.2 1.1] [--av-alpha 0.1 0.03 0] [--plate] [--realizations 1]

Writes ``benchmarks/results/sph_rate.json`` after every run; finished runs are skipped on a
rerun (interrupt and resume). A study: wall times are as run.
"""
from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

OUT = Path(__file__).parent / "results" / "sph_rate.json"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--medium", default="poppy LP")
    ap.add_argument("--dx-mm", type=float, default=4.0)
    ap.add_argument("--leg", default="flat", choices=("flat", "c", "reverse-c"))
    ap.add_argument("--omega", type=float, nargs="+", default=[0.2, 1.1])
    ap.add_argument("--av-alpha", type=float, nargs="+", default=[0.1, 0.03, 0.0])
    ap.add_argument("--plate", action="store_true",
                    help="also the plate test (the calibration, Table S3) at each alpha, two runs")
    ap.add_argument("--realizations", type=int, default=1, help="leg runs averaged (mean curve)")
    a = ap.parse_args()

    from terradyn.io import atomic_write_text
    from terradyn.sph import SPHConfig
    from terradyn.sph.calibration import plate_slope
    from terradyn.sph.materials import MATERIALS
    from terradyn.sph.state import SPHInstabilityError
    from terradyn.sph.suite import leg_vs_measured
    from terradyn.units import N_PER_CM3

    res = json.loads(OUT.read_text()) if OUT.exists() else {
        "machine": platform.platform(), "command": "python benchmarks/sph_rate.py", "runs": {}}
    rsuf = f"|r{a.realizations}" if a.realizations > 1 else ""
    for av in a.av_alpha:
        cfg = SPHConfig(dx=a.dx_mm * 1e-3, av_alpha=av)
        pkey = f"plate|{a.medium}|{a.dx_mm:g}mm|av{av:g}"
        if a.plate and pkey not in res["runs"]:
            t0 = time.perf_counter()
            r = plate_slope(MATERIALS[a.medium], config=cfg, realizations=2)
            res["runs"][pkey] = {"scene": "plate", "medium": a.medium, "dx_mm": a.dx_mm, "av_alpha": av,
                                 "alpha_z_N_cm3": r["alpha_z"] / N_PER_CM3,
                                 "alphas_N_cm3": [x / N_PER_CM3 for x in r["alphas"]],
                                 "wall_s": round(time.perf_counter() - t0, 1)}
            atomic_write_text(OUT, json.dumps(res, indent=1) + "\n")
            print(pkey, res["runs"][pkey]["alphas_N_cm3"], flush=True)
        for om in a.omega:
            key = f"{a.leg}|{a.medium}|{a.dx_mm:g}mm|omega{om:g}|av{av:g}{rsuf}"
            if key in res["runs"]:
                continue
            t0 = time.perf_counter()
            row = {"leg": a.leg, "medium": a.medium, "dx_mm": a.dx_mm, "omega": om, "av_alpha": av}
            try:
                r = leg_vs_measured(a.leg, MATERIALS[a.medium], omega=om, dx=cfg.dx, config=cfg,
                                    realizations=a.realizations)
                row |= {"realizations": a.realizations, "peaks_runs_lift_N": r["Fz"]["peaks_runs"],
                        "peaks_runs_thrust_N": r["Fx"]["peaks_runs"],
                        "peak_lift_N": r["Fz"]["peak_sph"], "peak_thrust_N": r["Fx"]["peak_sph"],
                        "rms_lift_N": r["Fz"]["rms_sph"], "rms_thrust_N": r["Fx"]["rms_sph"],
                        "measured_peak_lift_N": r["Fz"]["peak_measured"],
                        "measured_peak_thrust_N": r["Fx"]["peak_measured"]}
            except SPHInstabilityError as e:
                row["unstable"] = str(e)
            row["wall_s"] = round(time.perf_counter() - t0, 1)
            res["runs"][key] = row
            atomic_write_text(OUT, json.dumps(res, indent=1) + "\n")
            print(key, {k: row[k] for k in row if k.startswith(("peak", "unstable", "wall"))}, flush=True)
    # the speed effect at each alpha: peak at the fastest speed over the slowest
    lo, hi = min(a.omega), max(a.omega)
    for av in a.av_alpha if hi > lo else ():
        r0 = res["runs"].get(f"{a.leg}|{a.medium}|{a.dx_mm:g}mm|omega{lo:g}|av{av:g}{rsuf}", {})
        r1 = res["runs"].get(f"{a.leg}|{a.medium}|{a.dx_mm:g}mm|omega{hi:g}|av{av:g}{rsuf}", {})
        if "peak_lift_N" in r0 and "peak_lift_N" in r1:
            print(f"alpha {av:g}: omega {hi:g} / {lo:g} rad/s: lift x{r1['peak_lift_N'] / r0['peak_lift_N']:.3f}, "
                  f"thrust x{r1['peak_thrust_N'] / r0['peak_thrust_N']:.3f}")


if __name__ == "__main__":
    main()
