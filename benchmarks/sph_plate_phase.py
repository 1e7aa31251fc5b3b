"""The plate test's lattice phase and its resolution convergence (issue 17), from result files.

``sph_start_offsets.py`` run at several spacings with the friction angle held at the
production (2.5 mm) calibration and start offsets spread over one particle spacing
(0.2, 0.4, 0.6, 0.8 dx above the standard start, plus the standard start and its 10 nm
realization) samples where the plate face meets the particle lattice. This script reads
those runs (``benchmarks/results/sph_start_offsets_phase_TAG_DXmm[_PART].json``: a spacing's
runs may be split over several files, PART a letter, run side by side; or a run's
``.partial.json`` while it goes on, kept as ``.stopped.json`` when the run was stopped
before its last start) and reports, per medium and spacing:

* the standard start (the calibration's realization 0) against the mean over the five
  lattice phases (0, 0.2, ..., 0.8 dx): the bias of the standard start;
* the phase mean's change between consecutive spacings, with its standard error: the plate's
  resolution convergence measured without the phase the standard start happens to have.

    python benchmarks/sph_plate_phase.py [--figure docs/figures/sph_plate_phase.png]

Writes benchmarks/results/sph_plate_phase.json. Reads result files only (seconds)."""
from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

import numpy as np

RES = Path(__file__).parent / "results"
NAME = re.compile(r"sph_start_offsets_phase_(?P<tag>.+?)_(?P<dx>[0-9.]+)mm(?:_(?P<part>[a-z]))?"
                  r"(?P<partial>\.partial|\.stopped)?\.json$")


def load(results: Path = RES) -> list[dict]:
    """One row per (medium, spacing): the runs of every file of it, finished or partial
    (``final``: all of them finished)."""
    rows = {}
    for f in sorted(results.glob("sph_start_offsets_phase_*.json")):
        m = NAME.match(f.name)
        if not m:
            continue
        d = json.loads(f.read_text())
        dx = float(m["dx"])
        runs = d["runs"] if m["partial"] else {
            f"{r['medium']}|{tag}": {"alpha_z": v}
            for r in d["rows"] for g, q in r["groups"].items() if "alpha_z" in q
            for tag, v in zip(_tags(d["settings"], g), q["alpha_z"]["runs"])}
        for key, run in runs.items():
            medium, tag = key.split("|")
            row = rows.setdefault((medium, dx), {"medium": medium, "dx_mm": dx, "final": True,
                                                 "calibration_dx_mm": d["settings"].get("calibration_dx_mm"),
                                                 "runs": {}})
            row["final"] &= not m["partial"]
            row["runs"][tag] = run["alpha_z"]
    return [_summary(r) for r in sorted(rows.values(), key=lambda r: (r["medium"], -r["dx_mm"]))]


def _tags(settings, group: str) -> list[str]:
    """The run tags of a finished file's group, as the partial file names them."""
    if group == "10 nm":
        return [f"k{k}" for k in range(settings["nm_realizations"])]
    return [f"{x:g}um" for x in settings["offsets_um"]]


def _summary(r: dict) -> dict:
    runs = r["runs"]
    phases = [runs[t] for t in runs if t == "k0" or t.endswith("um")]
    out = {k: r[k] for k in ("medium", "dx_mm", "calibration_dx_mm", "final")}
    out["runs"] = runs
    out["n_phases"] = len(phases)
    if "k0" in runs:
        out["standard_start"] = runs["k0"]
    if len(phases) >= 2:
        mean = float(np.mean(phases))
        out["phase_mean"] = mean
        out["phase_std"] = float(np.std(phases, ddof=1))
        out["phase_se"] = out["phase_std"] / np.sqrt(len(phases))
        if "k0" in runs:
            out["standard_over_phase_mean"] = runs["k0"] / mean - 1
    return out


def changes(rows: list[dict]) -> list[dict]:
    """Phase mean's relative change from each spacing to the next finer one, per medium."""
    out = []
    for medium in dict.fromkeys(r["medium"] for r in rows):
        rs = [r for r in rows if r["medium"] == medium and "phase_mean" in r]
        for a, b in zip(rs, rs[1:]):
            d = b["phase_mean"] / a["phase_mean"] - 1
            se = np.hypot(a["phase_se"] / a["phase_mean"], b["phase_se"] / b["phase_mean"]) * (1 + d)
            std = (b["standard_start"] / a["standard_start"] - 1
                   if "standard_start" in a and "standard_start" in b else None)
            out.append({"medium": medium, "from_mm": a["dx_mm"], "to_mm": b["dx_mm"],
                        "phase_mean_change": d, "phase_mean_change_se": float(se),
                        "standard_start_change": std})
    return out


def figure(rows: list[dict], path: Path, measured: dict) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from terradyn.io import atomic_save
    media = list(dict.fromkeys(r["medium"] for r in rows))
    fig, axes = plt.subplots(1, len(media), figsize=(5.2 * len(media), 4.2), squeeze=False,
                             sharex=True)
    for ax, medium in zip(axes[0], media):
        rs = [r for r in rows if r["medium"] == medium]
        for r in rs:
            xs = [r["dx_mm"]] * len(r["runs"])
            ax.plot(xs, list(r["runs"].values()), "o", ms=3, color="0.6", zorder=1,
                    label="single runs" if r is rs[0] else None)
        m = [r for r in rs if "phase_mean" in r]
        ax.errorbar([r["dx_mm"] for r in m], [r["phase_mean"] for r in m],
                    yerr=[r["phase_se"] for r in m], fmt="s-", color="C0", capsize=3,
                    label="mean over the lattice phases run (+- s.e.)")
        s = [r for r in rs if "standard_start" in r]
        ax.plot([r["dx_mm"] for r in s], [r["standard_start"] for r in s], "^--", color="C3",
                label="standard start (calibration's run 0)")
        ax.axhline(measured[medium], color="k", lw=0.8, ls=":", label="measured (Li 2013 Table S3)")
        ax.set_xlabel("particle spacing dx (mm)")
        ax.set_ylabel(r"plate $\alpha_z(0, \pi/2)$ through the origin (N/cm$^3$)")
        ax.set_title(f"{medium}, friction fixed at the 2.5 mm calibration", fontsize=10)
        ax.legend(fontsize=8)
    spacings = [r["dx_mm"] for r in rows]
    axes[0][0].set_xlim(max(spacings) + 0.15, min(spacings) - 0.15)  # finer to the right
    fig.tight_layout()
    atomic_save(path, lambda t: fig.savefig(t, dpi=200))
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--figure", type=Path, default=None)
    ap.add_argument("--out", type=Path, default=RES / "sph_plate_phase.json")
    a = ap.parse_args(argv)
    from terradyn.io import atomic_write_text
    from terradyn.media import MEDIA
    from terradyn.units import N_PER_CM3
    rows = load()
    if not rows:
        print("no sph_start_offsets_phase_*.json in benchmarks/results", file=sys.stderr)
        return 2
    ch = changes(rows)
    for r in rows:
        print(f"{r['medium']:16s} {r['dx_mm']:5.2f} mm  runs {len(r['runs'])}"
              + (f"  standard {r['standard_start']:.4f}" if "standard_start" in r else "")
              + (f"  phase mean {r['phase_mean']:.4f} +- {r['phase_se']:.4f} (n {r['n_phases']})"
                 if "phase_mean" in r else "")
              + (f"  standard/mean - 1 {100 * r['standard_over_phase_mean']:+.1f} %"
                 if "standard_over_phase_mean" in r else "")
              + ("" if r["final"] else "  (partial)"))
    for c in ch:
        print(f"{c['medium']:16s} {c['from_mm']:g} -> {c['to_mm']:g} mm: phase mean "
              f"{100 * c['phase_mean_change']:+.1f} +- {100 * c['phase_mean_change_se']:.1f} %"
              + (f", standard start {100 * c['standard_start_change']:+.1f} %"
                 if c["standard_start_change"] is not None else ""))
    measured = {m: MEDIA[m].alpha_z_plate / N_PER_CM3 for m in {r["medium"] for r in rows}}
    atomic_write_text(a.out, json.dumps({"command": "python benchmarks/sph_plate_phase.py "
                                         + " ".join(argv if argv is not None else sys.argv[1:]),
                                         "measured_N_cm3": measured, "rows": rows,
                                         "changes": ch}, indent=1) + "\n")
    if a.figure:
        figure(rows, a.figure, measured)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
