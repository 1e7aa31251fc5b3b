"""Merge plate-test calibrations into the shipped calibration (issue 17): at the production
spacing they replace a medium's record; at other particle spacings, or in a larger plate bed,
they are added beside it (a medium runs with its calibration at the run's own spacing where
one is shipped; ``--calibration-bed large`` takes the one made in a settled plate bed).

    terradyn sph calibrate --medium "poppy LP" --dx-mm 2.5 -o poppy.json   (production)
    terradyn sph calibrate --medium "0.3 mm glass CP" --dx-mm 1.6 -o glass16.json
    terradyn sph calibrate --medium "poppy LP" --plate-bed-pad-cm 24 -o poppy_pad24.json
    python benchmarks/sph_calibration_merge.py poppy.json glass16.json poppy_pad24.json [...]

A calibration at the production spacing replaces the medium's record and keeps the records
under it; the file's ``_meta`` then says how the production records were made (``starts``,
``realizations``) when all five were made the same way. Each medium of the other files goes
under its ``other_resolutions`` in ``src/terradyn/data/sph_calibration.json``, or under its
``large_bed`` when the file's plate test had a larger bed
(``terradyn.sph.calibration.merge_resolutions``); the file is rewritten atomically."""
from __future__ import annotations

import json
import sys
from pathlib import Path

SHIPPED = Path(__file__).parent.parent / "src" / "terradyn" / "data" / "sph_calibration.json"


def main(paths: list[str]) -> None:
    from terradyn.io import atomic_write_text
    from terradyn.sph.calibration import merge_resolutions

    data = json.loads(SHIPPED.read_text())
    for p in paths:
        data = merge_resolutions(data, json.loads(Path(p).read_text()))
    data["_meta"]["other_resolutions"] = (
        "calibrations at other particle spacings, under each medium's other_resolutions (key: dx "
        "in mm): terradyn sph calibrate --medium M --dx-mm D, merged by "
        "benchmarks/sph_calibration_merge.py; a run at that spacing takes them (terradyn.sph.calibration.shipped_at)")
    data["_meta"]["large_bed"] = (
        "calibrations made with the plate in a bed where its slope has settled (about 0.7 of the "
        "plane-strain Prandtl reach beside it, docs/sph.md 'Bed size'), under each medium's "
        "large_bed: terradyn sph calibrate --medium M --plate-bed-pad-cm P, merged by "
        "benchmarks/sph_calibration_merge.py; taken with --calibration-bed large")
    prod = [r for m, r in data.items() if m != "_meta"]
    how = {(r.get("starts", "nm"), r.get("realizations", data["_meta"].get("realizations"))) for r in prod}
    if len(how) == 1:  # every production record made the same way: say so at the top
        starts, n = how.pop()
        data["_meta"]["starts"], data["_meta"]["realizations"] = starts, n
        if starts == "phase":
            data["_meta"]["command"] = (
                f"terradyn sph calibrate --medium M --dx-mm 2.5 --starts phase --realizations {n} "
                "(one run per medium, merged by benchmarks/sph_calibration_merge.py; each record's "
                "created says when)")
    else:
        data["_meta"]["starts"] = data["_meta"]["realizations"] = data["_meta"]["command"] = (
            "per medium: each production record's starts, realizations and created (none: the "
            "first calibration, terradyn sph calibrate --medium M --dx-mm 2.5 --starts nm "
            "--realizations 2)")
    atomic_write_text(SHIPPED, json.dumps(data, indent=1) + "\n")
    for m, r in data.items():
        if m != "_meta":
            extra = ", ".join(f"{k} mm: {v['friction_deg']:g} deg" for k, v in r.get("other_resolutions", {}).items())
            big = r.get("large_bed")
            if big:
                extra += (("; " if extra else "") + f"large bed ({big['plate_test']['bed_pad_m'] * 100:g} cm, "
                          f"{big['bed_over_prandtl_reach']:g} of the reach): {big['friction_deg']:g} deg")
            print(f"{m}: {r['dx_m'] * 1e3:g} mm: {r['friction_deg']:g} deg" + (f"; {extra}" if extra else ""))


if __name__ == "__main__":
    main(sys.argv[1:])
