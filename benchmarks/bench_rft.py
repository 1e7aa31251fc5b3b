"""RFT speed, side by side in one run.

* baseline: a straightforward scalar implementation structured like the thesis's code - a
  Python loop over angles and elements, the closed-form kinematics per element, one
  interpolator call (scipy RegularGridInterpolator, linear, on the measured grid) per element;
* the engine on the same standard curve (C leg, 200 angles x 100 elements): compiled
  Fourier-fit kernel (float64 and float32), and the NumPy path with the measured grid;
* batch throughput: 1000 designs (the arc family) x 200 angles x 100 elements = 2e7 element
  evaluations, hip at rest (rotation) and moving hip (general planar motion).

Usage: python benchmarks/bench_rft.py [--quick]   (writes benchmarks/results/rft.json)
"""
from __future__ import annotations

import dataclasses
import json
import math
import platform
import sys
import time
from pathlib import Path

import numpy as np
from scipy.interpolate import RegularGridInterpolator

import terradyn as td
from terradyn.rft.engine import PackedElements, _net_fourier, net_forces

QUICK = "--quick" in sys.argv
N_THETA, N_EL = 200, 100


def scalar_baseline(table, thetas, n=N_EL, L=0.0762, w=0.0254, h=0.02):
    """C leg, thesis kinematics, one interpolator call per element (measured grid, linear)."""
    interp = RegularGridInterpolator((table.beta, table.gamma),
                                     np.stack([table.alpha_z, table.alpha_x], -1), method="linear")
    R = L / 2
    area = math.pi * R * w / n
    fx_all, fz_all = [], []
    for th in thetas:
        fx = fz = 0.0
        for i in range(1, n + 1):
            a = (i - 0.5) * math.pi / n
            beta = a + th
            gamma = -(a / 2 + th)
            depth = R * (math.cos(th) + math.cos(beta)) - h
            if depth <= 0:
                continue
            g = (gamma + math.pi) % (2 * math.pi) - math.pi  # mirror into the measured domain
            sign = 1.0
            b = beta
            if abs(g) > math.pi / 2:
                g = math.pi - g if g > 0 else -math.pi - g
                b, sign = -b, -1.0
            b = (b + math.pi / 2) % math.pi - math.pi / 2
            az, ax = interp((b, g))
            fz += az * depth * area
            fx += sign * ax * depth * area
        fx_all.append(fx)
        fz_all.append(fz)
    return np.array(fx_all), np.array(fz_all)


def best_time(fn, repeat, number):
    ts = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(number):
            fn()
        ts.append((time.perf_counter() - t0) / number)
    return min(ts)


def main():
    import numba

    fit = td.FITS["3 mm glass CP"]
    table = td.packaged_tables("linear")["3 mm glass CP"]
    rot = td.standard_rotation(N_THETA)
    traj = rot.trajectory()
    leg = td.c_leg(n=N_EL)
    el = leg.elements()
    rows = []

    # --- standard curve -------------------------------------------------------------
    thetas = rot.theta[: 20] if QUICK else rot.theta
    t0 = time.perf_counter()
    bx, bz = scalar_baseline(table, thetas)
    t_base = (time.perf_counter() - t0) * (N_THETA / len(thetas))
    ex, ez, _ = net_forces(el, traj, table)
    assert np.allclose(bz, ez[: len(thetas)], atol=1e-9) and np.allclose(bx, ex[: len(thetas)], atol=1e-9), \
        "baseline and engine disagree"
    rows.append(("standard curve", "scalar loop + interpolator call (table, linear)", t_base, 1.0))

    p64 = PackedElements.of([el])
    p32 = PackedElements.of([el], np.float32)
    _net_fourier(p64, traj, fit, 0.0)
    _net_fourier(p32, traj, fit, 0.0)
    t = best_time(lambda: _net_fourier(p64, traj, fit, 0.0), 7, 300)
    rows.append(("standard curve", "engine, Fourier fit, float64 (compiled)", t, t_base / t))
    t = best_time(lambda: _net_fourier(p32, traj, fit, 0.0), 7, 300)
    rows.append(("standard curve", "engine, Fourier fit, float32 (compiled)", t, t_base / t))
    t = best_time(lambda: net_forces(el, traj, fit), 7, 300)
    rows.append(("standard curve", "engine, Fourier fit, float64, public net_forces()", t, t_base / t))
    t = best_time(lambda: net_forces(el, traj, table), 3, 10)
    rows.append(("standard curve", "engine, measured table, linear (NumPy path)", t, t_base / t))
    from terradyn.rft.engine import _net_numpy

    t = best_time(lambda: _net_numpy(el, traj, fit, 0.0), 3, 20)
    rows.append(("standard curve", "engine, Fourier fit, NumPy path (no compiler)", t, t_base / t))

    # --- batch throughput -----------------------------------------------------------
    D = 100 if QUICK else 1000
    legs = [td.ArcLeg(0.0254, N_EL, 0.0762, k) for k in np.linspace(-1, 1, D)]
    els = [lg.elements() for lg in legs]
    n_eval = D * N_THETA * N_EL
    moving = dataclasses.replace(traj, hip_vx=np.full(N_THETA, -0.01))
    batch = {}
    for dtype in (np.float64, np.float32):
        P = PackedElements.of(els, dtype)
        for name, tr in (("rotation", traj), ("moving hip", moving)):
            _net_fourier(P, tr, fit, 0.0)
            t = best_time(lambda: _net_fourier(P, tr, fit, 0.0), 3, 2)
            key = f"{np.dtype(dtype).name}, {name}"
            batch[key] = n_eval / t
            rows.append((f"batch {D} designs", f"engine, Fourier fit, {key}", t, None))

    print(f"\nRFT benchmark ({platform.processor() or platform.machine()}, "
          f"{numba.config.NUMBA_NUM_THREADS} threads, numba {numba.__version__})")
    print(f"{'case':<20} {'implementation':<55} {'time':>12} {'speed-up':>10}")
    for case, impl, t, ratio in rows:
        r = f"{ratio:,.0f}x" if ratio else ""
        print(f"{case:<20} {impl:<55} {t * 1e3:>9.4f} ms {r:>10}")
    print(f"\nbatch throughput ({n_eval:.1e} element evaluations per call):")
    for k, v in batch.items():
        print(f"  {k:<22} {v:.3e} element evaluations / s")
    out = Path(__file__).parent / "results" / "rft.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps({
        "machine": {"cpu": platform.processor() or platform.machine(), "cores": numba.config.NUMBA_NUM_THREADS,
                    "python": platform.python_version(), "numba": numba.__version__, "numpy": np.__version__},
        "quick": QUICK,
        "standard_curve": [{"implementation": i, "seconds": t, "speedup_vs_scalar": r}
                           for c, i, t, r in rows if c == "standard curve"],
        "batch_element_evals_per_s": batch}, indent=2) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
