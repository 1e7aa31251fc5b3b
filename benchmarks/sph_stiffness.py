"""Stiffness convergence of the SPH plate test (issue 17): alpha_z(0, pi/2) of the five media of
Li 2013 for numerical Young's moduli E = 0.25, 1 and 4 MPa; with ``--legs``, also the legs'
peaks in the rotating-leg test (``terradyn.sph.suite.leg_vs_measured``, omega 1.1 rad/s).

    python benchmarks/sph_stiffness.py [--dx-mm 4] [--realizations 2] [--youngs-mpa 0.25 1 4]
        [--friction repose|calibrated] [--media M ...] [--legs flat ...] [--no-plate]

Writes benchmarks/results/sph_stiffness.json after every plate test (resumable: finished
points are kept and skipped). A study, not a timing benchmark; wall times are recorded as
run (the machine may be busy)."""
from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

from terradyn.io import atomic_write_text
from terradyn.media import MEDIA
from terradyn.sph.calibration import plate_slope
from terradyn.sph.materials import from_medium
from terradyn.sph.state import SPHConfig
from terradyn.sph.suite import leg_vs_measured
from terradyn.sph.validation import alpha_z_plate_measured
from terradyn.units import N_PER_CM3

OUT = Path(__file__).parent / "results" / "sph_stiffness.json"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dx-mm", type=float, default=4.0)
    ap.add_argument("--realizations", type=int, default=2)
    ap.add_argument("--youngs-mpa", type=float, nargs="+", default=[0.25, 1.0, 4.0])
    ap.add_argument("--media", nargs="+", default=list(MEDIA))
    ap.add_argument("--friction", choices=["repose", "calibrated"], default="repose",
                    help="friction angle: the angle of repose or the shipped plate calibration")
    ap.add_argument("--legs", nargs="*", default=[], help="legs to run in the leg test as well")
    ap.add_argument("--no-plate", action="store_true", help="legs only")
    ap.add_argument("--out", type=Path, default=OUT, help="results file (one per concurrent job)")
    a = ap.parse_args()
    out = a.out
    res = json.loads(out.read_text()) if out.exists() else {"machine": platform.processor() or platform.machine(), "points": []}
    res.setdefault("legs", [])
    done = {(p["medium"], p["youngs_MPa"], p["dx_mm"], p.get("friction", "repose")) for p in res["points"]}
    done_legs = {(p["medium"], p["leg"], p["youngs_MPa"], p["dx_mm"], p["friction"]) for p in res["legs"]}
    for e in a.youngs_mpa:
        for medium in a.media:
            mat = from_medium(medium, youngs=e * 1e6, friction=a.friction)
            for leg in a.legs:
                if (medium, leg, e, a.dx_mm, a.friction) in done_legs:
                    continue
                t0 = time.perf_counter()
                r = leg_vs_measured(leg, mat, omega=1.1, dx=a.dx_mm * 1e-3)
                q = {"medium": medium, "leg": leg, "youngs_MPa": e, "dx_mm": a.dx_mm,
                     "friction": a.friction, "omega_rad_s": 1.1,
                     "friction_deg": round(mat.friction * 57.29577951308232, 3)}
                for comp in ("Fz", "Fx"):
                    c = r[comp]
                    q[comp] = {k: round(c[k], 4) for k in ("peak_sph", "peak_measured", "peak_rft",
                                                            "rms_sph", "rms_rft")}
                q["wall_s"] = round(time.perf_counter() - t0, 1)
                res["legs"].append(q)
                atomic_write_text(out, json.dumps(res, indent=1))
                print(json.dumps(q), flush=True)
            key = (medium, e, a.dx_mm, a.friction)
            if key in done or a.no_plate:
                continue
            r = plate_slope(mat, config=SPHConfig(dx=a.dx_mm * 1e-3), realizations=a.realizations)
            p = {"medium": medium, "youngs_MPa": e, "dx_mm": a.dx_mm, "friction": a.friction,
                 "friction_deg": round(mat.friction * 57.29577951308232, 3),
                 "alpha_z_origin_N_cm3": round(r["alpha_z"] / N_PER_CM3, 4),
                 "alphas_N_cm3": [round(x / N_PER_CM3, 4) for x in r["alphas"]],
                 "slope_free_N_cm3": round(r["slope"] / N_PER_CM3, 4),
                 "intercept_kPa": round(r["intercept_Pa"] / 1e3, 3),
                 "measured_N_cm3": alpha_z_plate_measured(medium) / N_PER_CM3,
                 "wall_s": round(r["wall_s"], 1)}
            res["points"].append(p)
            atomic_write_text(out, json.dumps(res, indent=1))
            print(json.dumps(p), flush=True)


if __name__ == "__main__":
    main()
