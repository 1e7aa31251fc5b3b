"""Bed size of the SPH leg scenes (issue 17, item 5: a shorter run is allowed "when shown not to
change the forces"): the three legs of the rotating-leg test (Li 2013 Fig. S5; hip 2 cm,
-135..135 deg, omega 1.1 rad/s) with the granular bed reaching --pads cm beyond the leg's path
below the surface (``SPHConfig.bed_pad``; 6 cm is the default), each the mean curve of
--realizations runs (run j with the hip j x 10 nm higher, as in ``sph validate``).

    python benchmarks/sph_bed_size.py --medium "poppy LP" [--dx-mm 2.5] [--pads 6 4 3]
        [--realizations 2] [--legs flat c reverse-c] [--store .sph-runs]
    python benchmarks/sph_bed_size.py --medium "poppy LP" --plate-pads 16 24 [--plate-below-cm 7.62]
        [--friction-deg X]
    python benchmarks/sph_bed_size.py --summarize

Records per run: peaks of Fz (lift) and Fx (thrust), particles, steps and wall time; the
summary gives, per medium, leg and pad, the change of each mean-curve peak from the 6 cm bed,
the RMS difference of the mean curves from the 6 cm bed over the angles where the leg is
near the bed (1 deg steps; as a
fraction of the 6 cm peak), and the run-to-run scatter of the peaks at 6 cm as the yardstick.
Finished runs are kept in --store (``terradyn.sph.suite.leg_run``) and in the result file, so
the study resumes; two studies (one per medium) may run at once, each merging under a lock
into benchmarks/results/sph_bed_size.json. A study, not a timing benchmark: wall times are
recorded as run."""
from __future__ import annotations

import argparse
import fcntl
import json
import os
import platform
import time
from pathlib import Path

OUT = Path(__file__).parent / "results" / "sph_bed_size.json"
REF_PAD_CM = 6.0


def _merge(update) -> dict:
    """Apply ``update(data)`` to the result file under an exclusive lock; returns the data."""
    OUT.parent.mkdir(parents=True, exist_ok=True)
    with open(OUT.with_suffix(".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        data = json.loads(OUT.read_text()) if OUT.exists() else {"runs": {}}
        update(data)
        from terradyn.io import atomic_write_text

        atomic_write_text(OUT, _dump(data))
        return data


def _dump(data: dict) -> str:
    """JSON text with one line per run (each holds two 271-sample curves)."""
    parts = []
    for k, v in data.items():
        if k in ("runs", "plate_runs"):
            inner = ",\n".join(f"  {json.dumps(rk)}: {json.dumps(rv, allow_nan=False)}"
                               for rk, rv in sorted(v.items()))
            parts.append(f' {json.dumps(k)}: {{\n{inner}\n }}')
        else:
            parts.append(f" {json.dumps(k)}: {json.dumps(v, indent=1, allow_nan=False)}")
    return "{\n" + ",\n".join(parts) + "\n}\n"


def summarize(data: dict) -> dict:
    import numpy as np

    runs = data["runs"]
    groups: dict[tuple, list] = {}
    for r in runs.values():
        groups.setdefault((r["medium"], r["dx_mm"], r["leg"], r["pad_cm"], r.get("friction_set_deg") or 0.0),
                          []).append(r)
    out = {}
    for (medium, dx, leg, pad, phi), rs in sorted(groups.items()):
        ref = groups.get((medium, dx, leg, REF_PAD_CM, 0.0))
        if not ref:
            continue
        n = min(len(rs), len(ref))
        rs = sorted(rs, key=lambda r: r["j"])[:n]
        ref = sorted(ref, key=lambda r: r["j"])[:n]
        row = {"realizations": n, "particles": rs[0]["particles"],
               "particles_ref": ref[0]["particles"],
               "wall_s_mean": round(float(np.mean([r["wall_s"] for r in rs])), 1),
               "wall_s_ref_mean": round(float(np.mean([r["wall_s"] for r in ref])), 1)}
        for comp, name in (("Fz", "lift"), ("Fx", "thrust")):
            cur = np.mean([r["curve_" + comp] for r in rs], axis=0)
            base = np.mean([r["curve_" + comp] for r in ref], axis=0)
            p_cur, p_ref = float(cur.max()), float(base.max())
            m = (cur != 0) | (base != 0)  # the leg near the bed in either
            runs_ref = [max(r["curve_" + comp]) for r in ref]
            row[name] = {"peak_N": round(p_cur, 4), "peak_ref_N": round(p_ref, 4),
                         "change_pct": round(100 * (p_cur / p_ref - 1), 2),
                         "rms_diff_over_peak_pct": round(100 * float(np.sqrt(np.mean((cur - base)[m] ** 2))) / p_ref, 2),
                         "ref_run_spread_pct": round(100 * (max(runs_ref) - min(runs_ref)) / p_ref, 2) if n > 1 else None}
        out[f"{medium}|{dx:g}mm|{leg}|pad {pad:g}cm" + (f"|phi {phi:g}" if phi else "")] = row
    return out


def vs_measured(data: dict) -> dict:
    """Per medium, pad and friction angle: each leg's mean curve against Li 2013 Fig. S5's
    measured curve, scored as ``terradyn sph validate`` scores it
    (``terradyn.sph.suite.leg_scores``: peak difference, RMS over the measured angles, RFT's
    RMS on the measured grid, linear), and the count of peaks within 15 % and of RMS no
    larger than RFT's."""
    import numpy as np

    from terradyn.sph.suite import leg_scores

    groups: dict[tuple, list] = {}
    for r in data["runs"].values():
        groups.setdefault((r["medium"], r["dx_mm"], r["pad_cm"], r.get("friction_set_deg") or 0.0,
                           r["leg"]), []).append(r)
    out: dict = {}
    for (medium, dx, pad, phi, leg), rs in sorted(groups.items()):
        curves = {c: np.mean([r["curve_" + c] for r in rs], axis=0) for c in ("Fz", "Fx")}
        sc = leg_scores(medium, rs[0]["theta_deg"], curves["Fz"], curves["Fx"],
                        omega=rs[0]["omega_rad_s"], leg=leg)
        key = f"{medium}|{dx:g}mm|pad {pad:g}cm" + (f"|phi {phi:g}" if phi else "")
        grp = out.setdefault(key, {"legs": {}, "peaks_within_15pct": 0, "rms_not_above_rft": 0,
                                   "checks": 0})
        row = {"realizations": len(rs)}
        for comp, name in (("Fz", "lift"), ("Fx", "thrust")):
            peak, meas = float(curves[comp].max()), sc[f"measured_peak_{name}_N"]
            diff = 100 * (peak / meas - 1)
            rms_s, rms_r = sc[f"rms_{name}_N"], sc[f"rms_{name}_rft_N"]
            row[name] = {"peak_N": round(peak, 4), "measured_N": round(meas, 4),
                         "diff_pct": round(diff, 1), "rms_N": rms_s, "rms_rft_N": rms_r}
            grp["peaks_within_15pct"] += abs(diff) <= 15
            grp["rms_not_above_rft"] += rms_s <= rms_r
            grp["checks"] += 1
        grp["legs"][leg] = row
    return out


def summarize_plate(data: dict) -> dict:
    """Per medium and bed: the plate test's alpha_z (mean of the runs, N/cm^3) and its change
    from the calibration's bed (``pad_cm`` None)."""
    import numpy as np

    groups: dict[tuple, list] = {}
    for r in data.get("plate_runs", {}).values():
        groups.setdefault((r["medium"], r["dx_mm"], r["pad_cm"] or 0.0, r.get("below_cm") or 0.0,
                           r.get("friction_set_deg") or 0.0), []).append(r)
    out = {}
    for (medium, dx, pad, below, phi), rs in sorted(groups.items()):
        ref = groups.get((medium, dx, 0.0, 0.0, phi))
        a = [r["alpha_z_N_per_cm3"] for r in rs]
        row = {"runs": len(rs), "particles": rs[0]["particles"],
               "bed_width_m": rs[0]["bed_width_m"], "bed_depth_m": rs[0]["bed_depth_m"],
               "alpha_z_N_per_cm3": round(float(np.mean(a)), 4),
               "run_spread_pct": round(100 * (max(a) - min(a)) / float(np.mean(a)), 2) if len(a) > 1 else None,
               "wall_s_mean": round(float(np.mean([r["wall_s"] for r in rs])), 1)}
        if ref:
            a0 = float(np.mean([r["alpha_z_N_per_cm3"] for r in ref]))
            row["change_from_calibration_bed_pct"] = round(100 * (float(np.mean(a)) / a0 - 1), 2)
        out[f"{medium}|{dx:g}mm|" + ("calibration bed" if pad == 0.0 else f"pad {pad:g}cm")
            + (f"|below {below:g}cm" if below else "") + (f"|phi {phi:g}" if phi else "")] = row
    return out


def plate_study(a) -> None:
    """The plate test (the calibration, ``terradyn.sph.calibration.plate_slope``) in the
    calibration's bed and in beds reaching --plate-pads cm beyond the plate's edges and below
    its deepest point (with --plate-below-cm, that far below it instead, so that the reach
    beside the plate and below it are seen apart); --friction-deg sets the angle."""
    import numpy as np

    from terradyn.sph.calibration import plate_slope
    from terradyn.sph.materials import from_medium
    from terradyn.sph.state import SPHConfig
    from terradyn.units import CM, N_PER_CM3

    mat = from_medium(a.medium, dx=a.dx_mm * 1e-3, friction_deg=a.friction_deg)
    below = a.plate_below_cm
    for pad in [None, *a.plate_pads]:
        for j in range(a.realizations):
            tag = ("calibration bed" if pad is None else f"pad {pad:g}cm"
                   + ("" if below is None else f"|below {below:g}cm"))
            key = (f"{a.medium}|{a.dx_mm:g}mm|{tag}"
                   + ("" if a.friction_deg is None else f"|phi {a.friction_deg:g}") + f"|j{j}")
            if OUT.exists() and key in json.loads(OUT.read_text()).get("plate_runs", {}):
                continue
            cfg = SPHConfig(dx=a.dx_mm * 1e-3, bed_pad=None if pad is None else pad * CM)
            r = plate_slope(mat, config=cfg, first=j,
                            below=None if pad is None or below is None else below * CM)
            run = json.loads(r["series"].attrs["input"])["run"]
            row = {"medium": a.medium, "dx_mm": a.dx_mm, "pad_cm": pad, "j": j,
                   "below_cm": None if pad is None else below, "friction_set_deg": a.friction_deg,
                   "friction_deg": round(float(np.degrees(mat.friction)), 3),
                   "alpha_z_N_per_cm3": round(r["alpha_z"] / N_PER_CM3, 5),
                   "slope_N_per_cm3": round(r["slope"] / N_PER_CM3, 5),
                   "particles": int(run["particles"]), "bed_width_m": run["bed_width_m"],
                   "bed_depth_m": run["bed_depth_m"], "wall_s": round(r["wall_s"], 1)}

            def put(data, key=key, row=row):
                data.setdefault("plate_runs", {})[key] = row
            _merge(put)
            print(key, row["particles"], row["wall_s"], row["alpha_z_N_per_cm3"], flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--medium", default="poppy LP")
    ap.add_argument("--dx-mm", type=float, default=2.5)
    ap.add_argument("--pads", type=float, nargs="+", default=[6.0, 4.0, 3.0], help="cm")
    ap.add_argument("--legs", nargs="+", default=["flat", "c", "reverse-c"])
    ap.add_argument("--realizations", type=int, default=2)
    ap.add_argument("--omega", type=float, default=1.1)
    ap.add_argument("--store", default=".sph-runs")
    ap.add_argument("--friction-deg", type=float, default=None,
                    help="legs: this friction angle instead of the shipped calibration's "
                         "(e.g. one calibrated in a larger plate bed, sph calibrate --plate-bed-pad-cm)")
    ap.add_argument("--plate-pads", type=float, nargs="*", default=None,
                    help="cm; run the plate test (calibration bed and these) instead of the legs")
    ap.add_argument("--plate-below-cm", type=float, default=None,
                    help="cm; the plate's padded beds reach this far below the plate (default: the pad)")
    ap.add_argument("--summarize", action="store_true")
    a = ap.parse_args()
    if a.summarize:
        def upd(data):
            data["summary"] = summarize(data)
            data["summary_vs_measured"] = vs_measured(data)
            if data.get("plate_runs"):
                data["summary_plate"] = summarize_plate(data)
        d = _merge(upd)
        print(json.dumps({k: d[k] for k in ("summary", "summary_plate", "summary_vs_measured") if k in d},
                         indent=1))
        return

    if a.plate_pads is not None:
        plate_study(a)
        return
    import numpy as np

    import terradyn as td
    from terradyn.sph.materials import from_medium
    from terradyn.sph.state import SPHConfig
    from terradyn.sph.suite import leg_run
    from terradyn.units import CM, DEG

    mat = from_medium(a.medium, dx=a.dx_mm * 1e-3, friction_deg=a.friction_deg)
    for pad in a.pads:
        cfg = SPHConfig(dx=a.dx_mm * 1e-3, bed_pad=pad * CM)
        for leg in a.legs:
            for j in range(a.realizations):
                key = (f"{a.medium}|{a.dx_mm:g}mm|{leg}|pad {pad:g}cm"
                       + ("" if a.friction_deg is None else f"|phi {a.friction_deg:g}") + f"|j{j}")
                if OUT.exists() and key in json.loads(OUT.read_text())["runs"]:
                    continue
                mot = td.Rotation(omega=a.omega, hip_height=2 * CM + 1e-8 * j, theta_start=-135 * DEG,
                                  theta_end=135 * DEG, n_theta=271)
                t0 = time.perf_counter()
                ds, stored = leg_run(leg, mot, mat, cfg, store=a.store)
                wall = time.perf_counter() - t0
                run = json.loads(ds.attrs["input"])["run"]
                th = ds.theta.values
                row = {"medium": a.medium, "dx_mm": a.dx_mm, "leg": leg, "pad_cm": pad, "j": j,
                       "friction_deg": round(float(np.degrees(mat.friction)), 3),
                       "friction_set_deg": a.friction_deg,
                       "omega_rad_s": a.omega, "particles": int(run["particles"]), "steps": int(run["steps"]),
                       "bed_width_m": run["bed_width_m"], "bed_depth_m": run["bed_depth_m"],
                       "wall_s": round(float(run["wall_seconds"]) if stored else wall, 1),
                       "theta_deg": [float(t) for t in th],
                       "curve_Fz": [round(float(v), 5) for v in np.interp(th, ds.theta.values, ds.Fz.values)],
                       "curve_Fx": [round(float(v), 5) for v in np.interp(th, ds.theta.values, ds.Fx.values)],
                       "peak_lift_N": round(float(ds.Fz.values.max()), 4),
                       "peak_thrust_N": round(float(ds.Fx.values.max()), 4)}

                def put(data, key=key, row=row):
                    data["runs"][key] = row
                    data["machine"] = f"{platform.machine()}, {os.cpu_count()} cores (shared)"
                    data["command"] = "python benchmarks/sph_bed_size.py --medium M"
                _merge(put)
                print(key, row["particles"], row["steps"], row["wall_s"], row["peak_lift_N"],
                      row["peak_thrust_N"], flush=True)


if __name__ == "__main__":
    main()
