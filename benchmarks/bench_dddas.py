"""DDDAS speed: one particle-filter assimilation step (N = 5000) and fit + ten-fold CV.

Side by side in one run:
* ``numpy``: a straightforward NumPy particle filter (float64, (N, D) particles, np.exp,
  searchsorted resampling, Gaussian jitter) - the reference;
* ``numba``: terradyn's kernels (float32 structure-of-arrays, vectorised exp/log/hash RNG);
for both resamplers, over streams of noisy samples of a realistic linear observation model
(D coefficients, smooth basis rows over 271 leg angles; a fresh filter every 271 samples so
the posterior does not collapse and resampling keeps happening). A step = one
``ParticleFilter.update`` (weights, ESS, and the resampling + jitter when ESS < N/2), the
budget is <= 50 us mean and <= 250 us p99 (brief). Also the full streaming path
(``Assimilation.update`` with a theta value) and the surrogate fit + leave-one-out CV on ten
conditions of RFT data.

Usage: python benchmarks/bench_dddas.py [--quick]   (writes benchmarks/results/dddas.json)
"""
from __future__ import annotations

import json
import platform
import sys
import time
from pathlib import Path

import numpy as np

from terradyn.dddas.filter import ParticleFilter, warmup

QUICK = "--quick" in sys.argv
N = 5000
S = 271
PASSES = 3 if QUICK else 10


def problem(D, seed=0):
    rng = np.random.default_rng(seed)
    th = np.linspace(-1, 1, S)
    H = np.stack([np.cos(np.pi * (k + 1) * th / 2) * np.exp(-th ** 2) for k in range(D)], -1)
    H *= 2.0 / np.sqrt(D)
    off = 3.0 * np.exp(-4 * th ** 2)
    return rng, H, off


def run(backend, resample, D, sigma=0.05, seed=0):
    rng, H, off = problem(D, seed)
    times, n_res = [], 0
    for p in range(PASSES):
        c = rng.standard_normal(D)
        y = H @ c + off + sigma * rng.standard_normal(S)
        pf = ParticleFilter(np.zeros(D), prior_std=np.ones(D), n_particles=N, resample=resample,
                            backend=backend, rng=seed + p)
        hs = [np.ascontiguousarray(h) for h in H]
        for k in range(S):
            t0 = time.perf_counter()
            pf.update(hs[k], off[k], y[k], sigma)
            times.append(time.perf_counter() - t0)
        n_res += pf.n_resamples
    t = np.array(times) * 1e6
    return {"backend": backend, "resample": resample, "D": D, "steps": len(t),
            "mean_us": float(t.mean()), "p50_us": float(np.percentile(t, 50)),
            "p99_us": float(np.percentile(t, 99)), "max_us": float(t.max()),
            "resample_fraction": n_res / len(t)}


def streaming(D=4):
    """Assimilation.update(theta, Fz=...) on a surrogate: includes the row lookup."""
    import xarray as xr

    import terradyn as td
    from terradyn.dddas import Assimilation, Surrogate

    theta = np.linspace(-135, 135, S)
    xs = np.linspace(0.2, 1.1, 10)
    s = np.deg2rad(theta)
    series = [td.force_series("theta", theta, 0.3 * x * np.sin(s) + 0.1 * x ** 2 * np.sin(3 * s),
                              (1 + x) * np.cos(s) ** 2 + 0.2 * np.sin(x * 3 * s), model="bench", inputs={})
              for x in xs]
    sur = Surrogate(inputs=["omega"], ranks=(D, None, None)).fit(td.stack(series, {"omega": xs}))
    a = Assimilation(sur, {"omega": 0.55}, obs_std=0.05, prior_floor=1.0, n_particles=N, rng=0)
    rng = np.random.default_rng(1)
    fz = (1.55) * np.cos(s) ** 2 + 0.2 * np.sin(0.55 * 3 * s)
    times = []
    for p in range(PASSES):
        a = Assimilation(sur, {"omega": 0.55}, obs_std=0.05, prior_floor=1.0, n_particles=N, rng=p)
        for k in range(S):
            y = fz[k] + 0.05 * rng.standard_normal()
            t0 = time.perf_counter()
            a.update(theta[k], Fz=y)
            times.append(time.perf_counter() - t0)
    t = np.array(times) * 1e6
    return {"path": "Assimilation.update (numba, systematic)", "D": int(sur.ranks_[0]),
            "mean_us": float(t.mean()), "p50_us": float(np.percentile(t, 50)),
            "p99_us": float(np.percentile(t, 99))}


def fit_cv():
    import terradyn as td
    from terradyn.dddas import Surrogate, cross_validate
    from terradyn.dddas.studies import rft_standin

    ds = rft_standin("flat")
    t0 = time.perf_counter()
    Surrogate(inputs=["hip_height_cm"]).fit(ds)
    t_fit = time.perf_counter() - t0
    cv = cross_validate(ds, Surrogate(inputs=["hip_height_cm"]))
    return {"fit_s": t_fit, "cv10_s": float(cv.attrs["seconds"]), "cases": int(ds.sizes["case"])}


def main():
    import os

    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"machine: {platform.platform()}, {os.cpu_count()} CPUs, load average {load:.2f} "
          "(timings on a loaded machine are inflated, mostly in the mean and p99)")
    warmup()
    rows = []
    for D in ((4,) if QUICK else (4, 7)):
        for resample in ("systematic", "multinomial"):
            for backend in ("numpy", "numba"):
                rows.append(run(backend, resample, D))
    print(f"particle filter, N = {N}, one assimilation step (us); {PASSES} x {S} steps each")
    print(f"{'D':>2} {'resample':<12} {'backend':<6} {'mean':>8} {'p50':>8} {'p99':>8} {'max':>9} {'resampled':>9}")
    for r in rows:
        print(f"{r['D']:>2} {r['resample']:<12} {r['backend']:<6} {r['mean_us']:8.1f} {r['p50_us']:8.1f} "
              f"{r['p99_us']:8.1f} {r['max_us']:9.1f} {100 * r['resample_fraction']:8.1f}%")
    print("speed-up numba vs numpy (mean, p99):")
    for i in range(0, len(rows), 2):
        a, b = rows[i], rows[i + 1]
        print(f"  D={a['D']} {a['resample']:<12} x{a['mean_us'] / b['mean_us']:.1f}, x{a['p99_us'] / b['p99_us']:.1f}"
              f"   budget (<=50 mean, <=250 p99): {'MET' if b['mean_us'] <= 50 and b['p99_us'] <= 250 else 'NOT MET'}")
    st = streaming()
    print(f"streaming path {st['path']}, D={st['D']}: mean {st['mean_us']:.1f} us, "
          f"p50 {st['p50_us']:.1f} us, p99 {st['p99_us']:.1f} us")
    fc = fit_cv()
    print(f"surrogate fit {fc['fit_s']:.2f} s; leave-one-out CV over {fc['cases']} conditions {fc['cv10_s']:.2f} s")
    out = Path(__file__).parent / "results" / "dddas.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps({"machine": platform.platform(), "processor": platform.processor(),
                               "python": platform.python_version(), "quick": QUICK, "particles": N, "load_average": load,
                               "filter": rows, "streaming": st, "fit_cv": fc,
                               "when": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}, indent=2))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
