"""``terradyn reproduce``: run the parts (each cached by the hash of its inputs), write
``report.json`` and the self-contained ``index.html``.

Tiers: ``quick`` (coarse grids, the flat leg only in the DDDAS speed study, 1000 particles:
minutes on 2 cores, what CI runs), ``standard`` (the studies' own settings: all three legs,
5000 particles) and ``full`` (standard, plus the SPH validation scenes run afresh instead of
read from the shipped result files; ``regenerate`` also rebuilds the shipped SPH training
set with ``terradyn sweep`` and uses it: hours).

Cache: each part's folder ``DIR/parts/<name>/`` holds its files and ``part.json`` with the
key, the sha256 of the part's name, its settings, the files it reads and the source code of
the package (the report's own rendering excepted). A rerun with the same key reuses the
part; anything else runs it again.
"""
from __future__ import annotations

import hashlib
import json
import os
import platform
import shutil
import subprocess
import time
from datetime import datetime, timezone
from importlib import metadata
from pathlib import Path
from typing import Callable

from ..errors import choice
from ..io import atomic_write_text
from . import parts as P

TIERS = ("quick", "standard", "full")
#: Seeds of the random parts (particle filter, synthetic trials, observation noise).
SEED = 0
#: Parts in order: name, title, function.
PARTS = (
    ("interp", "Stress coefficients: interpolating the measured grid", P.interp_part),
    ("legs", "The three legs in the rotating-leg test", P.legs_part),
    ("rft-sph-experiment", "RFT against SPH and against experiment", P.rft_sph_part),
    ("foot", "The human-sized foot", P.foot_part),
    ("foot-trials", "Foot trials: processing the sensor data", P.trial_part),
    ("dddas", "DDDAS: surrogate and particle filter", P.dddas_part),
    ("sph", "SPH validation scenes", P.sph_part),
)
PART_NAMES = tuple(p[0] for p in PARTS)
_VERSIONS = ("terradyn", "numpy", "scipy", "xarray", "pandas", "scikit-learn", "numba", "matplotlib")


def tier_settings(tier: str) -> dict:
    """Settings of every part for ``tier``."""
    quick = tier == "quick"
    return {
        "interp": {},
        "legs": {"n_theta": 91 if quick else 271, "n_elements": 40 if quick else 100},
        "rft-sph-experiment": {"n_elements": 40 if quick else 100},
        "foot": {"n_theta": 31 if quick else 61},
        "foot-trials": {"seed": SEED},
        "dddas": {"legs": ["flat"] if quick else ["flat", "c", "reverse-c"], "particles": 1000 if quick else 5000,
                  "seed": SEED, "n_theta": 91 if quick else 271},
        "sph": {},
    }


def _sha_file(p: Path, h=None):
    h = h or hashlib.sha256()
    with open(p, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h


def code_hash() -> str:
    """sha256 of the package's Python sources and data, without the report's rendering."""
    pkg = Path(__file__).resolve().parent.parent
    h = hashlib.sha256()
    for p in sorted(pkg.rglob("*")):
        rel = p.relative_to(pkg).as_posix()
        if not p.is_file() or "__pycache__" in rel or rel.startswith(("cli/", "report/html")):
            continue
        if p.suffix in (".py", ".csv", ".json", ".toml"):
            h.update(rel.encode())
            _sha_file(p, h)
    return h.hexdigest()


def _key(name: str, settings: dict, files: list, code: str) -> str:
    h = hashlib.sha256(json.dumps({"part": name, "settings": settings, "code": code}, sort_keys=True,
                                  default=str).encode())
    for f in files:
        h.update(str(Path(f).name).encode())
        _sha_file(Path(f), h)
    return h.hexdigest()


def _git_commit() -> str | None:
    root = P.repo_root()
    if root is None:
        return None
    try:
        rev = subprocess.run(["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True, timeout=10)
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=root,
                               capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return None
    if rev.returncode != 0:
        return None
    return rev.stdout.strip() + (" (with uncommitted changes)" if dirty.stdout.strip() else "")


def provenance(started: float) -> dict:
    versions = {}
    for pkg in _VERSIONS:
        try:
            versions[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            versions[pkg] = None
    return {"git_commit": _git_commit(), "versions": versions, "python": platform.python_version(),
            "machine": {"platform": platform.platform(), "processor": platform.processor() or platform.machine(),
                        "cpus": os.cpu_count(), "host": platform.node()},
            "seeds": {"dddas particle filter and observation noise": SEED, "synthetic foot trials": SEED},
            "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
            "total_seconds": round(time.perf_counter() - started, 2)}


def _made_with(st: dict) -> str:
    """' (dx 4 mm, Drucker-Prager match bui2008)': the model settings ``st`` a shipped SPH result
    file records, so that a report never passes off an older model's numbers as today's."""
    dx = st.get("dx_mm", st["dx_m"] * 1e3 if "dx_m" in st else None)
    match = st.get("dp_match")
    match = ", ".join(match) if isinstance(match, list) else match
    bits = ([f"dx {dx:g} mm"] if dx else []) + ([f"Drucker-Prager match {match}"] if match else [])
    return f" ({', '.join(bits)})" if bits else ""


def _sph_inputs(tier: str, out: Path, code: str, say, regenerate: bool) -> tuple[list, str, list, dict]:
    """The SPH validation results the parts read: the shipped files (quick, standard) or a
    fresh ``validate`` run (full; cached like a part). Returns (results, label, files, timing)."""
    if tier != "full":
        files = P.sph_result_files()
        results = P.load_sph_results(files)
        label = ("the shipped result files " + ", ".join(
                     f"benchmarks/results/{r['file']}{_made_with(r['settings'])}" for r in results)
                 if files else "no shipped SPH result files found (no source checkout)")
        return results, label, files, {}
    from ..sph.suite import validate

    folder = out / "parts" / "sph-run"
    key = _key("sph-run", {"regenerate": regenerate}, [], code)
    meta = folder / "part.json"
    t0 = time.perf_counter()
    if meta.is_file() and json.loads(meta.read_text()).get("key") == key:
        say("sph validation: cached")
        cached = True
    else:
        shutil.rmtree(folder, ignore_errors=True)
        (folder / "figures").mkdir(parents=True)
        # the leg runs (most of the hours) are kept beside the part, so that an interrupted
        # full tier resumes: finished runs are read back, the one in progress resumes from its
        # checkpoint (a stored run's key holds its code: runs of other code are not reused)
        legs = out / "parts" / "sph-run-legs"
        res = validate(quick=False, progress=lambda m: say(f"sph validation: {m}"), figures_dir=folder / "figures",
                       store=legs)
        atomic_write_text(folder / "validation.json", json.dumps(res, indent=1, default=float) + "\n")
        atomic_write_text(meta, json.dumps({"key": key, "seconds": time.perf_counter() - t0}) + "\n")
        shutil.rmtree(legs, ignore_errors=True)  # done: the part itself is the cache now
        cached = False
    res = json.loads((folder / "validation.json").read_text())
    timing = {"seconds": round(json.loads(meta.read_text())["seconds"], 2), "cached": cached}
    return [{"file": "validation.json", "checks": res["checks"], "settings": res.get("settings", {})}], \
        "this run's SPH validation (full tier)", \
        [folder / "validation.json"], timing


def _regenerate_sph_dataset(out: Path, say) -> Path:
    """Rebuild the SPH training set with its shipped sweep spec (resumable; hours on 2 cores)."""
    from ..sweep import execute, store

    root = P.repo_root()
    if root is None:
        from ..errors import InputError

        raise InputError("regenerate", "needs the source checkout's datasets/sph_legs_speeds.toml")
    target = out / "datasets" / "sph_legs_speeds.nc"
    if not target.is_file():
        st = out / "datasets" / "sph_legs_speeds.sweep"
        execute.run(root / "datasets" / "sph_legs_speeds.toml", st,
                    progress=lambda d, n, cid, ok: say(f"regenerating SPH dataset: {d}/{n}"))
        store.collect(st, target)
    return target


def reproduce(out, tier: str = "standard", parts=None, regenerate: bool = False,
              progress: Callable[[str], None] | None = None) -> dict:
    """Run the report's parts into ``out`` and write ``out/report.json`` and ``out/index.html``.
    ``parts``: names from :data:`PART_NAMES` (default all). Returns the report dict."""
    from . import html

    choice("tier", tier, TIERS)
    names = list(parts) if parts else list(PART_NAMES)
    for n in names:
        choice("part", n, list(PART_NAMES))
    if regenerate and tier != "full":
        from ..errors import InputError

        raise InputError("regenerate", "regenerating the shipped datasets belongs to the full tier (--full)")
    say = progress or (lambda m: None)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    code = code_hash()
    settings = tier_settings(tier)
    sph_results, sph_label, sph_files, sph_timing = _sph_inputs(tier, out, code, say, regenerate)
    from ..dddas.studies import find_sph_dataset

    dataset = _regenerate_sph_dataset(out, say) if regenerate else find_sph_dataset()
    shared = {"sph_results": sph_results, "sph_results_label": sph_label, "sph_dataset": dataset}
    figs_dir = out / "parts" / "sph-run" / "figures" if tier == "full" else None
    report_parts = []
    for name, title, fn in PARTS:
        if name not in names:
            continue
        s = dict(settings[name])
        files = []
        if name in ("rft-sph-experiment", "sph"):
            s.update(sph_results=sph_results, sph_results_label=sph_label)
            files += sph_files
        if name in ("rft-sph-experiment", "dddas") and dataset is not None:
            s["sph_dataset"] = str(dataset)
            files.append(dataset)
        if name == "sph" and figs_dir is not None:
            s["figures_dir"] = str(figs_dir)
        folder = out / "parts" / name
        key_settings = {k: v for k, v in s.items() if k not in ("sph_dataset", "figures_dir")}
        key = _key(name, key_settings, files, code)
        meta = folder / "part.json"
        old = json.loads(meta.read_text()) if meta.is_file() else {}
        if old.get("key") == key:
            say(f"{name}: cached")
            rec = old
            rec["cached"] = True
        else:
            say(f"{name}: running")
            shutil.rmtree(folder, ignore_errors=True)
            folder.mkdir(parents=True)
            t0 = time.perf_counter()
            cards = fn(folder, s)
            rec = {"name": name, "title": title, "key": key, "seconds": round(time.perf_counter() - t0, 2),
                   "settings": {k: v for k, v in key_settings.items() if k not in ("sph_results",)},
                   "inputs": [str(Path(f).name) for f in files], "cards": [c.describe() for c in cards]}
            atomic_write_text(meta, json.dumps(rec, indent=1, default=float) + "\n")
            rec["cached"] = False
        report_parts.append(rec)
    claims = [dict(c, card=card["id"], part=p["name"]) for p in report_parts for card in p["cards"]
              for c in card["claims"]]
    counts = {}
    for c in claims:
        counts[c["verdict"]] = counts.get(c["verdict"], 0) + 1
    cards = [c for p in report_parts for c in p["cards"]]
    card_counts = {}
    for c in cards:
        card_counts[c["verdict"]] = card_counts.get(c["verdict"], 0) + 1
    prov = provenance(started)
    prov["parts"] = {p["name"]: {"seconds": p["seconds"], "cached": p["cached"], "key": p["key"][:16]}
                     for p in report_parts}
    if sph_timing:
        prov["parts"]["sph-run"] = sph_timing
    prov["tier"] = tier
    prov["sph_results"] = sph_label
    prov["sph_dataset"] = str(dataset) if dataset else None
    report = {"title": "terradyn reproduces the thesis", "tier": tier,
              "summary": {"claims": counts, "cards": card_counts, "n_claims": len(claims), "n_cards": len(cards)},
              "parts": [{k: v for k, v in p.items() if k != "key"} for p in report_parts],
              "claims": claims, "provenance": prov}
    atomic_write_text(out / "report.json", json.dumps(report, indent=1, default=float) + "\n")
    html.write(report, out)
    return report
