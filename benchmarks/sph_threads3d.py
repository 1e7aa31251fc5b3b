"""3D SPH step time on 1 and 2 threads (and, optionally, the serial kernels they replaced), on
an idle machine and with two other busy processes on the cores.

The scene is the production 3D leg scene (:func:`terradyn.sph.plate3d.leg3d`'s bed for the
7.62 cm leg, hip 2 cm above the surface, 4 mm particles, both halves in x, half domain in y):
the flat leg hangs straight down through the bed and is dragged backwards at the tip speed of
omega = 1.1 rad/s, so the neighbour lists are rebuilt and the grains flow as in a stroke.
Each configuration runs in its own process (the thread count is fixed at start); the first
steps (compilation, first lists) are not timed. The 1- and 2-thread forces are compared
bitwise as part of the run.

    python benchmarks/sph_threads3d.py [--quick] [--steps N] [--baseline-src DIR]

``--baseline-src``: the ``src`` folder of a checkout of the serial code, e.g.
``git worktree add /tmp/serial3d 2ab80eb`` then ``--baseline-src /tmp/serial3d/src`` (the
last commit before the parallel kernels; same API). Writes
benchmarks/results/sph_threads3d.json (``--out``), with the load average before and after:
"idle" means no busy process of this benchmark's own, so run it on an otherwise idle machine.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from terradyn.io import atomic_write_text

sys.path.insert(0, str(Path(__file__).parent))
from bench_threading import hogs  # noqa: E402  (the same two busy processes)

OUT = Path(__file__).parent / "results" / "sph_threads3d.json"

CHILD = r"""
import json, math, sys, time
import numpy as np
import numba
from terradyn.sph.state import SPHConfig
from terradyn.sph import plate3d as P
steps, warm = int(sys.argv[1]), int(sys.argv[2])
L, hip, pad, omega = 0.0762, 0.02, 0.06, 1.1
half_x = math.sqrt(L * L - hip * hip) + pad
cz = hip - 0.5 * L
sc = P.plate_scene("poppy LP", config=SPHConfig(dx=4e-3, settle_time=0.0), length=L,
                   half_x=half_x, depth=L - hip + pad, mirror_x=False,
                   pose=(0.0, cz, -math.pi / 2))
s = P.Solver3D(sc, plate_speed=omega * L)
n = warm + steps
vx = -omega * 0.5 * L  # the centre's speed at theta = 0 (the tip's is twice it)
pose = np.zeros((n, 6))
pose[:, 0] = vx * s.dt * np.arange(n)
pose[:, 1] = cz
pose[:, 2] = -math.pi / 2
pose[:, 3] = vx
f0 = s.advance(pose[:warm], np.zeros(warm))
t = time.perf_counter()
f = s.advance(pose[warm:], np.zeros(steps))
el = time.perf_counter() - t
np.save(sys.argv[3], np.concatenate([f0, f]))
print(json.dumps({"threads": numba.get_num_threads(), "layer": numba.threading_layer(),
                  "particles": int(s.nr), "ghosts": int(s.ip[P.I_NG]), "steps": steps,
                  "ms_per_step": el / steps * 1e3,
                  "particle_steps_per_s": s.nr * steps / el}))
"""


def run(threads: int, src: str | None, steps: int, warm: int, forces: Path) -> dict:
    env = dict(os.environ, NUMBA_NUM_THREADS=str(threads))
    if src:
        env["PYTHONPATH"] = src  # the baseline checkout's package first
    p = subprocess.run([sys.executable, "-c", CHILD, str(steps), str(warm), str(forces)],
                       env=env, capture_output=True, text=True)
    if p.returncode:
        sys.exit(f"child failed ({threads} threads, src {src}):\n{p.stderr[-2000:]}")
    return json.loads(p.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer steps (a smoke run)")
    ap.add_argument("--steps", type=int, default=None, help="timed steps (default 600; quick 60)")
    ap.add_argument("--baseline-src", default=None, help="src/ of the serial code's checkout")
    ap.add_argument("--out", type=Path, default=OUT, help="result file (default: %(default)s)")
    a = ap.parse_args()
    load_before = os.getloadavg()[0]
    steps = a.steps or (60 if a.quick else 600)
    warm = 20
    configs = [("parallel kernels, 1 thread", 1, None), ("parallel kernels, 2 threads", 2, None)]
    if a.baseline_src:
        if not (Path(a.baseline_src) / "terradyn" / "sph" / "plate3d.py").is_file():
            sys.exit(f"error: --baseline-src {a.baseline_src}: no terradyn/sph/plate3d.py there")
        configs.insert(0, ("serial kernels (2ab80eb), 1 thread", 1, a.baseline_src))
    tmp = Path(os.environ.get("TMPDIR", "/tmp"))
    rows, same = [], {}
    for load in (0, 2):
        procs = hogs(load)
        try:
            time.sleep(0.5)
            for name, threads, src in configs:
                ff = tmp / f"sph_threads3d_{os.getpid()}_{load}_{threads}_{bool(src)}.npy"
                r = run(threads, src, steps, warm, ff) | {"config": name, "busy_processes": load}
                rows.append(r)
                if not src:
                    same.setdefault(load, []).append(np.load(ff))
                ff.unlink(missing_ok=True)
                print(f"{name:38s} busy={load}  {r['ms_per_step']:8.1f} ms/step  "
                      f"({r['particle_steps_per_s'] / 1e6:.2f} M particle-steps/s, "
                      f"{r['particles']} particles)", file=sys.stderr)
        finally:
            for p in procs:
                p.kill()
    for load in (0, 2):
        one = next(r for r in rows if r["busy_processes"] == load and r["config"].endswith("1 thread")
                   and "parallel" in r["config"])
        for r in rows:
            if r["busy_processes"] == load:
                r["speedup_vs_parallel_1_thread"] = one["ms_per_step"] / r["ms_per_step"]
    bitwise = {str(k): bool(np.array_equal(v[0], v[1])) for k, v in same.items()}
    res = {"machine": {"platform": platform.platform(), "cpus": os.cpu_count(),
                       "load_avg_1min_before": load_before,
                       "load_avg_1min_after": os.getloadavg()[0]},
           "scene": "3D leg bed (poppy LP, 4 mm, flat leg dragged at theta = 0)",
           "steps": steps, "warmup_steps": warm, "rows": rows,
           "forces_bitwise_equal_1_vs_2_threads": bitwise}
    if not a.quick:
        atomic_write_text(a.out, json.dumps(res, indent=1))
    for r in rows:
        print(f"{r['config']:38s} busy={r['busy_processes']}  x{r['speedup_vs_parallel_1_thread']:.2f}"
              " vs parallel 1 thread")
    print(f"1 vs 2 threads bitwise equal: {bitwise}")


if __name__ == "__main__":
    main()
