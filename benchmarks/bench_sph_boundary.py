"""The cost of the resolved leg boundary (issue 17): the same rotating-leg run with
``SPHConfig(boundary="resolved")`` (the side test: one nearest-segment search per particle
near the leg per step) and ``boundary="guard"`` (the model before), side by side in turns.

Usage: python benchmarks/bench_sph_boundary.py [--rounds N] [--omega W]
The run: the flat leg of the standard test from -135 to 135 deg at ``--omega`` (default 1.1
rad/s), 4 mm particles (the quick resolution). Writes benchmarks/results/sph_boundary.json with
each round's wall time and particle-steps per second and the median ratio resolved / guard.
"""
from __future__ import annotations

import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

OUT = Path(__file__).parent / "results" / "sph_boundary.json"


def _arg(name, default):
    return type(default)(sys.argv[sys.argv.index(name) + 1]) if name in sys.argv else default


def main() -> None:
    import terradyn as td
    from terradyn.sph import SPHConfig
    from terradyn.units import DEG

    rounds = _arg("--rounds", 3)
    omega = _arg("--omega", 1.1)
    leg = td.flat_leg()
    mot = td.Rotation(omega=omega, hip_height=0.02, theta_start=-135 * DEG,
                      theta_end=135 * DEG, n_theta=271)
    # compile both variants first (JIT out of the timings)
    warm = td.Rotation(omega=4.0, hip_height=0.02, theta_start=-80 * DEG, theta_end=-75 * DEG,
                       n_theta=6)
    for b in ("guard", "resolved"):
        td.sph.simulate(leg, warm, config=SPHConfig(dx=4e-3, boundary=b))
    rows = []
    for r in range(rounds):
        for b in ("guard", "resolved"):
            t0 = time.perf_counter()
            ds = td.sph.simulate(leg, mot, config=SPHConfig(dx=4e-3, boundary=b))
            wall = time.perf_counter() - t0
            run = td.series.inputs_of(ds)["run"]
            rows.append({"round": r, "boundary": b, "wall_s": round(wall, 2),
                         "particles": run["particles"], "steps": run["steps"],
                         "particle_steps_per_s": run["particles"] * run["steps"] / wall})
            print(f"round {r} {b:>8}: {wall:7.1f} s  "
                  f"{rows[-1]['particle_steps_per_s']:.3g} particle-steps/s", flush=True)
    ratios = [next(x["wall_s"] for x in rows if x["round"] == r and x["boundary"] == "resolved")
              / next(x["wall_s"] for x in rows if x["round"] == r and x["boundary"] == "guard")
              for r in range(rounds)]
    out = {"benchmark": "sph_boundary", "omega_rad_s": omega, "dx_m": 4e-3, "rows": rows,
           "wall_ratio_resolved_over_guard": ratios,
           "median_ratio": float(np.median(ratios)),
           "machine": {"platform": platform.platform(), "cpus": os.cpu_count(),
                       "load_average": os.getloadavg()},
           "created": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
    OUT.parent.mkdir(parents=True, exist_ok=True)
    tmp = OUT.with_suffix(".tmp")
    tmp.write_text(json.dumps(out, indent=1))
    tmp.replace(OUT)
    print(f"resolved / guard wall time: median {out['median_ratio']:.3f} "
          f"(rounds {', '.join(f'{x:.3f}' for x in ratios)}); wrote {OUT}")


if __name__ == "__main__":
    main()
