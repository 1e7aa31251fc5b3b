"""Dilatancy (issue 17): the closely packed media with a measured loose packing (poppy CP,
0.3 mm glass CP), non-dilatant at the CP angle of repose against Bolton's (1986) dilatant flow
(phi = the LP angle, psi = (phi_CP - phi_LP) / 0.8, dilation until the LP density): the plate
test (Li 2013 Table S3) and, in 0.3 mm glass CP, the three legs against Li 2013 Fig. S5.

    python benchmarks/sph_dilatancy.py [--dx-mm 4] [--realizations 2] [--no-legs]

Writes benchmarks/results/sph_dilatancy.json after every run (finished runs are skipped on a
rerun). A study, not a timing benchmark."""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from terradyn.io import atomic_write_text
from terradyn.sph.calibration import plate_slope
from terradyn.sph.materials import from_medium
from terradyn.sph.state import SPHConfig
from terradyn.sph.suite import leg_vs_measured
from terradyn.sph.validation import alpha_z_plate_measured
from terradyn.units import DEG, N_PER_CM3

OUT = Path(__file__).parent / "results" / "sph_dilatancy.json"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dx-mm", type=float, default=4.0)
    ap.add_argument("--realizations", type=int, default=2)
    ap.add_argument("--no-legs", action="store_true")
    a = ap.parse_args()
    res = json.loads(OUT.read_text()) if OUT.exists() else {"runs": {}}
    cfg = SPHConfig(dx=a.dx_mm * 1e-3)

    def save(key, val):
        res["runs"][key] = val
        atomic_write_text(OUT, json.dumps(res, indent=1))
        print(key, json.dumps(val), flush=True)

    jobs = [("plate", "0.3 mm glass CP", d) for d in ("none", "bolton")]
    if not a.no_legs:  # the legs at the repose angle (former match: sph_validate_legs_repose.json, git history)
        jobs.append(("flat", "0.3 mm glass CP", "bolton"))
    jobs += [("plate", "poppy CP", d) for d in ("none", "bolton")]
    if not a.no_legs:
        jobs += [(leg, "0.3 mm glass CP", "bolton") for leg in ("c", "reverse-c")]
    for scene, medium, dil in jobs:
        key = f"{scene}|{medium}|{dil}|{a.dx_mm:g}mm"
        if key in res["runs"]:
            continue
        mat = from_medium(medium, dilatancy=dil)
        base = {"friction_deg": round(mat.friction / DEG, 2), "dilatancy_deg": round(mat.dilatancy / DEG, 2)}
        if scene == "plate":
            r = plate_slope(mat, config=cfg, realizations=a.realizations)
            save(key, base | {"alpha_z_origin_N_cm3": round(r["alpha_z"] / N_PER_CM3, 4),
                              "alphas_N_cm3": [round(x / N_PER_CM3, 4) for x in r["alphas"]],
                              "measured_N_cm3": alpha_z_plate_measured(medium) / N_PER_CM3,
                              "wall_s": round(r["wall_s"], 1)})
        else:
            r = leg_vs_measured(scene, mat, omega=1.1, config=cfg)
            save(key, base | {c: {k: round(v, 3) for k, v in r[c].items() if isinstance(v, float)}
                              for c in ("Fx", "Fz")})


if __name__ == "__main__":
    main()
