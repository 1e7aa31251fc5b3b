"""Resolution convergence of the SPH model (issue 17, item 4): the plate test (Li 2013 Table S3)
and the three legs' peaks in the rotating-leg test (Li 2013 Fig. S5) at several particle
spacings, with the change between successive resolutions.

    python benchmarks/sph_convergence.py [--medium "poppy LP"] [--dx-mm 2 2.5 3 4]
        [--youngs-mpa 0.25] [--omega 1.1] [--realizations 2] (plate runs; legs: the mean curve of that many runs) [--threads 1]
        [--scenes plate flat c reverse-c] [--dp-match plane-strain|bui2008] [--store .sph-runs]
(the medium's preset material: its shipped plate calibration where there is one)

Writes benchmarks/results/sph_convergence.json after every run (finished runs are kept and
skipped on a rerun, so the study can be interrupted and resumed; several studies may run at
once: each merges its runs into the file under a lock). Each leg run is also kept in --store
(``terradyn.sph.suite.leg_run``; git ignores it): a rerun with more --realizations runs only
the new ones, and an interrupted leg run resumes from its checkpoint. A study, not a timing
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


def _changes(runs: dict, medium: str, e: float, match: str, phi: float, omega: float = 1.1, real: int = 1) -> dict:
    """Relative change of every quantity between successive resolutions (coarse -> fine) of
    one material (medium, stiffness, Drucker-Prager match, friction angle), one leg speed and
    one number of leg realizations (the plate's runs join every set)."""
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
    dxs = sorted(by_dx, reverse=True)
    out = {}
    for a, b in zip(dxs, dxs[1:]):
        common = sorted(set(by_dx[a]) & set(by_dx[b]))
        out[f"{a:g} -> {b:g} mm"] = {k: round(by_dx[b][k] / by_dx[a][k] - 1.0, 4) for k in common}
    return out


def _merge_and_write(key: str, val: dict) -> None:
    """Add one run to the results file, re-reading it under a lock so that concurrent studies
    (other media or stiffnesses) do not overwrite each other's runs."""
    from terradyn.io import atomic_write_text

    with open(OUT.with_suffix(".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        res = json.loads(OUT.read_text()) if OUT.exists() else {
            "machine": f"{platform.machine()}, {os.cpu_count()} cores (shared with other work)",
            "command": "python benchmarks/sph_convergence.py", "runs": {}}
        res["runs"][key] = val
        sets = sorted({(r["medium"], r["youngs_MPa"], r["dp_match"], r["friction_deg"], r.get("omega", 1.1),
                        1 if r["scene"] == "plate" else r.get("realizations", 1)) for r in res["runs"].values()})
        res["changes"] = {
            f"{m}, E {e:g} MPa, {dm}, phi {phi:g} deg" + (f", omega {w:g}" if w != 1.1 else "")
            + (f", legs: mean of {k} runs" if k > 1 else ""): _changes(res["runs"], m, e, dm, phi, w, k)
            for m, e, dm, phi, w, k in sets}
        atomic_write_text(OUT, json.dumps(res, indent=1))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--medium", default="poppy LP")
    ap.add_argument("--dx-mm", type=float, nargs="+", default=[2.0, 2.5, 3.0, 4.0])
    ap.add_argument("--youngs-mpa", type=float, default=0.25)
    ap.add_argument("--omega", type=float, default=1.1, help="leg angular speed, rad/s")
    ap.add_argument("--realizations", type=int, default=2)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--dp-match", default="plane-strain", choices=["plane-strain", "bui2008"],
                    help="Drucker-Prager match to Mohr-Coulomb (terradyn.sph.materials)")
    ap.add_argument("--scenes", nargs="+", default=["plate", *LEGS], choices=["plate", *LEGS])
    ap.add_argument("--store", type=Path, default=Path(__file__).parent.parent / ".sph-runs",
                    help="directory of the stored leg runs (default: .sph-runs in the repository)")
    a = ap.parse_args()
    os.environ["NUMBA_NUM_THREADS"] = str(a.threads)  # before numba is imported

    from terradyn.sph.calibration import plate_slope
    from terradyn.sph.materials import from_medium
    from terradyn.sph.state import SPHConfig
    from terradyn.sph.suite import leg_vs_measured
    from terradyn.sph.validation import alpha_z_plate_measured
    from terradyn.media import MEDIA
    from terradyn.units import DEG, N_PER_CM3

    done = json.loads(OUT.read_text())["runs"] if OUT.exists() else {}
    mat = from_medium(a.medium, youngs=a.youngs_mpa * 1e6, dp_match=a.dp_match)
    for dx in a.dx_mm:
        cfg = SPHConfig(dx=dx * 1e-3)
        for scene in a.scenes:
            key = f"{scene}|{a.medium}|{a.youngs_mpa:g}MPa|{dx:g}mm|omega{a.omega:g}|{a.dp_match}"
            if abs(mat.friction / DEG - MEDIA[a.medium].repose_angle / DEG) > 1e-9:
                key += f"|phi{mat.friction / DEG:.2f}"  # a friction angle other than the repose angle
            if scene != "plate" and a.realizations > 1:
                key += f"|r{a.realizations}"  # legs: the mean curve of several runs (older keys: one run)
            if key in done:
                continue
            t0 = time.perf_counter()
            base = {"scene": scene, "medium": a.medium, "youngs_MPa": a.youngs_mpa, "dx_mm": dx,
                    "omega": a.omega, "friction_deg": round(mat.friction / DEG, 2),
                    "threads": a.threads, "dp_match": a.dp_match}
            if scene == "plate":
                r = plate_slope(mat, config=cfg, realizations=a.realizations)
                val = base | {"alpha_z_origin_N_cm3": round(r["alpha_z"] / N_PER_CM3, 4),
                              "alphas_N_cm3": [round(x / N_PER_CM3, 4) for x in r["alphas"]],
                              "slope_free_N_cm3": round(r["slope"] / N_PER_CM3, 4),
                              "intercept_kPa": round(r["intercept_Pa"] / 1e3, 3),
                              "measured_N_cm3": alpha_z_plate_measured(a.medium) / N_PER_CM3}
            else:
                r = leg_vs_measured(scene, mat, omega=a.omega, config=cfg, realizations=a.realizations,
                                    store=a.store)
                val = base | {"realizations": r["realizations"]} | {
                    c: {k: (round(v, 4) if isinstance(v, float) else [round(x, 4) for x in v])
                        for k, v in r[c].items() if isinstance(v, float) or k == "peaks_runs"}
                    for c in ("Fx", "Fz")}
            val["wall_s"] = round(time.perf_counter() - t0, 1)
            _merge_and_write(key, val)
            print(key, json.dumps(val), flush=True)


if __name__ == "__main__":
    main()
