"""Wall time of the full standard rotating-leg test in SPH (issue 17, item 5: "the full
standard test (omega 0.2 rad/s, -135..135 deg) at the production resolution within 15 minutes
on this 2-core machine").

The flat leg in poppy LP (its preset: the shipped plate calibration), hip 2 cm, omega =
0.2 rad/s, 271 angles from -135 to 135 deg, at --dx-mm (default 2.5, the production
resolution) with --threads Numba threads; side by side in the same run (same machine state),
the same leg at the validation's omega = 1.1 rad/s (5.5 x fewer steps), so the cost ratio of
the two speeds is measured, not assumed. Records the wall time, steps, particles, the load
average before and after, and the peaks of both runs.

    python benchmarks/sph_standard_test.py [--dx-mm 2.5] [--threads 2] [--medium "poppy LP"]

Writes benchmarks/results/sph_standard_test.json (one entry per dx and threads, kept across
runs)."""
from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

OUT = Path(__file__).parent / "results" / "sph_standard_test.json"
TARGET_S = 15 * 60


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dx-mm", type=float, default=2.5)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--medium", default="poppy LP")
    ap.add_argument("--skip-fast", action="store_true", help="do not run the omega = 1.1 rad/s comparison")
    a = ap.parse_args()
    os.environ["NUMBA_NUM_THREADS"] = str(a.threads)  # before numba is imported

    import numpy as np

    import terradyn as td
    from terradyn.io import atomic_write_text
    from terradyn.sph.materials import from_medium
    from terradyn.sph.state import SPHConfig
    from terradyn.units import CM, DEG

    mat = from_medium(a.medium)
    rows = {}
    for omega in ((0.2,) if a.skip_fast else (0.2, 1.1)):
        mot = td.Rotation(omega=omega, hip_height=2 * CM, theta_start=-135 * DEG, theta_end=135 * DEG, n_theta=271)
        load0 = os.getloadavg()[0]
        t0 = time.perf_counter()
        ds, run = td.sph.simulate_run(td.flat_leg(), mot, mat, config=SPHConfig(dx=a.dx_mm * 1e-3))
        wall = time.perf_counter() - t0
        rows[f"omega {omega:g}"] = {
            "omega_rad_s": omega, "wall_s": round(wall, 1), "load_average_before": round(load0, 2),
            "load_average_after": round(os.getloadavg()[0], 2),
            "steps": int(run.steps), "particles": int(run.particles), "solver_wall_s": round(float(run.wall_seconds), 1),
            "peak_lift_N": round(float(np.max(ds.Fz.values)), 4), "peak_thrust_N": round(float(np.max(ds.Fx.values)), 4)}
        print(json.dumps(rows[f"omega {omega:g}"]), flush=True)
    std = rows["omega 0.2"]
    entry = {"medium": a.medium, "friction_deg": round(float(np.degrees(mat.friction)), 2), "dx_mm": a.dx_mm,
             "threads": a.threads, "runs": rows, "target_s": TARGET_S, "met": std["wall_s"] <= TARGET_S,
             "machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores (shared)",
             "when": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
    if "omega 1.1" in rows:
        entry["wall_ratio_0.2_over_1.1"] = round(std["wall_s"] / rows["omega 1.1"]["wall_s"], 2)
    res = json.loads(OUT.read_text()) if OUT.exists() else {"command": "python benchmarks/sph_standard_test.py", "entries": {}}
    res["entries"][f"{a.medium}|{a.dx_mm:g}mm|{a.threads}threads"] = entry
    atomic_write_text(OUT, json.dumps(res, indent=1))
    print(f"standard test (omega 0.2 rad/s) at {a.dx_mm:g} mm, {a.threads} threads: {std['wall_s'] / 60:.1f} min "
          f"(target {TARGET_S / 60:.0f} min: {'met' if entry['met'] else 'NOT met'}); wrote {OUT}")


if __name__ == "__main__":
    main()
