"""Score the leg runs a validation has stored so far (issue 17), before it has finished.

``terradyn sph validate --scene legs ... --out DIR`` keeps each finished leg run in
``DIR/runs/leg-*.nc``; a validation of big beds takes a day on 2 cores, and a session may end
before it does. This reads whatever runs are there, averages each leg's runs (angle by angle,
as the validation averages its realizations) and scores the mean curves against Li 2013
Fig. S5 with :func:`terradyn.sph.suite.leg_scores`, RFT's RMS beside them.

    python benchmarks/sph_score_leg_store.py OUT.json "MEDIUM=DIR/runs" [...] [--what TEXT]

e.g. ``"poppy LP=/work/runs/validate_large_poppyLP/runs"``. Writes OUT.json (per leg and
medium: the number of runs read, each run's peaks, the mean curve's peaks against the
measured ones, and the RMS errors) and prints one line per leg. Only the runs stored by the
code of the newest run in a folder are scored (a resumed validation reruns what older code
stored); record the commit the runs were made with in --what.
A scoring script, not a timing benchmark."""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import xarray as xr

from terradyn.io import atomic_write_text
from terradyn.sph.suite import leg_scores


def score_store(medium: str, folder: Path) -> dict:
    files = sorted(Path(folder).glob("leg-*.nc"), key=lambda f: f.stat().st_mtime)
    loaded = [(f, xr.load_dataset(f, engine="h5netcdf")) for f in files]
    # a resumed validation reruns what other code stored (its key holds the code): score only
    # the runs of the code of the newest run, and say which were left out
    newest = json.loads(loaded[-1][1].attrs["terradyn_run_spec"])["code"] if loaded else None
    runs: dict[str, list] = {}
    for f, ds in loaded:
        spec = json.loads(ds.attrs["terradyn_run_spec"])
        if spec["code"] != newest:
            print(f"left out {f.name}: stored by other code than the newest run's")
            continue
        runs.setdefault(spec["leg"], []).append(ds)
    out = {}
    for leg, rs in sorted(runs.items()):
        th = rs[0].theta.values
        omega = json.loads(rs[0].attrs["terradyn_run_spec"])["motion"].get("omega", 1.1)
        fz = np.mean([r.Fz.values for r in rs], axis=0)
        fx = np.mean([r.Fx.values for r in rs], axis=0)
        sc = leg_scores(medium, th, fz, fx, omega=omega, leg=leg)
        row = {"n_runs": len(rs), "peak_lift_N": float(fz.max()), "peak_thrust_N": float(fx.max()),
               "peaks_lift_runs": [float(r.Fz.max()) for r in rs],
               "peaks_thrust_runs": [float(r.Fx.max()) for r in rs]}
        if sc:
            row |= {"lift_rel": row["peak_lift_N"] / sc["measured_peak_lift_N"] - 1,
                    "thrust_rel": row["peak_thrust_N"] / sc["measured_peak_thrust_N"] - 1} | sc
        out[f"{leg} leg, {medium}"] = row
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out", type=Path, help="the JSON file to write")
    ap.add_argument("stores", nargs="+", help='"MEDIUM=FOLDER" (a validation\'s runs/ folder)')
    ap.add_argument("--what", default="", help="what the runs are (command, commit), kept in the output")
    a = ap.parse_args(argv)
    res = {"what": a.what, "legs": {}}
    for item in a.stores:
        medium, _, folder = item.partition("=")
        if not folder or not Path(folder).is_dir():
            ap.error(f"stores: {item!r} is not MEDIUM=FOLDER with an existing folder")
        res["legs"] |= score_store(medium, Path(folder))
    for name, r in res["legs"].items():
        line = f"{name:28s} n={r['n_runs']} lift {r['peak_lift_N']:.2f} N thrust {r['peak_thrust_N']:.2f} N"
        if "lift_rel" in r:
            line += (f" ({100 * r['lift_rel']:+.1f} %, {100 * r['thrust_rel']:+.1f} %) RMS lift "
                     f"{r['rms_lift_N']:.3f}/{r['rms_lift_rft_N']:.3f} thrust {r['rms_thrust_N']:.3f}/"
                     f"{r['rms_thrust_rft_N']:.3f} N (ours/RFT)")
        print(line)
    atomic_write_text(a.out, json.dumps(res, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
