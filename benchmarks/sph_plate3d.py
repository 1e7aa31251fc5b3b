"""Is the 2D SPH plate test low because it is 2D? The plate test (issue 17) in 3D.

For each medium: the 2D solver's plate alpha_z (``terradyn.sph.calibration.plate_slope``), the
3D code in the plane-strain configuration (a slab between two frictionless planes, the plate
spanning it: the cross-check that the 3D code is the 2D physics), and the finite 3.81 x 2.54 cm
plate of Li 2013 (quarter domain), against the measured Table S3 value, with the ratio 3D / 2D
beside the bearing-capacity shape factor s_q = 1 + (B/L) tan(phi).

    NUMBA_NUM_THREADS=1 python benchmarks/sph_plate3d.py [--points MEDIUM:KIND ...] [--dx-mm 4]

KIND: ``2d`` (the 2D solver), ``slab`` (3D, plane strain), ``finite`` (3D, Li's plate),
``finite-big`` (3D, bed half-widths and depth x 1.5: the wall check). Writes
benchmarks/results/sph_plate3d.json after every point (resumable: finished points are kept
and skipped; ``--redo`` runs them again). A study, not a timing benchmark: wall times are as
run, on whatever the machine was doing.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np

from terradyn.io import atomic_write_text
from terradyn.sph.calibration import PLATE_TEST, plate_slope
from terradyn.sph.materials import from_medium
from terradyn.sph.plate3d import PLATE_LENGTH, PLATE_WIDTH, fit_alpha, plate_push3d, shape_factor
from terradyn.sph.state import SPHConfig
from terradyn.sph.validation import alpha_z_plate_measured
from terradyn.units import DEG, N_PER_CM3

OUT = Path(__file__).parent / "results" / "sph_plate3d.json"
DEFAULT = ["3 mm glass CP:slab", "3 mm glass CP:2d", "3 mm glass CP:finite", "poppy LP:slab",
           "poppy LP:2d", "poppy LP:finite", "0.3 mm glass CP:slab", "0.3 mm glass CP:2d",
           "0.3 mm glass CP:finite"]
#: Slab thickness (particles in y) of the plane-strain configuration.
SLAB = 4


def run_point(medium: str, kind: str, dx: float, partial=None) -> dict:
    mat = from_medium(medium)
    cfg = SPHConfig(dx=dx)
    t0 = time.perf_counter()
    if kind == "2d":
        r = plate_slope(mat, config=cfg)
        out = {"alpha_z_N_cm3": r["alpha_z"] / N_PER_CM3, "slope_N_cm3": r["slope"] / N_PER_CM3,
               "intercept_kPa": r["intercept_Pa"] / 1e3, "depth_m": r["depth"].tolist(),
               "stress_kPa": (r["stress"] / 1e3).tolist()}
    else:
        kw = {}
        if kind == "slab":
            kw["slab"] = SLAB
        elif kind == "finite-big":
            kw.update(half_x=4.5 * PLATE_LENGTH, half_y=4.5 * PLATE_WIDTH,
                      depth=1.5 * (PLATE_TEST["depth_m"] + 2 * PLATE_LENGTH))
        elif kind != "finite":
            raise SystemExit(f"error: kind must be 2d, slab, finite or finite-big, got {kind!r}")
        ck = OUT.with_name(f"{OUT.stem}.{medium.replace(' ', '_')}.{kind}.{dx * 1e3:g}mm."
                           f"{mat.friction / DEG:.2f}deg.checkpoint.npz")  # resumes a stopped run
        r = plate_push3d(mat, config=cfg, partial=partial, checkpoint=ck, **kw)
        fz = np.asarray(r["fz_quarter_N"])
        out = {"alpha_z_N_cm3": r["alpha_z"] / N_PER_CM3, "slope_N_cm3": r["slope"] / N_PER_CM3,
               "intercept_kPa": r["intercept_Pa"] / 1e3, "depth_m": r["depth"].round(6).tolist(),
               "stress_kPa": (r["stress"] / 1e3).round(5).tolist(),
               "lateral_over_vertical": float(np.max(np.abs(r["fx_quarter_N"]))
                                              / max(np.max(np.abs(fz)), 1e-12)),
               "particles": r["particles"], "ghosts": r["ghosts"], "pairs": r["pairs"],
               "steps": r["steps"], "dt_s": r["dt_s"], "lost": r["lost"], "scene": r["scene"]}
    out.update(medium=medium, kind=kind, dx_mm=dx * 1e3, friction_deg=mat.friction / DEG,
               dp_match=mat.dp_match,
               youngs_MPa=mat.youngs / 1e6, wall_s=round(time.perf_counter() - t0, 1))
    return out


def _phi(p: dict) -> float:
    """A point's friction angle (deg, 2 decimals): points of other friction angles (the former
    angle-of-repose media, the plate-calibrated ones) are kept side by side."""
    return round(p["friction_deg"], 2)


def summary(points: list[dict]) -> list[dict]:
    rows = []
    by = {(p["medium"], p["kind"], p["dx_mm"], _phi(p)): p for p in points}
    for medium, dx, phi_deg in sorted({(p["medium"], p["dx_mm"], _phi(p)) for p in points}):
        g = {k: by.get((medium, k, dx, phi_deg), {}).get("alpha_z_N_cm3")
             for k in ("2d", "slab", "finite", "finite-big")}
        phi = phi_deg * DEG
        pts = [q for q in by.values() if (q["medium"], q["dx_mm"], _phi(q)) == (medium, dx, phi_deg)]
        row = {"medium": medium, "dx_mm": dx, "friction_deg": phi_deg,
               # the first points predate the corrected match: they ran the former cone
               "dp_match": pts[0].get("dp_match", "bui2008"),
               "alpha_z_2d": g["2d"], "alpha_z_3d_slab": g["slab"],
               "alpha_z_3d_finite": g["finite"], "alpha_z_3d_finite_big": g["finite-big"],
               "alpha_z_measured": alpha_z_plate_measured(medium) / N_PER_CM3,
               "shape_factor_sq": round(shape_factor(PLATE_LENGTH, PLATE_WIDTH, phi), 4)}
        if g["2d"] and g["slab"]:
            row["slab_over_2d"] = round(g["slab"] / g["2d"], 4)
        if g["finite"] and g["slab"]:
            row["finite_over_slab"] = round(g["finite"] / g["slab"], 4)
        if g["finite"] and g["2d"]:
            row["finite_over_2d"] = round(g["finite"] / g["2d"], 4)
        if g["finite"]:
            row["finite_vs_measured"] = round(g["finite"] / row["alpha_z_measured"] - 1, 4)
        rows.append(row)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", nargs="+", default=DEFAULT, help="MEDIUM:KIND, in order")
    ap.add_argument("--dx-mm", type=float, default=4.0)
    ap.add_argument("--redo", action="store_true")
    ap.add_argument("--out", type=Path, default=OUT,
                    help="results file (default: %(default)s); a separate one per process lets two "
                         "processes run points side by side (merge them with --merge)")
    ap.add_argument("--merge", type=Path, nargs="+", default=[],
                    help="results files whose points are merged into --out (no runs)")
    a = ap.parse_args()
    out = a.out
    res = (json.loads(out.read_text()) if out.exists() else
           {"what": "SPH plate test alpha_z(0, pi/2) in 2D, 3D plane-strain slab and 3D finite plate",
            "plate_test": PLATE_TEST, "points": []})
    res["machine"] = (f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores "
                      "shared with other developers' runs, NUMBA_NUM_THREADS="
                      f"{os.environ.get('NUMBA_NUM_THREADS', 'default')}")
    if a.merge:
        for f in a.merge:
            for q in json.loads(f.read_text())["points"]:
                key = (q["medium"], q["kind"], q["dx_mm"], _phi(q))
                res["points"] = [p for p in res["points"]
                                 if (p["medium"], p["kind"], p["dx_mm"], _phi(p)) != key] + [q]
        a.points = []
    for spec in a.points:
        medium, _, kind = spec.rpartition(":")
        key = (medium, kind, a.dx_mm, round(from_medium(medium).friction / DEG, 2))
        old = [p for p in res["points"] if (p["medium"], p["kind"], p["dx_mm"], _phi(p)) == key]
        if old and not a.redo:
            print(f"{spec}: done ({old[0]['alpha_z_N_cm3']:.4f} N/cm^3), skipped", flush=True)
            continue
        print(f"{spec}: running ...", flush=True)

        def partial(d, st, spec=spec):  # the curve so far, in case the run is stopped
            fit = fit_alpha(d, st, PLATE_TEST["fit_from_m"])
            res.setdefault("partial", {})[spec] = {
                "depth_reached_m": float(d[-1]), "alpha_z_so_far_N_cm3": fit["alpha_z"] / N_PER_CM3,
                "depth_m": d.round(6).tolist(), "stress_kPa": (st / 1e3).round(5).tolist()}
            atomic_write_text(out, json.dumps(res, indent=1))

        p = run_point(medium, kind, a.dx_mm * 1e-3, partial)
        res.get("partial", {}).pop(spec, None)
        res["points"] = [q for q in res["points"]
                         if (q["medium"], q["kind"], q["dx_mm"], _phi(q)) != key]
        res["points"].append(p)
        res["summary"] = summary(res["points"])
        atomic_write_text(out, json.dumps(res, indent=1))
        print(f"{spec}: alpha_z {p['alpha_z_N_cm3']:.4f} N/cm^3 (free slope "
              f"{p['slope_N_cm3']:.4f}, intercept {p['intercept_kPa']:.2f} kPa), {p['wall_s']:.0f} s",
              flush=True)
    res["summary"] = summary(res["points"])
    atomic_write_text(out, json.dumps(res, indent=1))
    for row in res["summary"]:
        print(json.dumps(row))


if __name__ == "__main__":
    main()
