"""SPH speed: particle-steps per second of terradyn's Drucker-Prager solver, side by side with
PySPH's elasto-plastic Taylor-bar example (same particle count, OpenMP on all cores).

A particle-step = one particle advanced by one time step (terradyn: two neighbour passes,
velocity gradient then accelerations; PySPH Taylor bar: its PEC integrator, von Mises
plasticity, Wendland quintic with hdx = 2). terradyn runs a bed at rest (every particle has
a full neighbourhood) at hdx = 1.3 (its default, ~21 neighbours) and at hdx = 2.0 (the Taylor
bar's, ~50 neighbours: the like-for-like work per particle).

PySPH is not a dependency: give a Python that has it with ``--pysph PYTHON`` (or
``PYSPH_PYTHON``), e.g. ``python -m venv /tmp/pysph && /tmp/pysph/bin/pip install pysph``.

PySPH and terradyn's 1.9k-particle beds run in turns (3 rounds): the speed-up is reported per
round and as their median, since the shared machine's speed drifts by 10-30 % over minutes.

Usage: python benchmarks/bench_sph.py [--quick] [--pysph PYTHON] [--leg]
  --leg   also time the full rotating-leg test (flat leg, omega = 0.2 rad/s) at the
          resolution of the RFT comparison (long).
Writes benchmarks/results/sph.json.
"""
from __future__ import annotations

import json
import os
import platform
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

QUICK = "--quick" in sys.argv
OUT = Path(__file__).parent / "results" / "sph.json"


def _arg(name, default=None):
    if name in sys.argv:
        return sys.argv[sys.argv.index(name) + 1]
    return default


def terradyn_rate(n_target: int, hdx: float, steps: int) -> dict:
    from terradyn.sph import SPHConfig, Solver
    from terradyn.sph.scenes import bed_scene

    dx = 2.5e-3
    side = np.sqrt(n_target / 2.0) * dx  # bed twice as wide as deep
    sc = bed_scene(width=2 * side, depth=side, config=SPHConfig(dx=dx, hdx=hdx, settle_time=0.0))
    s = Solver(sc)
    s.advance(1)  # compile (or load the kernels from Numba's cache)
    t = time.perf_counter()
    s.advance(steps)  # as run() does: blocks of steps without Python between them
    el = time.perf_counter() - t
    return {"particles": s.n, "hdx": hdx, "steps": steps, "seconds": el,
            "particle_steps_per_s": s.n * steps / el}


def pysph_rate(python: str, steps: int) -> dict | None:
    import tempfile

    code = ("import pysph, os; print(os.path.join(os.path.dirname(pysph.__file__), "
            "'examples', 'solid_mech', 'taylor_bar.py'))")
    try:
        script = subprocess.run([python, "-c", code], capture_output=True, text=True,
                                check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return None
    env = dict(os.environ, OMP_NUM_THREADS=str(os.cpu_count()))
    if os.environ.get("GOMP_SPINCOUNT") == "10000":  # set by `import terradyn`, not the user:
        del env["GOMP_SPINCOUNT"]  # PySPH runs with GNU OpenMP's default (best when idle)
    res = {}
    with tempfile.TemporaryDirectory() as d:
        for n in (5, steps):  # the short run measures the fixed cost (setup, first step)
            p = subprocess.run([python, script, "--openmp", "--max-steps", str(n),
                                "--disable-output", "-d", d], capture_output=True, text=True,
                               env=env)
            txt = p.stdout + p.stderr
            run = re.search(r"Run took: ([0-9.eE+-]+) secs", txt)
            tot = re.search(r"Total: (\d+)", txt)
            if not run or not tot:
                return {"error": txt[-500:]}
            res[n] = (float(run.group(1)), int(tot.group(1)))
    (t5, npart), (tn, _) = res[5], res[steps]
    el = tn - t5
    return {"particles": npart, "steps": steps - 5, "seconds": el,
            "particle_steps_per_s": npart * (steps - 5) / el, "case": "examples/solid_mech/taylor_bar.py --openmp"}


def leg_run() -> dict:
    import terradyn as td
    from terradyn.sph.api import QUICK_DX

    t = time.perf_counter()
    ds = td.sph.simulate(td.flat_leg(), td.standard_rotation(), quick=True)
    run = td.series.inputs_of(ds)["run"]
    return {"case": "flat leg, omega 0.2 rad/s, -135..135 deg (contact part simulated)",
            "dx_m": QUICK_DX, "wall_seconds": time.perf_counter() - t, **run}


def main():
    import numba

    steps = 100 if QUICK else 400
    rows = {"machine": {"platform": platform.platform(), "cpus": os.cpu_count(),
                        "numba_threads": numba.get_num_threads(),
                        "load_avg_1min": os.getloadavg()[0]}}
    rows["terradyn"] = [terradyn_rate(n, hdx, steps) for n in ((1500, 6000) if QUICK else (1500, 6000, 24000))
                        for hdx in (1.3, 2.0)]
    py = _arg("--pysph", os.environ.get("PYSPH_PYTHON"))
    if py:
        # side by side: PySPH and terradyn's small beds in turns, so that both see the same
        # phases of a shared machine; the speed-up of each round, then their median
        rounds = []
        for _ in range(1 if QUICK else 3):
            p = pysph_rate(py, 205 if QUICK else 1005)
            if not p or "particle_steps_per_s" not in p:
                rows["pysph_taylor_bar"] = p
                break
            r = {"pysph": p, "terradyn": [terradyn_rate(1500, hdx, steps) for hdx in (1.3, 2.0)]}
            r["speedup"] = {str(t["hdx"]): t["particle_steps_per_s"] / p["particle_steps_per_s"]
                            for t in r["terradyn"]}
            rounds.append(r)
        if rounds:
            rows["side_by_side"] = rounds
            rows["pysph_taylor_bar"] = rounds[0]["pysph"]
    if "--leg" in sys.argv:
        rows["leg_run"] = leg_run()
    print(f"{'code':<28}{'particles':>10}{'hdx':>6}{'Mparticle-steps/s':>20}")
    for r in rows["terradyn"]:
        print(f"{'terradyn (bed at rest)':<28}{r['particles']:>10}{r['hdx']:>6}{r['particle_steps_per_s'] / 1e6:>20.3f}")
    for i, r in enumerate(rows.get("side_by_side", [])):
        p = r["pysph"]
        print(f"{f'PySPH Taylor bar, round {i + 1}':<28}{p['particles']:>10}{2.0:>6}"
              f"{p['particle_steps_per_s'] / 1e6:>20.3f}   terradyn "
              + ", ".join(f"{t['particle_steps_per_s'] / 1e6:.3f} (hdx {t['hdx']})"
                          for t in r["terradyn"]))
    if rows.get("side_by_side"):
        summary = {}
        for hdx in ("1.3", "2.0"):
            v = sorted(r["speedup"][hdx] for r in rows["side_by_side"])
            summary[hdx] = {"median": float(np.median(v)), "min": v[0], "max": v[-1]}
            print(f"  speed-up over PySPH at hdx={hdx}: median {summary[hdx]['median']:.1f}x "
                  f"(rounds {', '.join(f'{x:.1f}' for x in v)})")
        rows["speedup_summary"] = summary
    elif py:
        print(f"PySPH did not run: {rows.get('pysph_taylor_bar')}")
    if "leg_run" in rows:
        lr = rows["leg_run"]
        print(f"full rotating-leg test (flat, 0.2 rad/s, dx={lr['dx_m'] * 1e3:g} mm): "
              f"{lr['wall_seconds']:.0f} s, {lr['particles']} particles, {lr['steps']} steps")
    print(f"machine: {rows['machine']}")
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
