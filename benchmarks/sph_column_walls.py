"""Column collapse in Lube et al. 2005's quasi-2D channel: what the side walls do.

The 2D SPH column (3 mm glass CP at its plate-calibrated friction angle) in plane strain
without walls, and between side walls 10 cm apart (Lube et al.'s channel) whose Coulomb
friction is pressed by the out-of-plane stress (``SPHConfig(channel_width=...)``, docs/sph.md
scene 2), at grain-wall friction angles from 0 to the medium's own, at a = 0.5, 1, 2, 4 and
two or three resolutions, with rate-independent friction and with Jop et al. 2006's mu(I)
(``from_medium(..., rheology="mu-i")``: the same static angle, friction rising with the
inertial number in flow). Final height H_f / H_i and run-out (L_f - L_i) / L_i against Lube's
fits (walls) and the plane-strain MPM's 2.28 a (no walls).

    NUMBA_NUM_THREADS=1 python benchmarks/sph_column_walls.py [--dx-mm 4 2.5 2] [--out FILE]

A study, not a timing benchmark: writes benchmarks/results/sph_column_walls.json.
"""
from __future__ import annotations

import argparse
import json
import math
import platform
import sys
import time
from pathlib import Path

from terradyn.io import atomic_write_text
from terradyn.sph.materials import from_medium
from terradyn.sph.validation import LUBE2005_CHANNEL, column_collapse

OUT = Path(__file__).parent / "results" / "sph_column_walls.json"
MEDIUM = "3 mm glass CP"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dx-mm", type=float, nargs="+", default=[4.0, 2.5])
    ap.add_argument("--aspects", type=float, nargs="+", default=[0.5, 1.0, 2.0, 4.0])
    ap.add_argument("--wall-friction-deg", type=float, nargs="+",
                    help="grain-wall friction angles (default: 0, half and all of the medium's)")
    ap.add_argument("--rheology", nargs="+", default=["constant", "mu-i"],
                    choices=["constant", "mu-i"])
    ap.add_argument("--dilatancy-deg", type=float, nargs="+", default=[0.0],
                    help="an experiment: dilatancy angles psi (deg) with the calibrated phi")
    ap.add_argument("--critical-density-kg-m3", type=float,
                    help="where dilation stops (needed with --dilatancy-deg)")
    ap.add_argument("--out", type=Path, default=OUT)
    a = ap.parse_args()
    phi = math.degrees(from_medium(MEDIUM).friction)
    mats = {(rh, psi): from_medium(MEDIUM, rheology=rh) for rh in a.rheology
            for psi in a.dilatancy_deg}
    mats = {(rh, psi): m.with_(dilatancy=math.radians(psi), critical_density=a.critical_density_kg_m3)
            if psi else m for (rh, psi), m in mats.items()}
    walls = a.wall_friction_deg if a.wall_friction_deg else [0.0, round(phi / 2, 3), round(phi, 3)]
    rows = []
    for (rh, psi), dx, asp, mw in ((k, dx, asp, mw) for k in mats for dx in a.dx_mm
                                   for asp in a.aspects for mw in [None] + walls):
        t0 = time.perf_counter()
        r = column_collapse(asp, mats[rh, psi], base=0.06, dx=dx * 1e-3,
                            channel_width=None if mw is None else LUBE2005_CHANNEL,
                            wall_friction=None if mw is None else math.radians(mw))
        row = {"rheology": rh, "dilatancy_deg": psi,
               "critical_density_kg_m3": a.critical_density_kg_m3, "dx_mm": dx, "aspect": asp,
               "channel_width_m": None if mw is None else LUBE2005_CHANNEL,
               "wall_friction_deg": mw, "H_f_over_H_i": round(r["height"] / asp, 4),
               "runout": round(r["runout"], 4), "runout_lube": round(r["runout_lube"], 4),
               "runout_plane_strain_mpm": r["runout_plane_strain_mpm"],
               "deposit_slope_deg": round(r["deposit_slope_deg"], 2),
               "height_bound_no_walls": round(r["height_bound"], 4),
               "p95_speed_m_s": r["p95_speed"], "wall_s": round(time.perf_counter() - t0, 1)}
        rows.append(row)
        print(json.dumps(row), flush=True)
    res = {"command": "python benchmarks/sph_column_walls.py", "argv": sys.argv[1:], "medium": MEDIUM,
           "friction_deg": round(phi, 3), "base_m": 0.06,
           "machine": platform.processor() or platform.machine(), "rows": rows}
    atomic_write_text(a.out, json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
