"""3D-RFT speed, side by side with the straightforward NumPy implementation, and latency of
small RFT calls (2D standard curve, one foot evaluation) idle and on a busy machine.

* batch: element evaluations per second of the compiled 3D kernel (serial, parallel, and
  the work-size choice) against :func:`terradyn.rft3d.element_tractions` (NumPy), a
  2,000-triangle foot sole at many poses;
* single pose: one evaluation of the foot (``Evaluator``, ``wrench``, a forced parallel
  region, NumPy) - p50 / p99 over many calls;
* 2D standard curve (c-leg, 100 elements, 271 angles): the serial kernel that the work-size
  rule picks, against the parallel one it replaced for small calls, p50 / p99;
the serial batch again compiled with LLVM's loop vectorizer off (a child process,
``NUMBA_LOOP_VECTORIZE=0``: the scalar code the element loop ran as until 2026-12-04);
each with no extra load and with two busy processes (``while True: pass``) on the cores.

Usage: python benchmarks/bench_rft3d.py [--quick]    Writes benchmarks/results/rft3d.json.
"""
from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numba
import numpy as np

import terradyn as td
from terradyn import rft3d as r3
from terradyn.rft import engine as e2
from terradyn.rft3d import engine as e3
from terradyn.rft3d.presets import foot_sole

sys.path.insert(0, str(Path(__file__).parent))
from bench_threading import hogs  # noqa: E402  (the same two busy processes)

QUICK = "--quick" in sys.argv
OUT = Path(__file__).parent / "results" / "rft3d.json"
CALLS = 300 if QUICK else 2000


def pct(ts) -> dict:
    ts = np.asarray(ts) * 1e6
    return {"p50_us": float(np.percentile(ts, 50)), "p99_us": float(np.percentile(ts, 99)),
            "calls": len(ts)}


def timed(fn, calls=CALLS) -> dict:
    fn()
    fn()
    ts = np.empty(calls)
    for i in range(calls):
        t = time.perf_counter()
        fn()
        ts[i] = time.perf_counter() - t
    return pct(ts)


def best(fn, repeat=5) -> float:
    fn()
    out = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t)
    return min(out)


def poses(S, rng):
    X = np.column_stack([rng.normal(0, 0.01, S), rng.normal(0, 0.01, S), rng.uniform(-0.02, 0.0, S)])
    ang = rng.normal(0, 0.1, (S, 3))
    q = np.column_stack([np.ones(S), 0.5 * ang])
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return X, q, rng.normal(0, 0.2, (S, 3)), rng.normal(0, 0.5, (S, 3))


def batch_serial(X, q, V, W) -> dict:
    """Element evaluations per second of the serial kernel, float64 and float32."""
    foot, med = foot_sole(), r3.medium3d("poppy LP")
    return {f"compiled {n}serial": len(X) * len(foot) / best(
        lambda dt=dt: r3.wrench_batch(foot, X, q, V, W, med, parallel=False, dtype=dt))
        for n, dt in (("", np.float64), ("float32 ", np.float32))}


def scalar_batch() -> dict:
    """:func:`batch_serial` in a child process compiled with LLVM's loop vectorizer off
    (NUMBA_LOOP_VECTORIZE=0, a fresh Numba cache): the element loop as scalar code, as it ran
    until 2026-12-04 (a conditional load kept it from vectorizing)."""
    with tempfile.TemporaryDirectory(prefix="terradyn-scalar-numba-") as cache:
        env = dict(os.environ, NUMBA_LOOP_VECTORIZE="0", NUMBA_CACHE_DIR=cache)
        r = subprocess.run([sys.executable, __file__, "--scalar-child"] + (["--quick"] if QUICK else []),
                           env=env, capture_output=True, text=True, check=True)
    return {f"{k}, loop vectorizer off (scalar)": v
            for k, v in json.loads(r.stdout.strip().splitlines()[-1]).items()}


def measure(load: int) -> dict:
    rng = np.random.default_rng(0)
    foot = foot_sole()
    med = r3.medium3d("poppy LP")
    n = len(foot)
    res = {"busy_processes": load, "loadavg_1min_before": os.getloadavg()[0]}
    # batch throughput
    S = 400 if QUICK else 4000
    X, q, V, W = poses(S, rng)
    active = r3.element_tractions(foot, X[:100], q[:100], V[:100], W[:100], med)["active"].mean()
    batch = {}
    for name, par, dt in (("compiled, work-size choice", None, np.float64),
                          ("compiled parallel", True, np.float64),
                          ("compiled float32, work-size choice", None, np.float32)):
        t = best(lambda: r3.wrench_batch(foot, X, q, V, W, med, parallel=par, dtype=dt))
        batch[name] = S * n / t
    batch.update(batch_serial(X, q, V, W))  # "compiled serial", "compiled float32 serial"
    batch.update(scalar_batch())
    Sn = 50 if QUICK else 200
    t = best(lambda: r3.element_tractions(foot, X[:Sn], q[:Sn], V[:Sn], W[:Sn], med), 3)
    batch["numpy (element_tractions)"] = Sn * n / t
    res["batch_element_evals_per_s"] = batch
    res["batch_active_fraction"] = float(active)
    res["batch_poses"] = S
    # single pose of the foot
    ev = r3.Evaluator(foot, med)
    ev32 = r3.Evaluator(foot, med, dtype=np.float32)
    x0, q0, v0, w0 = X[0], q[0], V[0], W[0]
    single = {
        "Evaluator (serial, compiled)": timed(lambda: ev(x0, q0, v0, w0)),
        "Evaluator float32": timed(lambda: ev32(x0, q0, v0, w0)),
        "wrench() (checks + serial kernel)": timed(lambda: r3.wrench(foot, x0, q0, v0, w0, med)),
        "forced parallel region": timed(lambda: r3.wrench_batch(foot, x0, q0, v0, w0, med, parallel=True)),
        "numpy (element_tractions)": timed(lambda: r3.element_tractions(foot, x0, q0, v0, w0, med),
                                           max(50, CALLS // 10)),
    }
    res["foot_single_pose"] = single
    # 2D standard curve
    leg = td.c_leg()
    traj = td.standard_rotation().trajectory()
    fit = td.FITS["3 mm glass CP"]
    el = leg.elements()
    e2.net_forces(el, traj, fit)
    packed = el.__dict__["_packed"]
    curve = {
        "serial (work-size choice)": timed(lambda: e2._net_fourier(packed, traj, fit, 0.0, None)),
        "parallel (previous behaviour)": timed(lambda: e2._net_fourier(packed, traj, fit, 0.0, True)),
        "numpy (element_forces)": timed(lambda: e2._net_numpy(el, traj, fit, 0.0), max(50, CALLS // 10)),
    }
    res["standard_curve_2d"] = curve
    return res


def main() -> None:
    if "--scalar-child" in sys.argv:
        X, q, V, W = poses(400 if QUICK else 4000, np.random.default_rng(0))
        print(json.dumps(batch_serial(X, q, V, W)))
        return
    rows = []
    for load in (0, 2):
        procs = hogs(load)
        try:
            time.sleep(0.5)
            rows.append(measure(load))
        finally:
            for p in procs:
                p.kill()
    for r in rows:
        b = r["batch_element_evals_per_s"]
        base = b["numpy (element_tractions)"]
        print(f"\n== busy processes: {r['busy_processes']} (load average before: "
              f"{r['loadavg_1min_before']:.1f}) ==", file=sys.stderr)
        print(f"batch, foot {len(foot_sole())} triangles x {r['batch_poses']} poses "
              f"({100 * r['batch_active_fraction']:.0f} % of elements in contact):", file=sys.stderr)
        for k, v in b.items():
            print(f"  {k:54s} {v / 1e6:9.1f} M element evaluations/s  ({v / base:6.1f} x NumPy)",
                  file=sys.stderr)
        for title, key in (("foot, one pose", "foot_single_pose"),
                           ("2D standard curve (c-leg, 100 el x 271 angles)", "standard_curve_2d")):
            print(f"{title}:", file=sys.stderr)
            for k, v in r[key].items():
                print(f"  {k:34s} p50 {v['p50_us']:9.1f} us   p99 {v['p99_us']:9.1f} us", file=sys.stderr)
    OUT.parent.mkdir(exist_ok=True)
    OUT.write_text(json.dumps({
        "machine": {"cpus": os.cpu_count(), "platform": platform.platform(),
                    "python": platform.python_version(), "numba": numba.__version__,
                    "numba_threads": numba.get_num_threads(),
                    "threading_layer_env": os.environ.get("NUMBA_THREADING_LAYER", "default"),
                    "note": "each row records the load average before it (other users' work counts)"},
        "parallel_min_work_3d": e3.PARALLEL_MIN_WORK, "parallel_min_work_2d": e2.PARALLEL_MIN_WORK,
        "quick": QUICK, "rows": rows}, indent=2))
    print(f"wrote {OUT}", file=sys.stderr)


if __name__ == "__main__":
    main()
