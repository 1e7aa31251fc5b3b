"""Is the SPH thrust deficit plane strain? The vertical plate pushed horizontally in 3D (issue 17).

Every leg's thrust in the 2D SPH is below Li 2013's measured curves, and the virtual plate
rig (``benchmarks/sph_rig.py``) shows the same deficit in the point that a leg's thrust rests
on: Li's plate held vertical (beta = pi/2) and pushed horizontally (gamma = 0), where the 2D
rig's alpha_x is 26-35 % below Table S5 in poppy LP and the 0.3 mm glass media while the
plate-down point (the calibration) matches. A plate 2.54 cm wide pushing grains ahead of it
lets the failed wedge spread sideways, which a strip (plane strain) cannot. This study runs
that one rig point with the same physics in 3D (:func:`terradyn.sph.plate3d.plate_drag3d`):

* ``slab``: the plane-strain configuration in the 3D code (the plate spans a slab between
  two frictionless planes): the check that the 3D code reproduces the 2D rig;
* ``finite``: Li's 3.81 x 2.54 cm plate (half domain, symmetry plane y = 0);

beside the 2D rig's value (``benchmarks/results/sph_rig_<medium>.json``) and the measured
one (Li 2013 Table S5, the rig's source).

    NUMBA_NUM_THREADS=1 python benchmarks/sph_plate_drag3d.py [--points MEDIUM:KIND ...]
        [--dx-mm 4] [--out FILE]

Writes benchmarks/results/sph_plate_drag3d.json after every point (resumable: finished points
are kept and skipped). A study, not a timing benchmark: wall times are as run.
"""
from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import numpy as np

from terradyn.io import atomic_write_text
from terradyn.sph.materials import from_medium
from terradyn.sph.plate3d import plate_drag3d
from terradyn.sph.state import SPHConfig
from terradyn.units import DEG, N_PER_CM3

RES = Path(__file__).parent / "results"
OUT = RES / "sph_plate_drag3d.json"
DEFAULT = ["poppy LP:slab", "poppy LP:finite", "0.3 mm glass LP:slab", "0.3 mm glass LP:finite"]
#: Slab thickness (particles in y) of the plane-strain configuration.
SLAB = 6


def rig_2d(medium: str) -> dict:
    """The 2D rig's and the measured alpha at beta = pi/2, gamma = 0 (N/cm^3)."""
    f = RES / f"sph_rig_{medium.replace(' ', '_')}.json"
    if not f.exists():
        return {}
    d = json.loads(f.read_text())
    ib = int(np.argmin(np.abs(np.array(d["beta"]) - np.pi / 2)))
    ig = int(np.argmin(np.abs(np.array(d["gamma"]))))
    return {"alpha_x_2d_rig": d["alpha_x"][ib][ig], "alpha_z_2d_rig": d["alpha_z"][ib][ig],
            "alpha_x_measured": d["alpha_x_measured"][ib][ig],
            "alpha_z_measured": d["alpha_z_measured"][ib][ig],
            "rig_dx_mm": d["settings"]["dx_mm"], "rig_friction_deg": d["settings"]["friction_deg"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", nargs="+", default=DEFAULT, help="MEDIUM:KIND, KIND slab|finite")
    ap.add_argument("--dx-mm", type=float, default=4.0)
    ap.add_argument("--out", type=Path, default=OUT)
    a = ap.parse_args()
    res = (json.loads(a.out.read_text()) if a.out.exists()
           else {"machine": platform.processor() or platform.machine(), "points": []})
    done = {(p["medium"], p["kind"], p["dx_mm"]) for p in res["points"]}
    for spec in a.points:
        medium, kind = spec.rsplit(":", 1)
        if kind not in ("slab", "finite"):
            raise SystemExit(f"error: --points: kind must be slab or finite, got {kind!r}")
        if (medium, kind, a.dx_mm) in done:
            continue
        mat = from_medium(medium)
        t0 = time.perf_counter()
        r = plate_drag3d(mat, config=SPHConfig(dx=a.dx_mm * 1e-3),
                         slab=SLAB if kind == "slab" else None)
        p = {"medium": medium, "kind": kind, "dx_mm": a.dx_mm,
             "friction_deg": round(mat.friction / DEG, 3), "youngs_MPa": mat.youngs / 1e6,
             "alpha_x_N_cm3": round(r["alpha_x"] / N_PER_CM3, 4),
             "alpha_z_N_cm3": round(r["alpha_z"] / N_PER_CM3, 4),
             "fx_N": np.round(r["fx_N"], 4).tolist(), "fz_N": np.round(r["fz_N"], 4).tolist(),
             "time_s": np.round(r["time"], 4).tolist(), "particles": r["particles"],
             "steps": r["steps"], "lost": r["lost"], "wall_s": round(time.perf_counter() - t0, 1),
             **rig_2d(medium)}
        res["points"].append(p)
        atomic_write_text(a.out, json.dumps(res, indent=1))
        print(json.dumps({k: v for k, v in p.items() if k not in ("fx_N", "fz_N", "time_s")}),
              flush=True)


if __name__ == "__main__":
    main()
