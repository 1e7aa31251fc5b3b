"""How much do repeated SPH runs scatter, and do the 10 nm "realizations" sample it? (issue 17)

The plate test (``calibration.plate_slope``), the rig and the legs take ``realization`` k:
the body starts k x 10 nm higher, "a physically nil change that gives another realization
of the chaotic flow". The calibration's standard error of the friction angle and the
convergence study's "two runs each" rest on it. This runs the plate test (the calibration's
scene and settings, :data:`terradyn.sph.calibration.PLATE_TEST`) of a medium at its shipped
friction angle with realizations 0, 1, 2, ... (10 nm apart) and with sub-particle start
offsets (50 um to 0.7 mm higher: a fraction of the particle spacing, so the plate meets the
particle lattice at another phase), and reports each group's mean, standard deviation and
range of the through-origin alpha_z.

    python benchmarks/sph_start_offsets.py [--media "poppy LP" ...] [--dx-mm 4]
        [--calibration-dx-mm 2.5 | --friction-deg PHI]
        [--nm-realizations 3 (0 or more)] [--offsets-um 50 100 200 400 700] [--threads 1]
        [--rig BETA_DEG GAMMA_DEG --out FILE]

``--calibration-dx-mm`` takes the friction angle calibrated at that spacing (default: the
run's own spacing, as :func:`terradyn.sph.materials.from_medium` picks it), so that a
resolution study holds the material fixed; ``--friction-deg`` sets the friction angle itself
(one calibration step over lattice phases). ``--rig`` runs one point of the virtual plate rig instead (alpha_z and alpha_x).

Writes benchmarks/results/sph_start_offsets.json (``--out``) when done; each finished run is
kept in the ``.partial.json`` beside it, so an interrupted study resumes. A study, not a
timing benchmark (each run's wall time is recorded)."""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

RES = Path(__file__).parent / "results"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--media", nargs="+", default=["poppy LP", "0.3 mm glass CP"])
    ap.add_argument("--dx-mm", type=float, default=4.0)
    ap.add_argument("--calibration-dx-mm", type=float, default=None,
                    help="the friction angle calibrated at this spacing (default: the run's own)")
    ap.add_argument("--friction-deg", type=float, default=None,
                    help="this friction angle instead of a calibrated one, deg")
    ap.add_argument("--nm-realizations", type=int, default=3, help="realizations 0..N-1, 10 nm apart")
    ap.add_argument("--offsets-um", nargs="+", type=float, default=[50, 100, 200, 400, 700])
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--rig", nargs=2, type=float, metavar=("BETA_DEG", "GAMMA_DEG"),
                    help="instead of the plate test: the rig's plate at this attack and intrusion "
                         "angle (suite.rig_point, Li's conventions; alpha_z and alpha_x)")
    ap.add_argument("--out", type=Path, default=RES / "sph_start_offsets.json")
    a = ap.parse_args(argv)
    if a.calibration_dx_mm is not None and not 0.5 <= a.calibration_dx_mm <= 10:
        ap.error(f"calibration-dx-mm: 0.5 to 10 mm, got {a.calibration_dx_mm:g} mm")
    if a.friction_deg is not None and (a.calibration_dx_mm is not None or not 10 <= a.friction_deg <= 60):
        ap.error("friction-deg: 10 to 60 deg, and not together with --calibration-dx-mm")
    if a.nm_realizations < 0 or a.nm_realizations + len(a.offsets_um) < 1 or any(x <= 0 for x in a.offsets_um):
        ap.error("nm-realizations: 0 or more; offsets-um: each > 0 um; at least one run in all "
                 "(a group of one run has no standard deviation)")
    os.environ["NUMBA_NUM_THREADS"] = str(a.threads)  # before numba is imported

    import numpy as np

    from terradyn.io import atomic_write_text
    from terradyn.media import MEDIA
    from terradyn.sph.calibration import PLATE_TEST, plate_slope
    from terradyn.sph.materials import from_medium
    from terradyn.sph.state import SPHConfig
    from terradyn.sph.suite import rig_point
    from terradyn.units import DEG, N_PER_CM3

    dx = a.dx_mm * 1e-3

    def run(mat, k):
        if a.rig is None:
            return {"alpha_z": plate_slope(mat, config=SPHConfig(dx=dx), realizations=1, first=k)["alpha_z"]
                    / N_PER_CM3}
        az, ax = rig_point(mat, a.rig[0] * DEG, a.rig[1] * DEG, dx=dx, realization=k)
        return {"alpha_z": az / N_PER_CM3, "alpha_x": ax / N_PER_CM3}

    cal_dx = dx if a.calibration_dx_mm is None else a.calibration_dx_mm * 1e-3
    settings = {"media": a.media, "dx_mm": a.dx_mm,
                **({} if a.calibration_dx_mm is None else {"calibration_dx_mm": a.calibration_dx_mm}),
                **({} if a.friction_deg is None else {"friction_deg": a.friction_deg}),
                "nm_realizations": a.nm_realizations,
                "offsets_um": a.offsets_um, "threads": a.threads,
                **({"plate_test": PLATE_TEST} if a.rig is None
                   else {"rig_beta_deg": a.rig[0], "rig_gamma_deg": a.rig[1]})}
    partial = a.out.with_name(a.out.stem + ".partial.json")
    done = {}
    if partial.exists():
        old = json.loads(partial.read_text())
        if old.get("settings") == settings:
            done = old["runs"]
            print(f"reading {partial.name}: {len(done)} runs done", flush=True)
    rows = []
    for m in a.media:
        mat = from_medium(m, dx=cal_dx, friction_deg=a.friction_deg)
        groups = {"10 nm": [(f"k{k}", k) for k in range(a.nm_realizations)],
                  "sub-particle": [(f"{x:g}um", round(100 * x)) for x in a.offsets_um]}
        row = {"medium": m, "friction_deg": round(mat.friction / DEG, 3),
               "alpha_z_measured": MEDIA[m].alpha_z_plate / N_PER_CM3, "groups": {}}
        for g, starts in groups.items():
            vals = {}
            for tag, k in starts:
                key = f"{m}|{tag}"
                if key not in done:
                    t0 = time.perf_counter()
                    done[key] = {"start_offset_um": k / 100, **run(mat, k),
                                 "wall_s": round(time.perf_counter() - t0, 1)}
                    atomic_write_text(partial, json.dumps({"settings": settings, "runs": done}, indent=1))
                    print(key, done[key], flush=True)
                for q in ("alpha_z", "alpha_x"):
                    if q in done[key]:
                        vals.setdefault(q, []).append(done[key][q])
            row["groups"][g] = {q: {"runs": v, "mean": float(np.mean(v)),
                                    "std": float(np.std(v, ddof=1)) if len(v) > 1 else None,
                                    "range_over_mean": float(np.ptp(v) / abs(np.mean(v)))}
                                for q, v in vals.items()}
        rows.append(row)
    atomic_write_text(a.out, json.dumps({"command": "python benchmarks/sph_start_offsets.py "
                                         + " ".join(argv if argv is not None else sys.argv[1:]),
                                         "settings": settings, "rows": rows}, indent=1) + "\n")
    partial.unlink(missing_ok=True)
    for row in rows:
        for g, qs in row["groups"].items():
            for q, s in qs.items():
                sd = "" if s["std"] is None else f" +- {s['std']:.4f}"
                print(f"{row['medium']:16s} {g:12s} {q} {s['mean']:.4f}{sd} N/cm^3 "
                      f"(range {100 * s['range_over_mean']:.1f} % of the mean; runs "
                      + ", ".join(f"{x:.4f}" for x in s["runs"]) + ")")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
