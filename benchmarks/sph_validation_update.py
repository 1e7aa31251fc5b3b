"""Bring a shipped validation result up to date with a partial rerun (issue 17).

``terradyn sph validate --scene S --medium M --out DIR`` reruns some checks, for example after
one medium's calibration changed; this puts DIR/validation.json's checks (matched by scene and
quantity) and details into a shipped result file in place of the old ones, adds those that are
new, recomputes the summary and records what was rerun under ``settings["updates"]``:

    python benchmarks/sph_validation_update.py benchmarks/results/sph_validate_legs.json \\
        DIR/validation.json --note "0.3 mm glass CP at 28.13 deg (phase calibration)"

The file is rewritten atomically. Reads and writes result files only (seconds)."""
from __future__ import annotations

import argparse
import json
from pathlib import Path


def update(old: dict, new: dict, note: str) -> dict:
    """``old`` with ``new``'s checks and details in place of the ones they rerun."""
    from terradyn.sph.suite import summary

    out = json.loads(json.dumps(old))
    index = {(c["scene"], c["quantity"]): i for i, c in enumerate(out["checks"])}
    for c in new["checks"]:
        k = (c["scene"], c["quantity"])
        if k in index:
            out["checks"][index[k]] = c
        else:
            out["checks"].append(c)
    for scene, items in new.get("details", {}).items():
        out.setdefault("details", {}).setdefault(scene, {}).update(items)
    out["summary"] = summary(out)
    rerun = sorted({c["quantity"] for c in new["checks"]})
    out["settings"].setdefault("updates", []).append(
        {"note": note, "settings": new.get("settings", {}), "checks_rerun": rerun})
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("shipped", type=Path)
    ap.add_argument("rerun", type=Path)
    ap.add_argument("--note", required=True, help="what was rerun and why")
    a = ap.parse_args(argv)
    from terradyn.io import atomic_write_text

    got = update(json.loads(a.shipped.read_text()), json.loads(a.rerun.read_text()), a.note)
    atomic_write_text(a.shipped, json.dumps(got, indent=1) + "\n")
    s = got["summary"]
    print(f"{a.shipped}: {s['pass']} of {s['total']} checks pass")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
