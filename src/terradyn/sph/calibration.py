"""Calibrating an SPH medium on the one experiment the brief names for it: the plate test.

Li, Zhang & Goldman (2013) characterise each medium by pushing a small horizontal plate
straight down and measuring alpha_z(0, pi/2), the slope of vertical stress against depth
(Table S3: 0.35, 0.56, 0.24, 0.40, 0.29 N/cm^3 for poppy LP, poppy CP, 0.3 mm glass LP,
0.3 mm glass CP, 3 mm glass CP). The SPH material's friction angle is the one parameter
this test pins down: the model's plate slope grows monotonically with phi (plane-strain
bearing capacity, slope ~ rho g N_q(phi)), and the measured bulk density fixes the rest.

:func:`calibrate_friction` finds the phi at which the *same 2D SPH plate test* reproduces the
measured slope. It never looks at leg-force curves (they judge the model). The result for
the five media of Li 2013 is shipped in ``terradyn/data/sph_calibration.json`` and used by
:data:`terradyn.sph.MATERIALS`; ``terradyn sph calibrate`` regenerates it, and calibrates a
user's medium from its density and one plate test.

Why a calibrated phi and not the angle of repose: the repose angle is a loose-pile property
(and for 3 mm glass CP, 21 deg, it is lower than for the looser 0.3 mm glass); a plane-strain
continuum at the repose angle gives 0.4-0.7 of the measured plate slope
(``shared/spec/sph-fidelity-notes.md`` section 2), because the experiments' plate is a 3D
footing (shape and depth factors above 1) in a dense packing (peak, not critical-state,
friction). The calibrated angle absorbs both and is therefore an *effective plane-strain*
friction angle, not a material constant to quote elsewhere.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from importlib import resources
from typing import Callable

from ..errors import InputError, in_range, positive
from ..units import DEG, N_PER_CM3

#: The plate test of the calibration (quick runs: 4 mm particles; see docs/sph.md).
PLATE_TEST = {"speed_m_s": 0.02, "depth_m": 0.04, "fit_from_m": 0.01, "n_samples": 41}
#: Friction angles the search may use, deg.
PHI_RANGE = (10.0, 60.0)
#: How the runs of a plate test averaged over realizations start: "nm" (run k k x 10 nm above
#: the standard start, as the shipped calibrations were made) or "phase" (run j of N a
#: fraction j / N of a particle spacing above it, so that the plate meets the particle lattice
#: at N phases; docs/sph.md "Run-to-run scatter").
STARTS = ("nm", "phase")


def bearing_nq(phi: float) -> float:
    """Prandtl-Reissner bearing-capacity factor N_q = e^(pi tan phi) tan^2(45 deg + phi/2)
    (plane strain; phi in rad): the shape of the plate slope's growth with phi, used for the
    first step of the search."""
    t = math.tan(phi)
    return math.exp(math.pi * t) * math.tan(math.pi / 4 + phi / 2) ** 2


def start_offsets(realizations: int, dx: float, starts: str = "nm", first: int = 0) -> list[int]:
    """The ``realization`` numbers (10 nm steps above the standard start) of the runs of a
    plate test averaged over ``realizations`` runs: ``first``, ``first`` + 1, ... for "nm";
    round(j dx / N / 10 nm) for j = 0 .. N - 1 for "phase" (N = ``realizations``, spacing
    ``dx`` in m), where ``first`` must be 0 and N at least 2."""
    from ..errors import choice, integer

    choice("starts", starts, list(STARTS))
    n = integer("realizations", realizations, 1)
    if starts == "nm":
        return list(range(int(first), int(first) + n))
    if first:
        raise InputError("first", "phase starts are fixed fractions of the particle spacing; "
                                  "first must be 0")
    if n < 2:
        raise InputError("realizations", "phase starts need at least 2 runs (the phases), got 1")
    return [round(j * dx / n / 1e-8) for j in range(n)]


def plate_run(mat, config, realization: int = 0, below: float | None = None, store=None) -> dict:
    """One run of the plate test (:data:`PLATE_TEST`, :func:`terradyn.sph.validation.plate_push`)
    of ``mat`` with ``config``: the plate's centre depth (m), its stress (Pa) and the force
    series. ``store``: a directory where the finished run is kept (``plate-KEY.nc``,
    :mod:`terradyn.sph.runstore`) and from which the same run is read again; ``stored`` says
    whether it was."""
    from .runstore import RUN_MODULES, code_digest, stored
    from .validation import plate_push

    def compute(_checkpoint=None):
        r = plate_push(mat, speed=PLATE_TEST["speed_m_s"], depth=PLATE_TEST["depth_m"],
                       n_samples=PLATE_TEST["n_samples"], fit_from=PLATE_TEST["fit_from_m"],
                       config=config, realization=realization, below=below)
        return r["series"].assign(plate_depth_m=("plate_sample", r["depth"]),
                                  plate_stress_Pa=("plate_sample", r["stress"]))

    if store is None:
        ds, was = compute(), False
    else:
        spec = {"scene": "plate", "plate_test": PLATE_TEST, "material": mat.describe(),
                "config": config.run_items(), "realization": int(realization), "below": below,
                "code": code_digest((*RUN_MODULES, "terradyn.sph.validation"))}
        ds, was = stored(store, "plate", spec, compute)
    return {"depth": ds.plate_depth_m.values, "stress": ds.plate_stress_Pa.values,
            "series": ds.drop_vars(["plate_depth_m", "plate_stress_Pa"]), "stored": was}


def plate_slope(mat, *, dx: float = 4e-3, config=None, realizations: int = 1, first: int = 0,
                below: float | None = None, starts: str = "nm", store=None) -> dict:
    """The SPH plate test (:func:`terradyn.sph.validation.plate_push`, :data:`PLATE_TEST`)
    for a :class:`~terradyn.sph.materials.GranularMaterial`, averaged over ``realizations``
    runs (physically identical starts, see plate_push's ``realization``), numbered from
    ``first`` (so that runs ``first``, ``first + 1``, ... add to an earlier call's);
    ``config.bed_pad`` sets the bed as in plate_push (None: the calibration's bed), and
    ``below`` (m) the bed below the plate on its own, as there. ``starts`` (:data:`STARTS`):
    "nm", the runs 10 nm apart from ``first``; "phase", spread over one particle spacing
    (:func:`start_offsets`). ``store``: a directory that keeps each finished run
    (:func:`plate_run`), so that a repeated or interrupted test reads the runs it has. At
    2.5 mm the former calibration's two runs from the standard start of 0.3 mm glass CP read
    about 4 % above the mean over five lattice phases (docs/sph.md "Run-to-run scatter").

    Returns ``alpha_z`` (N/m^3): the RFT-consistent coefficient, the least-squares fit of
    sigma = alpha |z| through the origin over depths 1-4 cm (RFT applies alpha that way; the
    SPH stress-depth curve has an intercept, the plate's own bearing term 0.5 rho g B N_gamma
    plus its mobilisation, and a free slope-and-intercept fit trades one for the other from
    run to run); also each run's value, the free fit's slope and intercept (Pa), the wall
    time, how many runs were read from ``store``, and the last run's depth, stress and force
    series."""
    import time

    import numpy as np

    from .state import SPHConfig

    cfg = config or SPHConfig(dx=dx)
    t0 = time.perf_counter()
    alphas, slopes, icpts, n_stored = [], [], [], 0
    for k in start_offsets(realizations, cfg.dx, starts, first):
        r = plate_run(mat, cfg, k, below, store)
        n_stored += r["stored"]
        d, st = r["depth"], r["stress"]
        m = d > PLATE_TEST["fit_from_m"]
        slope, icpt = np.polyfit(d[m], st[m], 1)
        slopes.append(float(slope))
        icpts.append(float(icpt))
        alphas.append(float(np.sum(st[m] * d[m]) / np.sum(d[m] ** 2)))
    return {"alpha_z": float(np.mean(alphas)), "alphas": alphas,
            "slope": float(np.mean(slopes)), "slopes": slopes,
            "intercept_Pa": float(np.mean(icpts)), "wall_s": time.perf_counter() - t0,
            "stored": n_stored,
            "depth": d, "stress": st, "series": r["series"]}


@dataclass
class Calibration:
    """Result of :func:`calibrate_friction`: the friction angle (deg) with its standard error
    from the scatter of the plate runs, the measured plate slope and the fitted SPH slope
    there (N/cm^3), and every evaluation (phi_deg, alpha_z_N_per_cm3)."""

    medium: str
    friction_deg: float
    alpha_z_measured: float
    alpha_z_sph: float
    dx_m: float
    history: list = field(default_factory=list)
    converged: bool = True
    friction_se_deg: float = float("nan")
    note: str = ""
    #: each evaluation's single-run alpha_z (N/cm^3), in the order of ``history``
    history_runs: list = field(default_factory=list)

    def describe(self) -> dict:
        return {"medium": self.medium, "friction_deg": round(self.friction_deg, 3),
                "friction_se_deg": (round(self.friction_se_deg, 3)
                                    if math.isfinite(self.friction_se_deg) else None),
                "alpha_z_measured_N_per_cm3": self.alpha_z_measured,
                "alpha_z_sph_N_per_cm3": round(self.alpha_z_sph, 4),
                "relative_difference": round(self.alpha_z_sph / self.alpha_z_measured - 1, 4),
                "dx_m": self.dx_m, "converged": self.converged, "note": self.note,
                "history": [[round(p, 3), round(a, 4)] for p, a in self.history],
                **({"history_runs": [[round(a, 4) for a in r] for r in self.history_runs]}
                   if self.history_runs else {}),
                "plate_test": PLATE_TEST}


def calibrate_friction(mat, alpha_z_measured: float, *, dx: float = 4e-3, tol: float = 0.03,
                       max_evals: int = 6, realizations: int = 5, config=None,
                       report: Callable[[float, float], None] | None = None,
                       starts: str = "phase", store=None) -> Calibration:
    """The friction angle at which the SPH plate test of ``mat`` (a GranularMaterial: its
    density, stiffness and the rest are kept) gives ``alpha_z_measured`` (N/m^3).

    The plate test is noisy (single runs scatter by about 10 %), so the search fits a line
    to log(alpha_z) against phi through the three evaluations nearest the current estimate
    and moves to where the line meets the target: first from the repose angle by the
    bearing-capacity scaling N_q(phi), then by the fit, until the estimate moves less than
    0.25 deg (or ``max_evals`` plate tests). Converged: the fitted slope at the estimate is the
    target and the nearest evaluation is within ``tol`` + the scatter. When the first
    angle (the medium's own: for a Li 2013 medium its shipped calibration) already gives the
    target within ``tol``, the search stops there: checking a calibration costs one plate test
    (its standard error then comes from the runs' scatter and the growth of N_q with phi,
    and ``note`` says so). ``report(phi_deg,
    alpha_z_N_per_cm3)`` after each test (about 20 s each at dx = 4 mm on 2 cores).
    ``config`` (an SPHConfig; None: ``SPHConfig(dx=dx)``) also sets the plate test's bed
    (``bed_pad``, :func:`plate_slope`); ``starts`` how its runs start (:data:`STARTS`);
    ``store`` a directory that keeps every finished plate run, so that a calibration stopped
    part-way and started again reads the runs it made (:func:`plate_run`)."""
    import numpy as np

    target = positive("alpha_z_measured", alpha_z_measured, "N/m^3")
    in_range("tol", tol, 1e-3, 0.5)
    lo_b, hi_b = PHI_RANGE
    pts: list[tuple[float, float]] = []  # (phi_deg, log(alpha / target))
    runs: list[list[float]] = []  # each evaluation's single-run alphas (N/cm^3)

    def f(phi_deg):
        r = plate_slope(mat.with_(friction=phi_deg * DEG), dx=dx, config=config,
                        realizations=realizations, starts=starts, store=store)
        a = r["alpha_z"]
        runs.append([x / N_PER_CM3 for x in r.get("alphas", [a]) if x > 0])
        pts.append((phi_deg, math.log(a / target) if a > 0 else -10.0))
        if report:
            report(phi_deg, a / N_PER_CM3)
        return pts[-1][1]

    phi0 = min(max(mat.friction / DEG, lo_b), hi_b)
    g0 = f(phi0)
    if abs(g0) <= math.log1p(tol) and lo_b < phi0 < hi_b:
        # the first angle (a shipped calibration being checked, or a good guess) already
        # meets the target: keep it. Its standard error: the scatter of the runs' log alpha
        # over the plate slope's growth with phi, taken as that of N_q (the search's model)
        logs = [math.log(x) for x in runs[0]]
        n = len(logs)
        d_lnnq = (math.log(bearing_nq((phi0 + 0.05) * DEG)) - math.log(bearing_nq((phi0 - 0.05) * DEG))) / 0.1
        se = (float(np.std(logs, ddof=1)) / math.sqrt(n) / d_lnnq) if n > 1 else float("nan")
        return Calibration(mat.name, phi0, target / N_PER_CM3, target * math.exp(g0) / N_PER_CM3,
                           dx, [(pts[0][0], target * math.exp(g0) / N_PER_CM3)], converged=True,
                           friction_se_deg=se, history_runs=runs,
                           note="the first angle meets the target within tol; standard error "
                                "from the runs' scatter and the slope of N_q(phi)")
    want = bearing_nq(phi0 * DEG) * math.exp(-g0)
    a, b = lo_b * DEG, hi_b * DEG
    for _ in range(60):
        mid = 0.5 * (a + b)
        a, b = (mid, b) if bearing_nq(mid) < want else (a, mid)
    est = min(max(0.5 * (a + b) / DEG, lo_b), hi_b)
    slope_fit, resid = float("nan"), float("nan")
    while len(pts) < max_evals:
        if abs(pts[-1][1]) <= math.log1p(tol) and len(pts) >= 2 and abs(pts[-1][0] - est) < 0.25:
            break
        f(est)
        near = sorted(pts, key=lambda p: abs(p[0] - est))[:3]
        P = np.array([p[0] for p in near])
        Gv = np.array([p[1] for p in near])
        if np.ptp(P) < 1e-6:
            break
        slope_fit, icpt = np.polyfit(P, Gv, 1)
        resid = float(np.std(Gv - (slope_fit * P + icpt))) if len(P) > 2 else 0.0
        if slope_fit <= 0:  # noise or a non-monotone response: no usable direction
            break
        new = min(max(-icpt / slope_fit, lo_b), hi_b)
        new = min(max(new, est - 8.0), est + 8.0)
        moved = abs(new - est)
        est = new
        if moved < 0.25:
            break
    near = min(pts, key=lambda p: abs(p[0] - est))
    if math.isfinite(slope_fit) and slope_fit > 0:
        g_est = 0.0 if lo_b < est < hi_b else (est - near[0]) * slope_fit + near[1]
        se = resid / slope_fit if math.isfinite(resid) else float("nan")
    else:
        est, g_est, se = near[0], near[1], float("nan")
    ok = (math.isfinite(slope_fit) and slope_fit > 0 and lo_b < est < hi_b
          and abs(near[1]) <= math.log1p(tol) + (resid if math.isfinite(resid) else 0.0))
    note = "" if ok else ("the plate slope did not grow with phi near the estimate"
                          if not (math.isfinite(slope_fit) and slope_fit > 0)
                          else "the target lies outside the friction angles searched"
                          if not lo_b < est < hi_b else "the runs scatter more than tol")
    return Calibration(mat.name, est, target / N_PER_CM3, target * math.exp(g_est) / N_PER_CM3,
                       dx, [(p, target * math.exp(g) / N_PER_CM3) for p, g in pts],
                       converged=ok, friction_se_deg=se, note=note, history_runs=runs)


# ----------------------------------------------------------------- the shipped calibration
CALIBRATION_FILE = "sph_calibration.json"


def shipped() -> dict:
    """The shipped calibration (``terradyn/data/sph_calibration.json``): medium ->
    :meth:`Calibration.describe` dict (at the production resolution; calibrations of the
    medium at other particle spacings under its ``"other_resolutions"``, keyed by the spacing
    in mm), plus ``_meta``; empty if the file is absent."""
    try:
        text = resources.files("terradyn.data").joinpath(CALIBRATION_FILE).read_text()
    except (FileNotFoundError, ModuleNotFoundError):
        return {}
    try:
        data = json.loads(text)
    except json.JSONDecodeError as e:  # a corrupt package file: say so, do not guess
        raise InputError("sph_calibration.json", f"unreadable ({e})") from None
    return data


def _mm(dx: float) -> str:
    """A particle spacing (m) as the key of ``other_resolutions`` (mm, as written: "1.6")."""
    return f"{round(dx * 1e3, 4):g}"


#: The plate beds a shipped calibration can have been made in: "standard" (the calibration
#: bed, 9.5 cm beside the plate and 7.6 cm below it: the validated default) and "large" (a bed
#: past about 0.7 of the plate's plane-strain Prandtl reach, where its slope has settled;
#: docs/sph.md, "Bed size"). Large-bed calibrations are under each medium's ``"large_bed"``.
CALIBRATION_BEDS = ("standard", "large")


def prandtl_reach(phi: float, width: float = 0.0381) -> float:
    """How far (m) the plane-strain Prandtl failure mechanism under a strip footing of
    ``width`` (m; Li 2013's plate: 3.81 cm) reaches beyond its edge at friction angle ``phi``
    (rad): 2 r1 cos(45 deg - phi/2), r1 = (B/2) e^((pi/2) tan phi) / cos(45 deg + phi/2)
    (the log-spiral's outer radius, Prandtl 1920). A plate test's bed must reach about 0.7 of
    it beside the plate before the slope stops changing (docs/sph.md, "Bed size")."""
    r1 = 0.5 * width * math.exp(0.5 * math.pi * math.tan(phi)) / math.cos(math.pi / 4 + phi / 2)
    return 2.0 * r1 * math.cos(math.pi / 4 - phi / 2)


def shipped_at(medium: str, dx: float | None = None, bed: str = "standard") -> dict | None:
    """The shipped calibration of ``medium`` for a run at particle spacing ``dx`` (m): the one
    made at ``dx`` where the package has it, else the production one (None if the medium has
    none). The plate test converges slowly with resolution (docs/sph.md, "Convergence"), so
    a medium run at another spacing than it was calibrated at reads a plate slope 5-15 % off
    the measured one; calibrating at the run's own spacing removes that part, and the
    leg-to-plate ratios move less with resolution than either force does.

    ``bed`` (:data:`CALIBRATION_BEDS`): "large" gives the calibration made with the plate in
    a bed where its slope has settled (at the production spacing only; None if the medium
    has none)."""
    from ..errors import choice

    choice("calibration_bed", bed, list(CALIBRATION_BEDS))
    found = shipped().get(medium)
    if found is None:
        return None
    if bed == "large":
        return found.get("large_bed")
    if dx is None:
        return found
    return found.get("other_resolutions", {}).get(_mm(dx), found)


def plate_bed(medium: str, bed: str = "standard") -> float | None:
    """The plate bed (m beyond the plate's edges and below it) that ``medium``'s shipped
    ``bed`` calibration was made in; None for the standard calibration bed (or none shipped)."""
    found = shipped_at(medium, bed=bed)
    return None if found is None else found.get("plate_test", {}).get("bed_pad_m")


def calibrated_spacings(medium: str) -> list[float]:
    """The particle spacings (mm) at which the package ships a calibration of ``medium``."""
    found = shipped().get(medium)
    if found is None:
        return []
    return sorted({round(found["dx_m"] * 1e3, 4), *(float(k) for k in found.get("other_resolutions", {}))})


#: A large-bed calibration's plate bed must reach at least this fraction of the plate's
#: Prandtl reach beside it (:func:`prandtl_reach`; the slope settles at about 0.7).
LARGE_BED_MIN_REACH = 0.5


def merge_resolutions(base: dict, new: dict) -> dict:
    """``base`` (a calibration file's content: ``terradyn sph calibrate`` output at the
    production spacing) with the media of ``new`` (the same command's output at another
    spacing) added under each medium's ``"other_resolutions"``, keyed by the spacing in mm;
    a calibration at the base's own spacing replaces the medium's record. A calibration made
    in a larger plate bed (``sph calibrate --plate-bed-pad-cm``: ``_meta.plate_test.bed_pad_m``
    set) goes under the medium's ``"large_bed"`` instead (the production spacing only, a bed
    reaching at least :data:`LARGE_BED_MIN_REACH` of the plate's Prandtl reach at the angle
    found; the record keeps its bed and that fraction). How the shipped file gets them:
    ``python benchmarks/sph_calibration_merge.py FILE...`` (docs/sph.md). A medium of ``new``
    that did not converge, or that base lacks, is refused."""
    out = json.loads(json.dumps(base))
    meta = new.get("_meta", {})
    pad = (meta.get("plate_test") or {}).get("bed_pad_m")
    if (meta.get("plate_test") or {}).get("leg_friction_deg") is not None:
        # the shipped media run with the rough leg: a calibration for a plate of another
        # friction is the user's, for runs with that friction, not a shipped record
        raise InputError("leg_friction_deg", "a calibration made with --leg-friction-deg is for runs "
                                             "with that plate friction; the shipped calibrations are "
                                             "for the rough (no-slip) plate and legs")
    for m, rec in new.items():
        if m == "_meta":
            continue
        if m not in out:
            raise InputError("medium", f"{m!r} has no production calibration to add a resolution to")
        if not rec.get("converged", False):
            raise InputError("medium", f"the calibration of {m!r} did not converge ({rec.get('note', '')})")
        rec = dict(rec, **{k: meta[k] for k in ("created", "realizations", "starts") if k in meta})
        if pad is not None:
            if abs(rec["dx_m"] - out[m]["dx_m"]) > 1e-9:
                raise InputError("dx_m", f"a large-bed calibration of {m!r} must be at the production "
                                         f"spacing {_mm(out[m]['dx_m'])} mm, not {_mm(rec['dx_m'])} mm")
            reach = prandtl_reach(rec["friction_deg"] * DEG)
            if pad < LARGE_BED_MIN_REACH * reach:
                raise InputError("bed_pad_m", f"{m!r}: a {pad * 100:g} cm plate bed is {pad / reach:.2f} of the "
                                 f"plate's Prandtl reach ({reach * 100:.1f} cm at {rec['friction_deg']:g} deg); "
                                 f"a large bed needs >= {LARGE_BED_MIN_REACH:g}")
            rec["plate_test"] = dict(rec.get("plate_test", PLATE_TEST), bed_pad_m=pad)
            rec["bed_over_prandtl_reach"] = round(pad / reach, 3)
            out[m]["large_bed"] = rec
        elif abs(rec["dx_m"] - out[m]["dx_m"]) < 1e-9:
            for keep in ("other_resolutions", "large_bed"):
                if keep in out[m]:
                    rec[keep] = out[m][keep]
            out[m] = rec
        else:
            out[m].setdefault("other_resolutions", {})[_mm(rec["dx_m"])] = rec
    return out
