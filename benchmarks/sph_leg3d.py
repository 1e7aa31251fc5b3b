"""The legs in 3D: does plane strain make the SPH leg's lift too high and its thrust too low?

The 2D SPH flat leg in poppy LP peaks at +32 % lift and -26 % thrust against Li 2013's
measured curves (docs/sph.md). The same stroke in the 3D code (:func:`terradyn.sph.plate3d.
flat_leg3d`: the 7.62 x 2.54 x 0.64 cm plate on its hip, half domain), beside the 3D code's
plane-strain slab (the 2D scene in the same code: the check that the codes agree and the
reference the 3D effect is measured against), at the same resolution and speed, and the
measured peaks. The C and reverse-C legs (:func:`terradyn.sph.plate3d.leg3d`, the half-circle
arcs of :mod:`terradyn.geometry`) the same way.

    NUMBA_NUM_THREADS=1 python benchmarks/sph_leg3d.py [--points MEDIUM:KIND[:LEG] ...]
        [--dx-mm 4] [--omega 1.1] [--friction-deg PHI] [--so-far] [--out FILE]

KIND: ``slab`` or ``finite``; LEG: ``flat`` (default), ``c`` or ``reverse-c``. Writes benchmarks/results/sph_leg3d.json after every point
(resumable: finished points are kept and skipped, a point stopped part-way resumes from its checkpoint beside --out), with the force curves. A study, not a
timing benchmark: wall times are as run.

``--friction-deg`` holds the friction angle (a resolution study at the angle of an earlier
run) instead of the medium's shipped calibration. ``--so-far`` runs nothing: it reads each
point's curve so far from its checkpoint (a run stopped part-way, or still going in another
process) and records it with ``partial_to_deg`` (the angle reached; the peaks are those so
far), which the validation checks skip and a later full run replaces.
"""
from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import numpy as np

from terradyn.errors import InputError
from terradyn.io import atomic_write_text
from terradyn.media import LI2013
from terradyn.sph.materials import from_medium
from terradyn.sph.plate3d import LEG3D_SHAPES, leg3d
from terradyn.sph.state import SPHConfig
from terradyn.sph.suite import leg_scores, measured_legs
from terradyn.units import DEG

RES = Path(__file__).parent / "results"
OUT = RES / "sph_leg3d.json"
DEFAULT = ["poppy LP:slab", "poppy LP:finite"]
#: Slab thickness (particles in y) of the plane-strain configuration.
SLAB = 6


def score(p: dict) -> dict:
    """Measured peaks and RMS differences of a point (:func:`terradyn.sph.suite.leg_scores`)."""
    return leg_scores(p["medium"], p["theta_deg"], p["Fz_N"], p["Fx_N"], p["omega_rad_s"],
                      leg_of(p))


def leg_of(p: dict) -> str:
    return p.get("leg", "flat")  # the first points (flat leg only) carry no leg


LI2013_S5 = f"{LI2013}, Fig. S5 (measured)"  # as the validation suite's leg checks cite it


def checks(points: list[dict]) -> list[dict]:
    """The finite (3D) points as rows of ``terradyn sph validate``'s leg checks (peaks within
    15 % of the measured ones, RMS no larger than RFT's), labelled 3D, for the report; the
    partial points (``--so-far``) are not checks."""
    rows = []
    for p in points:
        if (p["kind"] != "finite" or p.get("measured_peak_lift_N") is None
                or p.get("partial_to_deg") is not None):
            continue
        tag = f"{leg_of(p)} leg, {p['medium']} (3D, plate3d, {p['dx_mm']:g} mm)"
        for name in ("lift", "thrust"):
            ours, ref = p[f"peak_{name}_N"], p[f"measured_peak_{name}_N"]
            rows.append({"scene": "legs", "quantity": f"peak {name}, {tag}", "ours": ours,
                         "reference": ref, "unit": "N", "source": LI2013_S5,
                         "relative_difference": round(ours / ref - 1, 4),
                         "tolerance": "within 15 %",
                         "verdict": "pass" if abs(ours / ref - 1) <= 0.15 else "fail"})
            if f"rms_{name}_N" in p:
                a, b = p[f"rms_{name}_N"], p[f"rms_{name}_rft_N"]
                rows.append({"scene": "legs", "quantity": f"RMS {name} - measured, {tag}",
                             "ours": a, "reference": b, "unit": "N",
                             "source": "RFT (Table S5 grid, linear) against the same curve",
                             "relative_difference": round(a / b - 1, 4), "tolerance": "<= RFT's",
                             "verdict": "pass" if a <= b else "fail"})
    return rows


def write_checks(res: dict, path: Path) -> None:
    rows = checks(res["points"])
    if rows:
        atomic_write_text(path, json.dumps({"checks": rows, "details": {}, "settings": {
            "scenes": ["legs"], "model": "3D (terradyn.sph.plate3d.leg3d)",
            "dx_mm": sorted({q["dx_mm"] for q in res["points"] if q["kind"] == "finite"})[0],
            "dp_match": "plane-strain", "omega_rad_s": 1.1,
            "command": "python benchmarks/sph_leg3d.py"}}, indent=1))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", nargs="+", default=DEFAULT,
                    help="MEDIUM:KIND[:LEG], KIND slab|finite, LEG flat|c|reverse-c")
    ap.add_argument("--dx-mm", type=float, default=4.0)
    ap.add_argument("--omega", type=float, default=1.1)
    ap.add_argument("--friction-deg", type=float, default=None,
                    help="this friction angle, deg (default: the medium's shipped calibration)")
    ap.add_argument("--so-far", action="store_true",
                    help="run nothing: record each point's curve so far from its checkpoint")
    ap.add_argument("--out", type=Path, default=OUT)
    ap.add_argument("--figure", type=Path, help="draw the curves of the medium of the first point (PNG)")
    ap.add_argument("--compare", type=Path,
                    help="with --figure: also draw the finite points of this leg from this results "
                         "file (another spacing; with --friction-deg, those at that angle)")
    ap.add_argument("--checks", type=Path, default=RES / "sph_validate_legs3d.json",
                    help="the finite points as validation checks (the report reads them)")
    a = ap.parse_args()
    if a.friction_deg is not None and not 10 <= a.friction_deg <= 60:
        ap.error(f"--friction-deg: 10 to 60 deg, got {a.friction_deg:g} deg")
    if a.compare is not None and (a.figure is None or not a.compare.is_file()):
        ap.error(f"--compare: needs --figure and an existing results file, got {a.compare}")
    res = (json.loads(a.out.read_text()) if a.out.exists()
           else {"machine": platform.processor() or platform.machine(), "points": []})

    def key(p):
        return (p["medium"], p["kind"], leg_of(p), p["dx_mm"], p["omega_rad_s"], p["friction_deg"])

    done = {key(p) for p in res["points"] if p.get("partial_to_deg") is None}
    exp = measured_legs()
    specs = []
    for spec in a.points:
        parts = spec.split(":")
        medium, kind = parts[0], parts[1] if len(parts) > 1 else ""
        leg = parts[2] if len(parts) == 3 else "flat"
        if kind not in ("slab", "finite") or leg not in LEG3D_SHAPES or len(parts) > 3:
            ap.error(f"--points: {spec!r} must be MEDIUM:KIND[:LEG] with KIND "
                             f"slab or finite and LEG one of {', '.join(LEG3D_SHAPES)}")
        specs.append((spec, medium, kind, leg))
    for spec, medium, kind, leg in specs:
        mat = from_medium(medium, friction_deg=a.friction_deg)
        phi = round(mat.friction / DEG, 3)
        if (medium, kind, leg, a.dx_mm, a.omega, phi) in done:
            continue
        t0 = time.perf_counter()
        last = [0.0]

        def progress(d, tot):
            if time.perf_counter() - last[0] > 60:
                last[0] = time.perf_counter()
                print(f"  {spec}: {d:.2f} / {tot:.2f} s simulated", flush=True)

        # a point stopped part-way resumes from its checkpoint (removed when it finishes)
        fixed = "" if a.friction_deg is None else f"_{a.friction_deg:g}deg"
        ck = a.out.with_name(f"{a.out.stem}.{medium.replace(' ', '_')}.{kind}.{leg}."
                             f"{a.dx_mm:g}mm{fixed}.checkpoint.npz")
        try:
            r = leg3d(mat, shape=leg, config=SPHConfig(dx=a.dx_mm * 1e-3), omega=a.omega,
                      slab=SLAB if kind == "slab" else None, progress=progress, checkpoint=ck,
                      so_far=a.so_far)
        except InputError as err:  # e.g. --so-far with no checkpoint, or one still settling
            ap.error(f"{spec}: {err}")
        if r["resumed_from"]:
            print(f"  {spec}: resumed from {ck} at step {r['resumed_from']['step']}", flush=True)
        p = {"medium": medium, "kind": kind, "leg": leg, "dx_mm": a.dx_mm, "omega_rad_s": a.omega,
             "friction_deg": phi, "youngs_MPa": mat.youngs / 1e6,
             "peak_lift_N": round(r["peak_lift"], 4), "peak_thrust_N": round(r["peak_thrust"], 4),
             "theta_deg": np.round(r["theta"] / DEG, 3).tolist(),
             "Fx_N": np.round(r["Fx"], 4).tolist(), "Fz_N": np.round(r["Fz"], 4).tolist(),
             "window_deg": r["window_deg"], "particles": r["particles"], "steps": r["steps"],
             "lost": r["lost"], "wall_s": round(time.perf_counter() - t0, 1)}
        if a.so_far:  # the curve so far: NaN past the angle reached (JSON null)
            p["partial_to_deg"] = round(r["reached_deg"], 3)
            p["Fx_N"] = [None if np.isnan(v) else v for v in p["Fx_N"]]
            p["Fz_N"] = [None if np.isnan(v) else v for v in p["Fz_N"]]
            p.pop("wall_s")
            for comp, name in (("Fz", "lift"), ("Fx", "thrust")):
                e = exp[(exp.medium == medium) & (exp.leg == leg) & (exp.force == comp)]
                if len(e):
                    p[f"measured_peak_{name}_N"] = round(float(e.force_N.max()), 4)
        else:
            p.update(score(p))
        res["points"] = [q for q in res["points"]  # a newer partial or the full run replaces it
                         if not (q.get("partial_to_deg") is not None and key(q) == key(p))]
        res["points"].append(p)
        atomic_write_text(a.out, json.dumps(res, indent=1))
        print(json.dumps({k: v for k, v in p.items() if k not in ("theta_deg", "Fx_N", "Fz_N")}),
              flush=True)
    if a.out == OUT:  # the shipped study: its checks go beside the 2D validation's
        write_checks(res, a.checks)
    if a.figure:
        from terradyn.sph import plots

        medium, leg = specs[0][1], specs[0][3]
        pts = [p for p in res["points"] if p["medium"] == medium and p["omega_rad_s"] == a.omega
               and leg_of(p) == leg and (p["dx_mm"] == a.dx_mm or a.compare is not None)]
        if a.compare is not None:  # the same leg from another results file (another spacing)
            pts = [p for p in json.loads(a.compare.read_text())["points"]
                   if p["medium"] == medium and p["omega_rad_s"] == a.omega and leg_of(p) == leg
                   and p["kind"] == "finite"
                   and (a.friction_deg is None or p["friction_deg"] == round(a.friction_deg, 3))] + pts
        e = exp[(exp.medium == medium) & (exp.leg == leg)]
        meas = {c: (e[e.force == c].theta_deg.values, e[e.force == c].force_N.values)
                for c in ("Fz", "Fx")}
        spacing = (", 2.54 cm wide, 3D" if len({p["dx_mm"] for p in pts}) > 1
                   else f", {a.dx_mm:g} mm particles")
        plots.leg3d(pts, meas, a.figure, title=f"{leg} leg, {medium}, omega = {a.omega:g} rad/s"
                                               f"{spacing}")


if __name__ == "__main__":
    main()
