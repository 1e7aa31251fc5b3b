"""What mu(I) does to the quasi-static tests: the plate and the flat leg with and without it.

Jop et al. 2006's mu(I) (``from_medium(..., rheology="mu-i")``) raises the friction where the
grains flow fast; the column collapse needs that (benchmarks/sph_column_walls.py). The plate
test (which calibrates each medium's static angle) and the slow rotating-leg tests must not
depend on it much, or the calibration and the leg checks would move. This runs, side by side
in one process, the plate-down test and the flat leg (hip 2 cm, -135..135 deg, Li 2013 Fig.
S5's media) with rate-independent friction, with mu(I), and with a control that changes
nothing physical (mu(I) with a rise of 1e-9: the same code path, a rounding-level difference
that gives another realization of the chaotic granular flow), at the leg speeds given, and
reports alpha_z (mean of two realizations), the peak lift and thrust and their ratios to the
rate-independent run, the stroke-mean forces and the RMS differences from the measured curves
(with RFT's beside them). The control's ratio is the run-to-run scatter that a mu(I) effect must
exceed to count.

    NUMBA_NUM_THREADS=1 python benchmarks/sph_mu_i.py [--dx-mm 4] [--omega 1.1 0.2]

A study, not a timing benchmark: writes benchmarks/results/sph_mu_i.json.
"""
from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

from terradyn.io import atomic_write_text
from terradyn.media import MEDIA
from terradyn.sph.calibration import plate_slope
from terradyn.sph.materials import from_medium
from terradyn.sph.suite import LEG_MEDIA, leg_vs_measured
from terradyn.units import N_PER_CM3

OUT = Path(__file__).parent / "results" / "sph_mu_i.json"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dx-mm", type=float, default=4.0)
    ap.add_argument("--omega", type=float, nargs="+", default=[1.1], help="leg speeds, rad/s")
    ap.add_argument("--media", nargs="+", default=list(LEG_MEDIA))
    ap.add_argument("--leg", default="flat", choices=["flat", "c", "reverse-c"])
    ap.add_argument("--no-plate", action="store_true")
    ap.add_argument("--out", type=Path, default=OUT)
    a = ap.parse_args()
    dx = a.dx_mm * 1e-3
    rows = []

    def emit(row):
        rows.append(row)
        print(json.dumps(row), flush=True)
        atomic_write_text(a.out, json.dumps({
            "command": "python benchmarks/sph_mu_i.py", "argv": sys.argv[1:], "dx_mm": a.dx_mm,
            "machine": platform.processor() or platform.machine(), "rows": rows}, indent=1))

    for m in a.media:
        mats = {rh: from_medium(m, rheology=rh) for rh in ("constant", "mu-i")}
        mats["control"] = mats["mu-i"].with_(mu_rise=1e-9)
        if not a.no_plate:
            r, wall = {}, {}
            for rh, mat in mats.items():
                t0 = time.perf_counter()
                r[rh] = plate_slope(mat, dx=dx, realizations=2)["alpha_z"] / N_PER_CM3
                wall[rh] = round(time.perf_counter() - t0, 1)
            emit({"test": "plate", "medium": m, "realizations": 2,
                  "alpha_z_N_cm3": r, "ratio_mu_i": r["mu-i"] / r["constant"],
                  "ratio_control": r["control"] / r["constant"],
                  "measured_N_cm3": MEDIA[m].alpha_z_plate / N_PER_CM3, "wall_s": wall})
        for om in a.omega:
            out = {}
            for rh, mat in mats.items():
                t0 = time.perf_counter()
                res = leg_vs_measured(a.leg, mat, omega=om, dx=dx)
                out[rh] = {c: res[c]["peak_sph"] for c in ("Fz", "Fx")}
                out[rh]["measured"] = {c: res[c]["peak_measured"] for c in ("Fz", "Fx")}
                out[rh]["mean"] = {c: float(res["sph"][c].mean()) for c in ("Fz", "Fx")}
                out[rh]["rms"] = {c: res[c]["rms_sph"] for c in ("Fz", "Fx")}
                out[rh]["rms_rft"] = {c: res[c]["rms_rft"] for c in ("Fz", "Fx")}
                out[rh]["wall_s"] = round(time.perf_counter() - t0, 1)
            emit({"test": f"{a.leg} leg", "medium": m, "omega_rad_s": om,
                  "peak_lift_N": {rh: out[rh]["Fz"] for rh in mats},
                  "peak_thrust_N": {rh: out[rh]["Fx"] for rh in mats},
                  **{f"ratio_{c}_{rh.replace('-', '_')}": out[rh][k] / out["constant"][k]
                     for c, k in (("lift", "Fz"), ("thrust", "Fx")) for rh in ("mu-i", "control")},
                  "stroke_mean_lift_N": {rh: out[rh]["mean"]["Fz"] for rh in mats},
                  "stroke_mean_thrust_N": {rh: out[rh]["mean"]["Fx"] for rh in mats},
                  "rms_lift_vs_measured_N": {rh: out[rh]["rms"]["Fz"] for rh in mats},
                  "rms_thrust_vs_measured_N": {rh: out[rh]["rms"]["Fx"] for rh in mats},
                  "rms_rft_lift_thrust_N": [out["constant"]["rms_rft"][c] for c in ("Fz", "Fx")],
                  "measured_lift_N": out["constant"]["measured"]["Fz"],
                  "measured_thrust_N": out["constant"]["measured"]["Fx"],
                  "wall_s": {rh: out[rh]["wall_s"] for rh in mats}})


if __name__ == "__main__":
    main()
