"""3D SPH on the GPU against the CPU kernels, side by side in one run (issue 17: the 3D legs at
the resolutions that converge).

The scene is the production 3D leg bed of ``benchmarks/sph_threads3d.py`` (the 7.62 cm flat
leg, hip 2 cm above the surface, poppy LP, both halves in x, half domain in y), the leg hanging
straight down and dragged backwards at the tip speed of omega = 1.1 rad/s, so the lists are
rebuilt and the grains flow as in a stroke. For each --dx-mm: the GPU backend, and the CPU
backend (all Numba threads) where --cpu-dx-mm names that spacing; ms per step after --warm
untimed steps (compilation, first lists), particle-steps per second, the GPU / CPU speed ratio,
the largest force difference over the first steps (the two paths differ by rounding, which the
flow then grows), and the wall time a whole 3D leg run (``sph leg3d``: settling and the stroke)
would take at that speed.

    python benchmarks/bench_sph_gpu3d.py [--dx-mm 4 3 2.5] [--cpu-dx-mm 4] [--steps 400]
        [--warm 50] [--allow-sim]

``--allow-sim`` runs under NUMBA_ENABLE_CUDASIM=1 (a smoke test of this script: the simulator's
timings mean nothing; use --dx-mm 12 --steps 2 --warm 1). Writes
benchmarks/results/sph_gpu3d.json (``--out``)."""
from __future__ import annotations

import argparse
import json
import math
import os
import platform
import time
from pathlib import Path

import numpy as np

OUT = Path(__file__).parent / "results" / "sph_gpu3d.json"


def leg_bed(dx: float, backend: str):
    from terradyn.sph import plate3d as P
    from terradyn.sph.state import SPHConfig

    L, hip, pad, omega = 0.0762, 0.02, 0.06, 1.1
    cz = hip - 0.5 * L
    sc = P.plate_scene("poppy LP", config=SPHConfig(dx=dx, settle_time=0.0, backend=backend),
                       length=L, half_x=math.sqrt(L * L - hip * hip) + pad, depth=L - hip + pad,
                       mirror_x=False, pose=(0.0, cz, -math.pi / 2))
    s = P.Solver3D(sc, plate_speed=omega * L)
    return s, cz, -omega * 0.5 * L


def time_backend(dx: float, backend: str, steps: int, warm: int) -> tuple[dict, np.ndarray]:
    s, cz, vx = leg_bed(dx, backend)
    n = warm + steps
    pose = np.zeros((n, 6))
    pose[:, 0] = vx * s.dt * np.arange(n)
    pose[:, 1] = cz
    pose[:, 2] = -math.pi / 2
    pose[:, 3] = vx
    f0 = s.advance(pose[:warm], np.zeros(warm))
    t = time.perf_counter()
    f = s.advance(pose[warm:], np.zeros(steps))
    el = time.perf_counter() - t
    from terradyn.sph import plate3d as P

    return ({"backend": s.backend, "particles": int(s.nr), "ghosts": int(s.ip[P.I_NG]),
             "dt_s": s.dt, "c0_m_s": s.c0, "h_m": s.h, "steps": steps, "ms_per_step": el / steps * 1e3,
             "particle_steps_per_s": s.nr * steps / el, "lost": s.lost},
            np.concatenate([f0, f]))


def leg_run_steps(dx: float, dt: float, c0: float, h: float) -> int:
    """Steps of a whole ``leg3d`` run (flat leg, poppy LP, hip 2 cm, omega 1.1 rad/s): the
    settling (15 bed-depth sound transits) and the stroke over the contact window."""
    L, hip, pad, omega = 0.0762, 0.02, 0.06, 1.1
    settle = 15.0 * (L - hip + pad) / c0
    window = 2.0 * math.acos(hip / L) + 2.0 * (2 * h + dx) / L  # about the contact, rad
    return int(math.ceil((settle + window / omega) / dt))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dx-mm", nargs="+", type=float, default=[4.0, 3.0, 2.5])
    ap.add_argument("--cpu-dx-mm", nargs="*", type=float, default=[4.0],
                    help="also time the CPU kernels at these spacings (4 mm: ~0.1 s a step on 2 cores)")
    ap.add_argument("--steps", type=int, default=400)
    ap.add_argument("--warm", type=int, default=50)
    ap.add_argument("--allow-sim", action="store_true")
    ap.add_argument("--out", type=Path, default=OUT)
    a = ap.parse_args(argv)
    if a.steps < 1 or a.warm < 1 or any(not 1.0 <= d <= 20.0 for d in a.dx_mm + a.cpu_dx_mm):
        ap.error("steps, warm: >= 1; dx-mm: 1 to 20 mm")
    from numba import config, cuda

    sim = bool(config.ENABLE_CUDASIM)
    if sim and not a.allow_sim:
        ap.error("NUMBA_ENABLE_CUDASIM=1: the simulator's timings mean nothing (--allow-sim "
                 "for a smoke test)")
    if not sim and not cuda.is_available():
        ap.error("no CUDA GPU: this benchmark compares the GPU with the CPU")
    if a.out.exists() and a.out.suffix != ".json":
        ap.error(f"out: a .json file, got {a.out}")
    import numba

    rows = []
    for dxm in a.dx_mm:
        dx = dxm * 1e-3
        g, fg = time_backend(dx, "gpu", a.steps, a.warm)
        row = {"dx_mm": dxm, "leg_run_steps": leg_run_steps(dx, g["dt_s"], g["c0_m_s"], g["h_m"]),
               "gpu": g}
        row["leg_run_minutes_gpu"] = row["leg_run_steps"] * g["ms_per_step"] / 6e4
        if dxm in a.cpu_dx_mm:
            c, fc = time_backend(dx, "cpu", a.steps, a.warm)
            row["cpu"] = {**c, "threads": numba.get_num_threads()}
            row["gpu_over_cpu_speed"] = c["ms_per_step"] / g["ms_per_step"]
            row["leg_run_minutes_cpu"] = row["leg_run_steps"] * c["ms_per_step"] / 6e4
            k = min(50, len(fc))
            scale = max(float(np.abs(fc[:k]).max()), 1e-300)
            row["force_rel_diff_first_steps"] = float(np.abs(fc[:k] - fg[:k]).max() / scale)
            row["force_rel_diff_steps"] = k
        rows.append(row)
        print(json.dumps(row), flush=True)
    gpu_name = "CUDA simulator" if sim else cuda.get_current_device().name
    if isinstance(gpu_name, bytes):
        gpu_name = gpu_name.decode()
    res = {"command": "python benchmarks/bench_sph_gpu3d.py", "gpu": gpu_name, "simulator": sim,
           "machine": f"{platform.machine()}, {os.cpu_count()} cores",
           "when": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()), "rows": rows}
    from terradyn.io import atomic_write_text

    atomic_write_text(a.out, json.dumps(res, indent=1) + "\n")
    print(f"wrote {a.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
