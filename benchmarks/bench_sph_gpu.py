"""SPH speed on the GPU: particle-steps per second of the GPU backend (Numba CUDA) on beds of
1e5 and 1e6 particles, side by side with the CPU backend on the 1e5 bed.

A particle-step = one particle advanced by one time step (two neighbour passes). The beds are
at rest (geostatic stress, every particle with a full neighbourhood), dx = 1 mm, hdx = 1.3,
four times as wide as deep, in a container of dummy-particle walls (counted in the particles).
The issue's target: at least 5e7 particle-steps/s on a bed of at least 1e6 particles.

Needs an NVIDIA GPU and numba-cuda (``pip install 'terradyn[gpu]'``; see docs/sph.md for a
machine without internet). Without a usable GPU it says so and exits with status 2.

Usage: python benchmarks/bench_sph_gpu.py [--sizes 1e5,1e6] [--cpu-size 1e5] [--steps N]
  --allow-sim  run even under NUMBA_ENABLE_CUDASIM=1 (a smoke test of this script: the
               simulator's timings mean nothing; use tiny --sizes).
Writes benchmarks/results/sph_gpu.json (not under the simulator).
"""
from __future__ import annotations

import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

OUT = Path(__file__).parent / "results" / "sph_gpu.json"


def _arg(name, default=None):
    if name in sys.argv:
        return sys.argv[sys.argv.index(name) + 1]
    return default


def bed(n_target: float, backend: str):
    from terradyn.sph import SPHConfig
    from terradyn.sph.scenes import bed_scene

    dx = 1e-3
    depth = np.sqrt(n_target / 4.0) * dx
    return bed_scene(width=4 * depth, depth=depth,
                     config=SPHConfig(dx=dx, settle_time=0.0, backend=backend))


def rate(n_target: float, backend: str, steps: int) -> dict:
    from terradyn.sph import Solver

    t0 = time.perf_counter()
    s = Solver(bed(n_target, backend))
    t_setup = time.perf_counter() - t0
    t0 = time.perf_counter()
    s.step()  # compiles the kernels (GPU: a few seconds; the CPU's are cached on disk)
    s.step()
    t_first = time.perf_counter() - t0
    t0 = time.perf_counter()
    f = None
    for _ in range(steps):
        f = s.step()  # each step returns the leg force: one small device-to-host copy
    el = time.perf_counter() - t0
    t0 = time.perf_counter()
    s.sync_to_host()
    t_sync = time.perf_counter() - t0
    ok = bool(np.isfinite(s.x).all()) and f is not None
    speed = float(np.hypot(s.vx[s.sidx], s.vz[s.sidx]).max())
    return {"backend": s.backend_name, "particles": int(s.n), "granular": int(len(s.sidx)),
            "steps": steps, "seconds": el, "ms_per_step": 1e3 * el / steps,
            "particle_steps_per_s": s.n * steps / el, "setup_s": t_setup,
            "first_two_steps_s": t_first, "sync_to_host_s": t_sync,
            "finite": ok, "max_speed_m_s": speed}


def main() -> int:
    from numba import config

    from terradyn.sph.solver import gpu_available

    sim = bool(config.ENABLE_CUDASIM)
    if sim and "--allow-sim" not in sys.argv:
        print("NUMBA_ENABLE_CUDASIM=1: the CUDA simulator is on; its timings mean nothing "
              "(add --allow-sim for a smoke test of this script).", file=sys.stderr)
        return 2
    if not gpu_available():
        print("no CUDA GPU available: this benchmark needs an NVIDIA GPU and numba-cuda "
              "(pip install 'terradyn[gpu]'; docs/sph.md, section 'GPU').", file=sys.stderr)
        return 2
    sizes = [float(v) for v in _arg("--sizes", "1e5,1e6").split(",")]
    cpu_size = float(_arg("--cpu-size", "1e5"))
    steps = _arg("--steps")
    rows = []
    for n in sizes:
        st = int(steps) if steps else (20 if sim else max(50, int(2e8 / n)))
        r = rate(n, "gpu", st)
        print(json.dumps(r), flush=True)
        rows.append(r)
    if cpu_size > 0:
        st = int(steps) if steps else (5 if sim else 20)
        r = rate(cpu_size, "cpu", st)
        print(json.dumps(r), flush=True)
        rows.append(r)
    from numba import cuda

    dev = "CUDA simulator"
    if not sim:
        d = cuda.get_current_device()
        dev = d.name.decode() if isinstance(d.name, bytes) else str(d.name)
    try:
        from importlib.metadata import version

        ncv = version("numba-cuda")
    except Exception:  # noqa: BLE001
        ncv = None
    import numba

    out = {"benchmark": "SPH bed at rest, dx = 1 mm, hdx = 1.3, particle-steps per second",
           "target": "GPU: >= 5e7 particle-steps/s on >= 1e6 particles (issue)",
           "device": dev, "cpu": platform.processor() or platform.machine(),
           "cpu_threads": numba.get_num_threads(), "numba": numba.__version__,
           "numba_cuda": ncv, "python": platform.python_version(), "results": rows,
           "date": time.strftime("%Y-%m-%d")}
    big = [r for r in rows if r["backend"] == "gpu" and r["particles"] >= 1e6]
    if big:
        out["meets_target"] = bool(max(r["particle_steps_per_s"] for r in big) >= 5e7)
    if not sim:
        OUT.parent.mkdir(parents=True, exist_ok=True)
        OUT.write_text(json.dumps(out, indent=1) + "\n")
        print(f"wrote {OUT}", file=sys.stderr)
    else:
        print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    os.environ.setdefault("PYTHONUNBUFFERED", "1")
    sys.exit(main())
