"""Stiffness convergence of the SPH plate test (issue 17): alpha_z(0, pi/2) of the five media of
Li 2013 at the angle of repose for numerical Young's moduli E = 0.25, 1 and 4 MPa.

    python benchmarks/sph_stiffness.py [--dx-mm 4] [--realizations 2] [--youngs-mpa 0.25 1 4]

Writes benchmarks/results/sph_stiffness.json after every plate test (resumable: finished
points are kept and skipped). A study, not a timing benchmark; wall times are recorded as
run (the machine may be busy)."""
from __future__ import annotations

import argparse
import json
import platform
from pathlib import Path

from terradyn.io import atomic_write_text
from terradyn.media import MEDIA
from terradyn.sph.calibration import plate_slope
from terradyn.sph.materials import from_medium
from terradyn.sph.state import SPHConfig
from terradyn.sph.validation import alpha_z_plate_measured
from terradyn.units import N_PER_CM3

OUT = Path(__file__).parent / "results" / "sph_stiffness.json"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dx-mm", type=float, default=4.0)
    ap.add_argument("--realizations", type=int, default=2)
    ap.add_argument("--youngs-mpa", type=float, nargs="+", default=[0.25, 1.0, 4.0])
    ap.add_argument("--media", nargs="+", default=list(MEDIA))
    a = ap.parse_args()
    res = json.loads(OUT.read_text()) if OUT.exists() else {"machine": platform.processor() or platform.machine(), "points": []}
    done = {(p["medium"], p["youngs_MPa"], p["dx_mm"]) for p in res["points"]}
    for e in a.youngs_mpa:
        for medium in a.media:
            key = (medium, e, a.dx_mm)
            if key in done:
                continue
            mat = from_medium(medium, youngs=e * 1e6)
            r = plate_slope(mat, config=SPHConfig(dx=a.dx_mm * 1e-3), realizations=a.realizations)
            p = {"medium": medium, "youngs_MPa": e, "dx_mm": a.dx_mm,
                 "friction_deg": round(mat.friction * 57.29577951308232, 3),
                 "alpha_z_origin_N_cm3": round(r["alpha_z"] / N_PER_CM3, 4),
                 "alphas_N_cm3": [round(x / N_PER_CM3, 4) for x in r["alphas"]],
                 "slope_free_N_cm3": round(r["slope"] / N_PER_CM3, 4),
                 "intercept_kPa": round(r["intercept_Pa"] / 1e3, 3),
                 "measured_N_cm3": alpha_z_plate_measured(medium) / N_PER_CM3,
                 "wall_s": round(r["wall_s"], 1)}
            res["points"].append(p)
            atomic_write_text(OUT, json.dumps(res, indent=1))
            print(json.dumps(p), flush=True)


if __name__ == "__main__":
    main()
