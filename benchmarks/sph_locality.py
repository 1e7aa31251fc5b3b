"""How much of an SPH leg force is local? RFT built from SPH's own plate rig against the SPH legs.

RFT sums local stresses: alpha(beta, gamma) of each leg element, from a plate moved once
through fresh material. Built from the measured Table S5, it misses Li 2013's measured leg
curves by what the real leg owes to anything else (the material it has already disturbed,
flow along and around the leg). Built from SPH's own virtual plate rig
(``benchmarks/sph_rig.py``; :func:`terradyn.sph.suite.rig_table`), it gives the part of the SPH
leg force that SPH's local stresses explain. Side by side, per leg and component (peaks, N):

* ``sph_leg / rft_sph_rig``: what the SPH leg adds to its own local stresses;
* ``measured / rft_measured``: what the real leg adds to its measured local stresses;
* ``rft_sph_rig / rft_measured``: SPH's local stresses against the measured ones, as a leg
  sums them.

If the first two ratios agree, SPH's leg misses are in its local stresses (the rig); if the
first differs from the second, they are in the rest of the scene.

    python benchmarks/sph_locality.py [--rig MEDIUM=FILE ...] [--legs FILE]

Inputs: the full-grid rig results (default ``benchmarks/results/sph_rig_<medium>.json``) and
the SPH leg peaks of ``benchmarks/results/sph_legs_single_runs.json`` (single runs of
``terradyn sph validate --scene legs``, the numbers docs/sph.md quotes; ``--legs
benchmarks/results/sph_validate_legs.json`` takes the means of three runs). Writes ``benchmarks/results/sph_locality.json``. RFT only: seconds.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from terradyn.io import atomic_write_text
from terradyn.media import stress_model
from terradyn.motion import Rotation
from terradyn.rft import simulate
from terradyn.sph.suite import make_leg, measured_legs, rig_table
from terradyn.units import CM, DEG

RES = Path(__file__).parent / "results"
MEDIA = ("poppy LP", "0.3 mm glass CP")
LEGS = ("flat", "c", "reverse-c")


def sph_peaks(path: Path) -> dict:
    """{(medium, leg, comp): SPH peak} from a validation result's leg checks."""
    out = {}
    for c in json.loads(path.read_text())["checks"]:
        q = c["quantity"]
        if c["scene"] != "legs" or not q.startswith("peak "):
            continue
        # "peak lift, flat leg, poppy LP"
        what, leg, medium = [t.strip() for t in q.split(",", 2)]
        comp = "Fz" if what == "peak lift" else "Fx"
        out[(medium, leg.removesuffix(" leg"), comp)] = c["ours"]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rig", nargs="*", default=[], help="MEDIUM=FILE (a full-grid rig result)")
    ap.add_argument("--legs", type=Path, default=RES / "sph_legs_single_runs.json")
    ap.add_argument("--out", type=Path, default=RES / "sph_locality.json")
    a = ap.parse_args()
    rigs = {m: RES / f"sph_rig_{m.replace(' ', '_')}.json" for m in MEDIA}
    for spec in a.rig:
        m, f = spec.split("=", 1)
        rigs[m] = Path(f)
    sph = sph_peaks(a.legs)
    exp = measured_legs()
    mot = Rotation(omega=1.1, hip_height=2 * CM, theta_start=-135 * DEG, theta_end=135 * DEG,
                   n_theta=271)
    rows = []
    for medium in MEDIA:
        rig = json.loads(rigs[medium].read_text())
        own = rig_table(rig, f"SPH rig, {medium}")
        meas = stress_model(medium, "table", interp="linear")
        for leg in LEGS:
            r_own = simulate(make_leg(leg), mot, own)
            r_meas = simulate(make_leg(leg), mot, meas)
            for comp in ("Fz", "Fx"):
                e = exp[(exp.medium == medium) & (exp.leg == leg) & (exp.force == comp)]
                row = {"medium": medium, "leg": leg, "component": comp,
                       "sph_leg": sph.get((medium, leg, comp)),
                       "rft_sph_rig": float(r_own[comp].max()),
                       "rft_measured": float(r_meas[comp].max()),
                       "measured": float(e.force_N.max()),
                       "rig_dx_mm": rig["settings"]["dx_mm"],
                       "rig_file": str(rigs[medium].name)}
                if row["sph_leg"] is not None:
                    row["sph_leg_over_rft_sph_rig"] = row["sph_leg"] / row["rft_sph_rig"]
                row["measured_over_rft_measured"] = row["measured"] / row["rft_measured"]
                row["rft_sph_rig_over_rft_measured"] = row["rft_sph_rig"] / row["rft_measured"]
                rows.append(row)
                print(f"{medium:16s} {leg:10s} {comp}: SPH leg {row['sph_leg']:.2f}, "
                      f"RFT(SPH rig, {row['rig_dx_mm']:g} mm) {row['rft_sph_rig']:.2f}, "
                      f"RFT(Table S5) {row['rft_measured']:.2f}, measured {row['measured']:.2f}"
                      f" | SPH/own {row.get('sph_leg_over_rft_sph_rig', float('nan')):.2f}, "
                      f"meas/RFT {row['measured_over_rft_measured']:.2f}")
    settings = {"legs_file": a.legs.name, "omega_rad_s": 1.1,
                "command": "python benchmarks/sph_locality.py "
                           + " ".join(f"--rig {s}" for s in a.rig)}
    atomic_write_text(a.out, json.dumps({"rows": rows, "settings": settings}, indent=1))


if __name__ == "__main__":
    main()
