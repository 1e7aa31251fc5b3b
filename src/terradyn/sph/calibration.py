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


def bearing_nq(phi: float) -> float:
    """Prandtl-Reissner bearing-capacity factor N_q = e^(pi tan phi) tan^2(45 deg + phi/2)
    (plane strain; phi in rad): the shape of the plate slope's growth with phi, used for the
    first step of the search."""
    t = math.tan(phi)
    return math.exp(math.pi * t) * math.tan(math.pi / 4 + phi / 2) ** 2


def plate_slope(mat, *, dx: float = 4e-3, config=None, progress=None) -> dict:
    """The SPH plate test (:func:`terradyn.sph.validation.plate_push`, :data:`PLATE_TEST`)
    for a :class:`~terradyn.sph.materials.GranularMaterial`; returns alpha_z (N/m^3), the
    stress intercept at zero depth (Pa) and the wall time."""
    import time

    import numpy as np

    from .state import SPHConfig
    from .validation import plate_push

    cfg = config or SPHConfig(dx=dx)
    t0 = time.perf_counter()
    r = plate_push(mat, speed=PLATE_TEST["speed_m_s"], depth=PLATE_TEST["depth_m"],
                   n_samples=PLATE_TEST["n_samples"], fit_from=PLATE_TEST["fit_from_m"],
                   config=cfg)
    d, s = r["depth"], r["stress"]
    m = d > PLATE_TEST["fit_from_m"]
    slope, icpt = np.polyfit(d[m], s[m], 1)
    return {"alpha_z": float(slope), "intercept_Pa": float(icpt),
            "wall_s": time.perf_counter() - t0, "depth": d, "stress": s}


@dataclass
class Calibration:
    """Result of :func:`calibrate_friction`: the friction angle (deg), the measured and
    reproduced plate slopes (N/cm^3), every evaluation (phi_deg, alpha_z_N_per_cm3)."""

    medium: str
    friction_deg: float
    alpha_z_measured: float
    alpha_z_sph: float
    dx_m: float
    history: list = field(default_factory=list)
    converged: bool = True

    def describe(self) -> dict:
        return {"medium": self.medium, "friction_deg": round(self.friction_deg, 3),
                "alpha_z_measured_N_per_cm3": self.alpha_z_measured,
                "alpha_z_sph_N_per_cm3": round(self.alpha_z_sph, 4),
                "relative_difference": round(self.alpha_z_sph / self.alpha_z_measured - 1, 4),
                "dx_m": self.dx_m, "converged": self.converged,
                "history": [[round(p, 3), round(a, 4)] for p, a in self.history],
                "plate_test": PLATE_TEST}


def calibrate_friction(mat, alpha_z_measured: float, *, dx: float = 4e-3, tol: float = 0.03,
                       max_evals: int = 6, config=None,
                       report: Callable[[float, float], None] | None = None) -> Calibration:
    """The friction angle at which the SPH plate test of ``mat`` (a GranularMaterial: its
    density, stiffness and the rest are kept) gives ``alpha_z_measured`` (N/m^3) within
    ``tol`` (relative). Secant search on log(alpha_z) against phi, bracketed, started from the
    bearing-capacity scaling N_q(phi); ``report(phi_deg, alpha_z_N_per_cm3)`` after each run.
    Each evaluation is one plate test (about 20 s at dx = 4 mm on 2 cores)."""
    target = positive("alpha_z_measured", alpha_z_measured, "N/m^3")
    in_range("tol", tol, 1e-3, 0.5)
    lo_b, hi_b = PHI_RANGE
    hist: list[tuple[float, float]] = []

    def f(phi_deg):
        m = mat.with_(friction=phi_deg * DEG)
        a = plate_slope(m, dx=dx, config=config)["alpha_z"]
        hist.append((phi_deg, a / N_PER_CM3))
        if report:
            report(phi_deg, a / N_PER_CM3)
        return math.log(a / target) if a > 0 else -10.0

    phi0 = min(max(mat.friction / DEG, lo_b), hi_b)
    g0 = f(phi0)
    if abs(g0) > math.log1p(tol):
        # first step: N_q(phi1) = N_q(phi0) * target / alpha(phi0)
        want = bearing_nq(phi0 * DEG) * math.exp(-g0)
        a, b = lo_b * DEG, hi_b * DEG
        for _ in range(60):
            mid = 0.5 * (a + b)
            a, b = (mid, b) if bearing_nq(mid) < want else (a, mid)
        phi1 = min(max(0.5 * (a + b) / DEG, lo_b), hi_b)
        g1 = f(phi1)
        pts = [(phi0, g0), (phi1, g1)]
        while abs(pts[-1][1]) > math.log1p(tol) and len(hist) < max_evals:
            below = [p for p in pts if p[1] < 0]
            above = [p for p in pts if p[1] > 0]
            (p_a, g_a), (p_b, g_b) = pts[-2], pts[-1]
            nxt = p_b - g_b * (p_b - p_a) / (g_b - g_a) if g_b != g_a else p_b + 2.0
            if below and above:  # keep inside the bracket
                lo = max(p for p, _ in below)
                hi = min(p for p, _ in above)
                if not lo < nxt < hi:
                    nxt = 0.5 * (lo + hi)
            nxt = min(max(nxt, lo_b), hi_b)
            pts.append((nxt, f(nxt)))
        best = min(pts, key=lambda p: abs(p[1]))
    else:
        best = (phi0, g0)
    return Calibration(mat.name, best[0], target / N_PER_CM3,
                       target * math.exp(best[1]) / N_PER_CM3, dx, hist,
                       converged=abs(best[1]) <= math.log1p(tol))


# ----------------------------------------------------------------- the shipped calibration
CALIBRATION_FILE = "sph_calibration.json"


def shipped() -> dict:
    """The shipped calibration (``terradyn/data/sph_calibration.json``): medium ->
    :meth:`Calibration.describe` dict, plus ``_meta``; empty if the file is absent."""
    try:
        text = resources.files("terradyn.data").joinpath(CALIBRATION_FILE).read_text()
    except (FileNotFoundError, ModuleNotFoundError):
        return {}
    try:
        data = json.loads(text)
    except json.JSONDecodeError as e:  # a corrupt package file: say so, do not guess
        raise InputError("sph_calibration.json", f"unreadable ({e})") from None
    return data
