"""The virtual plate rig (issue 17): SPH's own alpha_z, alpha_x maps of one medium on Li 2013's
Table S5 grid (or the quick 3 x 5 subset), beside the measured ones, with the RMS differences
as fractions of the largest measured |alpha_z| (target <= 0.20 each).

    python benchmarks/sph_rig.py --medium "poppy LP" [--quick] [--dx-mm 4]
        [--dp-match plane-strain|bui2008] [--threads 1] [--figure docs/figures/sph_rig_poppy_LP.png]

Writes benchmarks/results/sph_rig_<medium>.json (sph_rig_<medium>_quick.json for the subset;
the files the report and docs/sph.md read; another --dx-mm adds _<dx>mm to the name) once the grid is complete; every finished point is kept in
benchmarks/results/sph_rig_<medium>.partial.json, so an interrupted study resumes where it
stopped. A study, not a timing benchmark: the wall time is recorded as run."""
from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

RES = Path(__file__).parent / "results"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--medium", required=True)
    ap.add_argument("--quick", action="store_true", help="the 3 x 5 subset of the grid")
    ap.add_argument("--dx-mm", type=float, default=4.0)
    ap.add_argument("--dp-match", default="plane-strain", choices=["plane-strain", "bui2008"])
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--figure", type=Path, help="also draw the maps (PNG)")
    a = ap.parse_args()
    os.environ["NUMBA_NUM_THREADS"] = str(a.threads)  # before numba is imported

    import numpy as np

    from terradyn.io import atomic_write_text
    from terradyn.sph.materials import from_medium
    from terradyn.sph.suite import rig_against_table, rig_grid, rig_point
    from terradyn.units import DEG, N_PER_CM3

    mat = from_medium(a.medium, dp_match=a.dp_match)
    stem = ("sph_rig_" + a.medium.replace(" ", "_") + ("_quick" if a.quick else "")
            + ("" if a.dx_mm == 4.0 else f"_{a.dx_mm:g}mm"))  # 4 mm: the files docs and report read
    final, partial = RES / f"{stem}.json", RES / f"{stem}.partial.json"
    settings = {"dx_mm": a.dx_mm, "dp_match": a.dp_match, "quick": a.quick,
                "friction_deg": round(mat.friction / DEG, 3), "youngs_MPa": mat.youngs / 1e6,
                "threads": a.threads, "command": "python benchmarks/sph_rig.py " + " ".join(
                    [f'--medium "{a.medium}"', f"--dx-mm {a.dx_mm:g}", f"--dp-match {a.dp_match}"]
                    + (["--quick"] if a.quick else []))}
    done = {}
    if partial.exists():
        old = json.loads(partial.read_text())
        if old["settings"] == settings:
            done = old["points"]
            print(f"resuming {partial.name}: {len(done)} points done", flush=True)
    betas, gammas = rig_grid(a.quick)
    t0 = time.perf_counter()
    for b in betas:
        for g in gammas:
            key = f"{b:.6f},{g:.6f}"
            if key in done:
                continue
            t1 = time.perf_counter()
            az, ax = rig_point(mat, float(b), float(g), dx=a.dx_mm * 1e-3)
            done[key] = [az / N_PER_CM3, ax / N_PER_CM3, round(time.perf_counter() - t1, 1)]
            atomic_write_text(partial, json.dumps({"settings": settings, "points": done}))
            print(f"beta {b / DEG:6.1f} gamma {g / DEG:6.1f}: alpha_z {done[key][0]:.4f} "
                  f"alpha_x {done[key][1]:.4f} N/cm^3 ({done[key][2]} s)", flush=True)
    az = [[done[f"{b:.6f},{g:.6f}"][0] for g in gammas] for b in betas]
    ax = [[done[f"{b:.6f},{g:.6f}"][1] for g in gammas] for b in betas]
    r = rig_against_table(a.medium, betas, gammas, az, ax)
    out = {k: (v.tolist() if hasattr(v, "tolist") else v) for k, v in r.items()} | {
        "phi": mat.friction / DEG, "wall": sum(v[2] for v in done.values()), "settings": settings}
    atomic_write_text(final, json.dumps(out))
    partial.unlink()
    if a.figure:
        from terradyn.sph.plots import rig_maps

        rig_maps({k: (np.asarray(v) if isinstance(v, list) else v) for k, v in out.items()},
                 a.figure, title=f"virtual plate rig, {a.medium} (phi = {out['phi']:.1f} deg, "
                                 f"{a.dp_match} match, {a.dx_mm:g} mm)")
    print(f"{final.name}: RMS alpha_z {out['rms_z_frac']:.3f}, alpha_x {out['rms_x_frac']:.3f} of "
          f"max |alpha_z| ({time.perf_counter() - t0:.0f} s)", flush=True)


if __name__ == "__main__":
    main()
