"""Resolution convergence of the SPH model (issue 17, item 4): the plate test (Li 2013 Table S3)
and the three legs' peaks in the rotating-leg test (Li 2013 Fig. S5) at several particle
spacings, with the change between successive resolutions.

    python benchmarks/sph_convergence.py [--medium "poppy LP"] [--dx-mm 2 2.5 3 4]
        [--youngs-mpa 0.25] [--friction-deg PHI] [--omega 1.1] [--realizations 2] (plate runs, a stored entry with fewer gets the missing ones; legs: the mean curve of that many runs) [--threads 1]
        [--scenes plate flat c reverse-c] [--dp-match plane-strain|bui2008] [--store .sph-runs]
    python benchmarks/sph_convergence.py --summarize   (recompute the changes and extrapolations)
(the medium's preset material: its shipped plate calibration where there is one)

Writes benchmarks/results/sph_convergence.json after every run (finished runs are kept and
skipped on a rerun, so the study can be interrupted and resumed; several studies may run at
once: each merges its runs into the file under a lock). Each leg run is also kept in --store
(``terradyn.sph.suite.leg_run``; git ignores it): a rerun with more --realizations runs only
the new ones, and an interrupted leg run resumes from its checkpoint. With three or more
resolutions of a quantity the file also holds its Richardson extrapolation from the three
finest (observed order, extrapolated value, grid convergence index; Celik et al. 2008), where
the changes are monotone. A study, not a timing
benchmark: wall times are recorded as run, on whatever else the machine was doing."""
from __future__ import annotations

import argparse
import fcntl
import json
import os
import platform
import time
from pathlib import Path

OUT = Path(__file__).parent / "results" / "sph_convergence.json"
LEGS = ("flat", "c", "reverse-c")


def _by_dx(runs: dict, medium: str, e: float, match: str, phi: float, omega: float = 1.1, real: int = 1) -> dict:
    """{dx_mm: {quantity: value}} of one material (medium, stiffness, Drucker-Prager match,
    friction angle), one leg speed and one number of leg realizations (the plate's runs join
    every set)."""
    by_dx: dict[float, dict] = {}
    for r in runs.values():
        if (r["medium"], r["youngs_MPa"], r["dp_match"], r["friction_deg"]) == (medium, e, match, phi) \
                and r.get("omega", 1.1) == omega and r.get("realizations", 1) in ((1, real) if r["scene"] == "plate" else (real,)):
            q = by_dx.setdefault(r["dx_mm"], {})
            if r["scene"] == "plate":
                q["plate alpha_z (through origin)"] = r["alpha_z_origin_N_cm3"]
                q["plate slope (free fit)"] = r["slope_free_N_cm3"]
            else:
                q[f"{r['scene']} lift peak"] = r["Fz"]["peak_sph"]
                q[f"{r['scene']} thrust peak"] = r["Fx"]["peak_sph"]
    return by_dx


def _changes(by_dx: dict) -> dict:
    """Relative change of every quantity between successive resolutions (coarse -> fine)."""
    dxs = sorted(by_dx, reverse=True)
    out = {}
    for a, b in zip(dxs, dxs[1:]):
        common = sorted(set(by_dx[a]) & set(by_dx[b]))
        out[f"{a:g} -> {b:g} mm"] = {k: round(by_dx[b][k] / by_dx[a][k] - 1.0, 4) for k in common}
    return out


def richardson(h: tuple[float, float, float], f: tuple[float, float, float]) -> dict:
    """Observed order, extrapolated value and fine-grid convergence index from three
    resolutions h1 < h2 < h3 (fine to coarse) with values f1, f2, f3: the procedure of Celik
    et al. 2008 (J. Fluids Eng. 130:078001, "Procedure for estimation and reporting of
    uncertainty due to discretization in CFD applications"), which allows unequal refinement
    ratios (here 1.2-1.25): p from the fixed point of
    p = |ln|e32 / e21| + ln((r21^p - s) / (r32^p - s))| / ln r21, e21 = f2 - f1, e32 = f3 - f2,
    s = sign(e32 / e21). ``monotone`` is False when the changes alternate in sign (s < 0):
    the order and extrapolation then describe noise, not convergence, and are not given."""
    import math

    (h1, h2, h3), (f1, f2, f3) = h, f
    r21, r32 = h2 / h1, h3 / h2
    e21, e32 = f2 - f1, f3 - f2
    out = {"h_mm": [h1, h2, h3], "values": [f1, f2, f3], "monotone": bool(e21 * e32 > 0)}
    if not out["monotone"]:
        return out
    p = 1.0
    for _ in range(200):
        q = math.log((r21 ** p - 1) / (r32 ** p - 1))
        pn = abs(math.log(abs(e32 / e21)) + q) / math.log(r21)
        if pn > 20:  # the finest change is tiny against the coarser one: no finite order to quote
            return out | {"order": None}
        if abs(pn - p) < 1e-10:
            break
        p = pn
    f_ext = (r21 ** p * f1 - f2) / (r21 ** p - 1)
    out |= {"order": round(p, 3), "extrapolated": round(f_ext, 4),
            "extrapolated_vs_finest": round(f_ext / f1 - 1, 4),
            "gci_fine": round(1.25 * abs(e21 / f1) / (r21 ** p - 1), 4)}
    return out


def _extrapolation(by_dx: dict) -> dict:
    """:func:`richardson` for every quantity at its three finest resolutions."""
    out = {}
    for k in sorted({k for q in by_dx.values() for k in q}):
        hs = sorted(dx for dx, q in by_dx.items() if k in q)[:3]
        if len(hs) == 3:
            out[k] = richardson(tuple(hs), tuple(by_dx[dx][k] for dx in hs))
    return out


def _merge_and_write(key: str | None, val: dict | None) -> None:
    """Add one run to the results file (None: none, only recompute the changes and the
    extrapolations), re-reading it under a lock so that concurrent studies (other media or
    stiffnesses) do not overwrite each other's runs."""
    from terradyn.io import atomic_write_text

    with open(OUT.with_suffix(".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        res = json.loads(OUT.read_text()) if OUT.exists() else {
            "machine": f"{platform.machine()}, {os.cpu_count()} cores (shared with other work)",
            "command": "python benchmarks/sph_convergence.py", "runs": {}}
        if key is not None:
            res["runs"][key] = val
        sets = sorted({(r["medium"], r["youngs_MPa"], r["dp_match"], r["friction_deg"], r.get("omega", 1.1),
                        1 if r["scene"] == "plate" else r.get("realizations", 1)) for r in res["runs"].values()})
        res["changes"], res["extrapolation"] = {}, {}
        for m, e, dm, phi, w, k in sets:
            name = (f"{m}, E {e:g} MPa, {dm}, phi {phi:g} deg" + (f", omega {w:g}" if w != 1.1 else "")
                    + (f", legs: mean of {k} runs" if k > 1 else ""))
            by_dx = _by_dx(res["runs"], m, e, dm, phi, w, k)
            res["changes"][name] = _changes(by_dx)
            if ext := _extrapolation(by_dx):
                res["extrapolation"][name] = ext
        atomic_write_text(OUT, json.dumps(res, indent=1, allow_nan=False))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--medium", default="poppy LP")
    ap.add_argument("--dx-mm", type=float, nargs="+", default=[2.0, 2.5, 3.0, 4.0])
    ap.add_argument("--youngs-mpa", type=float, default=0.25)
    ap.add_argument("--friction-deg", type=float, default=None,
                    help="friction angle, deg (default: the medium's production calibration, at 2.5 mm, "
                         "so that every resolution runs one material)")
    ap.add_argument("--omega", type=float, default=1.1, help="leg angular speed, rad/s")
    ap.add_argument("--realizations", type=int, default=2)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--dp-match", default="plane-strain", choices=["plane-strain", "bui2008"],
                    help="Drucker-Prager match to Mohr-Coulomb (terradyn.sph.materials)")
    ap.add_argument("--scenes", nargs="+", default=["plate", *LEGS], choices=["plate", *LEGS])
    ap.add_argument("--store", type=Path, default=Path(__file__).parent.parent / ".sph-runs",
                    help="directory of the stored leg runs (default: .sph-runs in the repository)")
    ap.add_argument("--summarize", action="store_true",
                    help="run nothing: recompute the changes and the Richardson extrapolations of the results file")
    a = ap.parse_args()
    if a.summarize:
        _merge_and_write(None, None)
        print(json.dumps(json.loads(OUT.read_text())["extrapolation"], indent=1))
        return
    os.environ["NUMBA_NUM_THREADS"] = str(a.threads)  # before numba is imported

    from terradyn.sph.calibration import plate_slope
    from terradyn.sph.materials import from_medium
    from terradyn.sph.state import SPHConfig
    from terradyn.sph.suite import leg_vs_measured
    from terradyn.sph.validation import alpha_z_plate_measured
    from terradyn.media import MEDIA
    from terradyn.units import DEG, N_PER_CM3

    done = json.loads(OUT.read_text())["runs"] if OUT.exists() else {}
    mat = from_medium(a.medium, youngs=a.youngs_mpa * 1e6, dp_match=a.dp_match, friction_deg=a.friction_deg)
    for dx in a.dx_mm:
        cfg = SPHConfig(dx=dx * 1e-3)
        for scene in a.scenes:
            key = f"{scene}|{a.medium}|{a.youngs_mpa:g}MPa|{dx:g}mm|omega{a.omega:g}|{a.dp_match}"
            if abs(mat.friction / DEG - MEDIA[a.medium].repose_angle / DEG) > 1e-9:
                key += f"|phi{mat.friction / DEG:.2f}"  # a friction angle other than the repose angle
            if scene != "plate" and a.realizations > 1:
                key += f"|r{a.realizations}"  # legs: the mean curve of several runs (older keys: one run)
            have = len(done[key].get("alphas_N_cm3", ())) if key in done else 0
            if key in done and (scene != "plate" or have >= a.realizations):
                continue
            t0 = time.perf_counter()
            base = {"scene": scene, "medium": a.medium, "youngs_MPa": a.youngs_mpa, "dx_mm": dx,
                    "omega": a.omega, "friction_deg": round(mat.friction / DEG, 2),
                    "threads": a.threads, "dp_match": a.dp_match}
            if scene == "plate":
                # a stored entry with fewer runs gets only the missing ones (runs have, have + 1, ...)
                r = plate_slope(mat, config=cfg, realizations=a.realizations - have, first=have)
                old = done.get(key, {})
                alphas = old.get("alphas_N_cm3", []) + [round(x / N_PER_CM3, 4) for x in r["alphas"]]
                slopes = old.get("slopes_N_cm3", [old["slope_free_N_cm3"]] * have if have else []) \
                    + [round(x / N_PER_CM3, 4) for x in r["slopes"]]
                # per-run intercepts were not kept before; the old mean stands for its runs
                icpts = [old["intercept_kPa"]] * have + [r["intercept_Pa"] / 1e3] * len(r["alphas"])
                val = base | {"alpha_z_origin_N_cm3": round(sum(alphas) / len(alphas), 4),
                              "alphas_N_cm3": alphas, "slopes_N_cm3": slopes,
                              "slope_free_N_cm3": round(sum(slopes) / len(slopes), 4),
                              "intercept_kPa": round(sum(icpts) / len(icpts), 3),
                              "measured_N_cm3": alpha_z_plate_measured(a.medium) / N_PER_CM3}
            else:
                r = leg_vs_measured(scene, mat, omega=a.omega, config=cfg, realizations=a.realizations,
                                    store=a.store)
                val = base | {"realizations": r["realizations"]} | {
                    c: {k: (round(v, 4) if isinstance(v, float) else [round(x, 4) for x in v])
                        for k, v in r[c].items() if isinstance(v, float) or k == "peaks_runs"}
                    for c in ("Fx", "Fz")}
                if r["realizations"] == 1:  # one run has no standard error (NaN); left out, as in sph validate
                    for c in ("Fx", "Fz"):
                        val[c].pop("peak_sem", None)
            val["wall_s"] = round(time.perf_counter() - t0 + done.get(key, {}).get("wall_s", 0.0) * (scene == "plate"), 1)
            _merge_and_write(key, val)
            print(key, json.dumps(val), flush=True)


if __name__ == "__main__":
    main()
