"""Can one plate test set a leg's forces? Peak leg force over the plate slope, medium by medium.

The SPH media have one free constant, the friction angle, set by one measurement, the plate
pushed straight down (alpha_z(0, pi/2), Li 2013 Table S3). In a rate-independent frictional
continuum a leg's peak force and the plate's slope then scale together (both ~ rho g x a
function of phi), so their ratio (N over N/cm^3 = cm^3) changes little from medium to medium.
This script puts that ratio beside the measured one for the flat leg (lift and thrust) in the
three media where a measured peak is known here:

* poppy LP and 0.3 mm glass CP: Li 2013 Fig. S5 (``terradyn/data/li2013_fig_s5_experiments.csv``);
* 3 mm glass CP: the peaks issue 17 quotes (3.07 N lift, 3.57 N thrust; the curves are not in
  this repository, and nothing here is fitted to them).

SPH rows: 2D, the mean curves of three runs at 2.5 mm (``results/sph_validate_legs.json``) and,
for 3 mm glass CP, the shipped training set at 0.2 and 1.1 rad/s
(``datasets/sph_legs_speeds.nc``); 3D at 4 mm (``results/sph_leg3d.json``, finite width). RFT on
each medium's measured grid (Table S5, linear) is the local-stress reference. Reads result
files only (seconds); writes ``results/sph_leg_plate_ratio.json``.

    python benchmarks/sph_leg_plate_ratio.py
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import xarray as xr

from terradyn.io import atomic_write_text
from terradyn.media import MEDIA, stress_model
from terradyn.motion import Rotation
from terradyn.rft import simulate
from terradyn.sph.suite import make_leg, measured_legs
from terradyn.units import CM, DEG, N_PER_CM3

HERE = Path(__file__).parent
RES = HERE / "results"
#: Issue 17's quoted measured flat-leg peaks in 3 mm glass CP (N): judged, never fitted.
ISSUE17_3MM_FLAT = {"Fz": 3.07, "Fx": 3.57}
MEDIA3 = ("poppy LP", "0.3 mm glass CP", "3 mm glass CP")


def main() -> None:
    exp = measured_legs()
    legs2d = {c["quantity"]: c["ours"] for c in json.loads((RES / "sph_validate_legs.json").read_text())["checks"]}
    legs3d = [p for p in json.loads((RES / "sph_leg3d.json").read_text())["points"]
              if p["kind"] == "finite" and p.get("leg", "flat") == "flat" and p["dx_mm"] == 4.0]
    ds = xr.open_dataset(HERE.parent / "datasets" / "sph_legs_speeds.nc")
    mot = Rotation(omega=0.2, hip_height=2 * CM, theta_start=-135 * DEG, theta_end=135 * DEG, n_theta=271)
    rows = []
    for m in MEDIA3:
        az = MEDIA[m].alpha_z_plate / N_PER_CM3  # N/cm^3, Table S3
        rft = simulate(make_leg("flat"), mot, stress_model(m, "table", interp="linear"))
        for comp, what in (("Fz", "lift"), ("Fx", "thrust")):
            e = exp[(exp.medium == m) & (exp.leg == "flat") & (exp.force == comp)]
            measured = float(e.force_N.max()) if len(e) else ISSUE17_3MM_FLAT[comp]
            row = {"medium": m, "component": what, "alpha_z_N_cm3": az,
                   "measured_source": "Li 2013 Fig. S5" if len(e) else "issue 17 (quoted)",
                   "measured": measured, "rft_table": float(rft[comp].max())}
            q = f"peak {what}, flat leg, {m}"
            if q in legs2d:
                row["sph2d_mean3_1.1"] = legs2d[q]
            if m == "3 mm glass CP":
                for om in (0.2, 1.1):
                    i = np.flatnonzero((ds.shape.values == "flat") & np.isclose(ds.omega_rad_s.values, om))[0]
                    row[f"sph2d_dataset_{om:g}"] = float(ds[comp].isel(case=i).max())
            p3 = [p for p in legs3d if p["medium"] == m]
            if p3:
                row["sph3d_4mm_1.1"] = p3[0]["peak_lift_N" if comp == "Fz" else "peak_thrust_N"]
            row["ratios_cm3"] = {k: row[k] / az for k in row
                                 if k in ("measured", "rft_table") or k.startswith("sph")}
            rows.append(row)
    keys = ["measured", "rft_table", "sph2d_mean3_1.1", "sph2d_dataset_0.2", "sph2d_dataset_1.1", "sph3d_4mm_1.1"]
    print("peak flat-leg force / plate alpha_z (cm^3); in brackets: over the measured ratio")
    print(f"{'medium':16s} {'':7s}" + "".join(f"{k:>19s}" for k in keys))
    for r in rows:
        cells = []
        for k in keys:
            v = r["ratios_cm3"].get(k)
            cells.append(f"{'-':>19s}" if v is None else
                         f"{v:>11.1f} ({v / r['ratios_cm3']['measured']:4.2f})")
        print(f"{r['medium']:16s} {r['component']:7s}" + "".join(cells))
    atomic_write_text(RES / "sph_leg_plate_ratio.json", json.dumps(
        {"rows": rows, "settings": {"command": "python benchmarks/sph_leg_plate_ratio.py",
                                    "leg": "flat", "rft_omega_rad_s": 0.2}}, indent=1) + "\n")


if __name__ == "__main__":
    main()
