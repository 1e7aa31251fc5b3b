"""Sweep overhead: 1000 small RFT cases in-process, on the local process pool and on a local
Dask cluster; with ``--sph``, the speed-up from one to two workers on small SPH cases.

Baseline: a plain in-process loop over the cases (build the leg and motion, ``rft.simulate``),
no storage. Every sweep row runs the same cases through :func:`terradyn.sweep.run` into a
fresh store (one NetCDF per case, written atomically by the driver) and reports

* ``wall_s``: the whole run, process-pool start-up included (the Dask workers are started
  and warmed before timing: a cluster is long-lived);
* ``per_case_ms``: wall / cases;
* ``overhead_ms``: worker time per case beyond the baseline compute,
  (wall x workers) / cases - baseline per case.

Usage: python benchmarks/bench_sweep.py [--quick] [--sph]   (writes benchmarks/results/sweep.json)
"""
from __future__ import annotations

import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

QUICK = "--quick" in sys.argv
SPH = "--sph" in sys.argv
N = 200 if QUICK else 1000
WORKERS = os.cpu_count() or 1

SPEC = f"""
[sweep]
name = "bench"
model = "rft"
[leg]
shape = "flat"
elements = 20
[motion]
n_theta = 19
[model]
medium = "3 mm glass CP"
[grid]
leg.length_cm = {{start = 5, stop = 10, num = {N}}}
"""

SPH_SPEC = """
[sweep]
name = "bench-sph"
model = "sph"
[leg]
shape = "flat"
[motion]
omega_rad_s = 1.0
theta_start_deg = -60
theta_end_deg = -30
n_theta = 16
[model]
medium = "3 mm glass CP"
quick = true
[grid]
leg.length_cm = [7.0, 7.3, 7.62, 8.0]
"""


def cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def main() -> None:
    import terradyn.sweep as sw
    from terradyn.sweep.execute import simulate_case

    spec = sw.parse(SPEC)
    cases = spec.cases
    simulate_case(cases[0].params)  # compile / load the kernel
    t0 = time.perf_counter()
    for c in cases:
        simulate_case(c.params)
    base = (time.perf_counter() - t0) / len(cases)
    rows = [{"executor": "plain loop (baseline)", "workers": 1, "cases": len(cases),
             "wall_s": base * len(cases), "per_case_ms": base * 1e3, "overhead_ms": 0.0}]

    def row(name, workers, summary):
        assert summary.done == len(cases) and not summary.failed, summary.failed
        w = summary.wall_s
        rows.append({"executor": name, "workers": workers, "cases": len(cases), "wall_s": w,
                     "per_case_ms": w / len(cases) * 1e3,
                     "overhead_ms": (w * workers / len(cases) - base) * 1e3})

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        row("sweep, in-process", 1, sw.run(spec, tmp / "serial.sweep", workers=0))
        row("sweep, local pool", WORKERS, sw.run(spec, tmp / "pool.sweep", workers=WORKERS))
        for v in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS"):
            os.environ[v] = "1"  # inherited by the Dask workers
        from distributed import Client, LocalCluster

        with LocalCluster(n_workers=WORKERS, threads_per_worker=1, processes=True, host="127.0.0.1",
                          dashboard_address=None) as cluster:
            with Client(cluster) as client:  # the sweep reuses this client
                client.run(simulate_case, cases[0].params)  # warm: imports + kernel load
                row("sweep, Dask local cluster", WORKERS, sw.run(spec, tmp / "dask.sweep", scheduler=cluster.scheduler_address))
        sph_rows = []
        if SPH:
            sspec = sw.parse(SPH_SPEC)
            for w in (1, 2):
                s = sw.run(sspec, tmp / f"sph{w}.sweep", workers=w)
                assert s.done == len(sspec.cases) and not s.failed, s.failed
                sph_rows.append({"workers": w, "cases": len(sspec.cases), "wall_s": s.wall_s})
            sph_rows[1]["speedup"] = sph_rows[0]["wall_s"] / sph_rows[1]["wall_s"]

    print(f"\nSweep overhead, {len(cases)} small RFT cases (flat leg, 20 elements x 19 angles); "
          f"{WORKERS} cores, {cpu_name()}")
    print(f"{'executor':<28}{'workers':>8}{'wall s':>10}{'ms/case':>10}{'overhead ms':>13}")
    for r in rows:
        print(f"{r['executor']:<28}{r['workers']:>8}{r['wall_s']:>10.2f}{r['per_case_ms']:>10.2f}{r['overhead_ms']:>13.2f}")
    for r in sph_rows:
        print(f"SPH quick cases: {r['cases']} on {r['workers']} worker(s): {r['wall_s']:.1f} s"
              + (f"  (speed-up {r['speedup']:.2f}x)" if "speedup" in r else ""))
    out = Path(__file__).parent / "results" / "sweep.json"
    out.parent.mkdir(exist_ok=True)
    res = {"benchmark": "sweep", "quick": QUICK, "cases": len(cases), "rows": rows, "sph": sph_rows,
           "machine": {"cpu": cpu_name(), "cores": os.cpu_count(), "python": platform.python_version(),
                       "platform": platform.platform()},
           "when": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
    if not SPH and out.exists():  # keep an earlier SPH measurement
        try:
            res["sph"] = json.loads(out.read_text()).get("sph", [])
        except ValueError:
            pass
    out.write_text(json.dumps(res, indent=1) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
