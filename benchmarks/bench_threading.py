"""Numba threading layer for the SPH step: work-queue vs OpenMP (GNU spin default) vs OpenMP
with a short spin (GOMP_SPINCOUNT=10000, what ``import terradyn`` sets), on a small bed at
rest (where kernel launches weigh most), on an idle machine and with two other busy
processes on the cores (a sweep, a build, a browser).

Each configuration runs in its own process (the layer is fixed at the first parallel launch).
Usage: python benchmarks/bench_threading.py [--quick]
Writes benchmarks/results/threading.json.
"""
from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

QUICK = "--quick" in sys.argv
OUT = Path(__file__).parent / "results" / "threading.json"
STEPS = 200 if QUICK else 1000

CHILD = r"""
import json, sys, time
import numpy as np
import numba
from terradyn.sph import SPHConfig, Solver
from terradyn.sph.scenes import bed_scene
dx = 2.5e-3
side = np.sqrt(2400 / 2.0) * dx
s = Solver(bed_scene(width=2 * side, depth=side, config=SPHConfig(dx=dx, settle_time=0.0)))
s.step()
t = time.perf_counter()
for _ in range(int(sys.argv[1])):
    s.step()
el = time.perf_counter() - t
print(json.dumps({"layer": numba.threading_layer(), "particles": s.n,
                  "us_per_step": el / int(sys.argv[1]) * 1e6,
                  "particle_steps_per_s": s.n * int(sys.argv[1]) / el}))
"""

CONFIGS = {
    "workqueue": {"NUMBA_THREADING_LAYER": "workqueue"},
    "omp, GNU default spin (300000)": {"NUMBA_THREADING_LAYER": "omp", "GOMP_SPINCOUNT": "300000"},
    "omp, GOMP_SPINCOUNT=10000 (terradyn's default)": {"NUMBA_THREADING_LAYER": "omp"},
}


def run(extra: dict) -> dict:
    env = {k: v for k, v in os.environ.items()
           if k not in ("GOMP_SPINCOUNT", "OMP_WAIT_POLICY", "NUMBA_THREADING_LAYER")}
    env.update(extra)
    p = subprocess.run([sys.executable, "-c", CHILD, str(STEPS)], env=env, capture_output=True,
                       text=True, check=True)
    return json.loads(p.stdout.strip().splitlines()[-1])


def hogs(n: int) -> list:
    return [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]


def main() -> None:
    rows = []
    for load in (0, 2):
        procs = hogs(load)
        try:
            time.sleep(0.5)
            for name, extra in CONFIGS.items():
                r = run(extra) | {"config": name, "busy_processes": load}
                rows.append(r)
                print(f"{name:48s} busy={load}  {r['us_per_step']:9.0f} us/step  "
                      f"({r['particle_steps_per_s'] / 1e6:.2f} M particle-steps/s, "
                      f"layer {r['layer']})", file=sys.stderr)
        finally:
            for p in procs:
                p.kill()
    for load in (0, 2):
        base = next(r for r in rows if r["busy_processes"] == load and r["config"] == "workqueue")
        for r in rows:
            if r["busy_processes"] == load:
                r["speedup_vs_workqueue"] = base["us_per_step"] / r["us_per_step"]
    OUT.parent.mkdir(exist_ok=True)
    OUT.write_text(json.dumps({"machine": {"platform": platform.platform(), "cpus": os.cpu_count(),
                                           "load_avg_1min": os.getloadavg()[0]},
                               "steps": STEPS, "rows": rows}, indent=1))
    for r in rows:
        print(f"{r['config']:48s} busy={r['busy_processes']}  "
              f"{r['speedup_vs_workqueue']:.2f}x vs workqueue")


if __name__ == "__main__":
    main()
