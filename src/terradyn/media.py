"""Granular media: RFT stress coefficients and material properties.

Stress per unit depth ``alpha`` (N/m^3 inside terradyn; the literature quotes N/cm^3) as a
function of the plate's attack angle ``beta`` and intrusion angle ``gamma`` (rad), after
Li, Zhang & Goldman, "A terradynamics of legged locomotion on granular media",
Science 339:1408 (2013), DOI 10.1126/science.1229163, and its supplement.

Conventions (Li 2013): beta is the plate angle from horizontal (a plate is the same plate after
a half turn, so only 2*beta matters); gamma is the direction of motion below horizontal in the
frame where the horizontal velocity is >= 0 (gamma = +pi/2 straight down); alpha_z > 0 is
upward; alpha_x > 0 opposes the horizontal component of the motion. Outside the measured
gamma range the symmetry alpha_z(b, g) = alpha_z(-b, pi - g), alpha_x(b, g) = -alpha_x(-b, pi - g)
holds (a mirror image), so every stress model here is defined for all angles.

Three kinds of stress model, all with ``alpha(beta, gamma) -> (alpha_x, alpha_z)``:

* :class:`FourierFit` - the nine-term Fourier fit (Table S2), for five media or
  ``generic x zeta`` for any medium;
* :class:`StressTable` - the measured 7 x 13 grids (Table S5) or a user's own grid, with one
  of five interpolators;
* anything with the same method (duck typing) for user extensions.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field, fields
from importlib import resources
from pathlib import Path
from typing import Protocol

import numpy as np

from .errors import InputError, open_text, choice, finite_array, positive
from .units import N_PER_CM3

LI2013 = ("C. Li, T. Zhang, D. I. Goldman, A terradynamics of legged locomotion on granular media, "
          "Science 339:1408-1412 (2013), doi:10.1126/science.1229163")

#: Interpolators for measured grids (scipy.interpolate.RegularGridInterpolator methods).
INTERPOLATORS = ("linear", "nearest", "slinear", "cubic", "quintic")
#: Human names for the interpolators (the thesis calls slinear "linear spline").
INTERPOLATOR_NAMES = {"linear": "linear", "nearest": "nearest", "slinear": "linear spline",
                      "cubic": "cubic", "quintic": "quintic"}


class StressModel(Protocol):
    def alpha(self, beta, gamma) -> tuple[np.ndarray, np.ndarray]:
        """Stress per unit depth (alpha_x, alpha_z) in N/m^3 at angles in rad (broadcast)."""


# --------------------------------------------------------------------------------------------
# Fourier fit
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class FourierFit:
    """Li 2013 nine-term Fourier fit of alpha_z, alpha_x; coefficients in N/m^3.

    alpha_z = A00 + A10 cos 2b + B11 sin(2b+g) + B01 sin g + Bm11 sin(-2b+g)
    alpha_x = C11 cos(2b+g) + C01 cos g + Cm11 cos(-2b+g) + D10 sin 2b
    """

    A00: float
    A10: float
    B11: float
    B01: float
    Bm11: float
    C11: float
    C01: float
    Cm11: float
    D10: float
    name: str = "custom"

    @classmethod
    def from_n_per_cm3(cls, name: str = "custom", **coeffs: float) -> "FourierFit":
        return cls(name=name, **{k: float(v) * N_PER_CM3 for k, v in coeffs.items()})

    def as_array(self, dtype=np.float64) -> np.ndarray:
        """The nine coefficients (N/m^3) in field order, for compiled kernels (cached)."""
        cache = self.__dict__.setdefault("_array_cache", {})
        key = np.dtype(dtype).str
        if key not in cache:
            cache[key] = np.array([getattr(self, f.name) for f in fields(self) if f.name != "name"],
                                  dtype=dtype)
        return cache[key]

    def scaled(self, zeta: float, name: str | None = None) -> "FourierFit":
        zeta = positive("zeta", zeta)
        vals = {f.name: getattr(self, f.name) * zeta for f in fields(self) if f.name != "name"}
        return FourierFit(name=name or f"{self.name} x {zeta:g}", **vals)

    def alpha(self, beta, gamma):
        b2 = 2.0 * np.asarray(beta, dtype=float)
        g = np.asarray(gamma, dtype=float)
        az = (self.A00 + self.A10 * np.cos(b2) + self.B11 * np.sin(b2 + g)
              + self.B01 * np.sin(g) + self.Bm11 * np.sin(-b2 + g))
        ax = (self.C11 * np.cos(b2 + g) + self.C01 * np.cos(g)
              + self.Cm11 * np.cos(-b2 + g) + self.D10 * np.sin(b2))
        return ax, az

    def describe(self) -> dict:
        return {"kind": "fourier-fit", "name": self.name,
                "coefficients_N_per_cm3": {f.name: getattr(self, f.name) / N_PER_CM3
                                           for f in fields(self) if f.name != "name"}}


# Table S2 of the Li 2013 supplement, N/cm^3, in the order A00 A10 B11 B01 B-11 C11 C01 C-11 D10.
_S2 = {
    "poppy LP": (0.051, 0.047, 0.053, 0.083, 0.020, -0.026, 0.057, 0.000, 0.025),
    "poppy CP": (0.094, 0.092, 0.092, 0.151, 0.035, -0.039, 0.086, 0.018, 0.046),
    "0.3 mm glass LP": (0.040, 0.030, 0.045, 0.077, 0.000, -0.031, 0.066, 0.000, 0.017),
    "0.3 mm glass CP": (0.081, 0.063, 0.078, 0.133, 0.024, -0.050, 0.087, 0.000, 0.033),
    "3 mm glass CP": (0.045, 0.031, 0.046, 0.084, 0.012, -0.031, 0.060, 0.000, 0.015),
    "generic": (0.206, 0.169, 0.212, 0.358, 0.055, -0.124, 0.253, 0.007, 0.088),
}
_NAMES = ("A00", "A10", "B11", "B01", "Bm11", "C11", "C01", "Cm11", "D10")

#: The Li 2013 fits (Table S2) by medium name, including ``"generic"``.
FITS: dict[str, FourierFit] = {
    m: FourierFit.from_n_per_cm3(m, **dict(zip(_NAMES, v))) for m, v in _S2.items()}

#: Scaling factor zeta of each medium relative to the generic fit (Table S2).
ZETA = {"poppy LP": 0.248, "poppy CP": 0.488, "0.3 mm glass LP": 0.194,
        "0.3 mm glass CP": 0.371, "3 mm glass CP": 0.214, "generic": 1.0}


def generic(zeta: float) -> FourierFit:
    """Generic coefficients times ``zeta`` (Li 2013): a fit for any medium from one number."""
    return FITS["generic"].scaled(zeta, name=f"generic x zeta={zeta:g}")


def zeta_from_plate_test(alpha_z_plate: float) -> float:
    """Estimate zeta from alpha_z(0, pi/2) (N/m^3) measured by pushing a horizontal plate down.

    Li 2013: zeta ~= 0.8 x alpha_z(0, pi/2) expressed in N/cm^3.
    """
    return 0.8 * positive("alpha_z_plate", alpha_z_plate, "N/m^3") / N_PER_CM3


# --------------------------------------------------------------------------------------------
# Measured grids
# --------------------------------------------------------------------------------------------
def wrap_angles(beta, gamma):
    """Map any (beta, gamma) into the measured domain [-pi/2, pi/2]^2.

    Returns (beta', gamma', sign) with alpha_z(b, g) = alpha_z(b', g') and
    alpha_x(b, g) = sign * alpha_x(b', g').
    """
    beta = np.asarray(beta, dtype=float)
    gamma = np.asarray(gamma, dtype=float)
    g = np.mod(gamma + np.pi, 2 * np.pi) - np.pi  # (-pi, pi]
    back = np.abs(g) > np.pi / 2  # moving against +x: mirror the scene
    g = np.where(back, np.where(g > 0, np.pi - g, -np.pi - g), g)
    b = np.where(back, -beta, beta)
    b = np.mod(b + np.pi / 2, np.pi) - np.pi / 2  # [-pi/2, pi/2)
    return b, g, np.where(back, -1.0, 1.0)


@dataclass(frozen=True, eq=False)
class StressTable:
    """A measured grid alpha(beta, gamma) with an interpolator valid over all angles.

    beta: (nb,) rad ascending covering [-pi/2, pi/2]; gamma: (ng,) rad ascending covering
    [-pi/2, pi/2]; alpha_z, alpha_x: (nb, ng) N/m^3.
    """

    name: str
    beta: np.ndarray
    gamma: np.ndarray
    alpha_z: np.ndarray
    alpha_x: np.ndarray
    method: str = "linear"
    source: str = ""
    _interp: tuple = field(default=None, repr=False, compare=False)

    def __post_init__(self):
        choice("interp", self.method, INTERPOLATORS)
        from scipy.interpolate import RegularGridInterpolator

        need = {"linear": 2, "nearest": 1, "slinear": 2, "cubic": 4, "quintic": 6}[self.method]
        if min(len(self.beta), len(self.gamma)) < need:
            raise InputError("interp", f"{self.method} needs >= {need} grid points per axis")
        grid = (self.beta, self.gamma)
        interp = tuple(RegularGridInterpolator(grid, a, method=self.method, bounds_error=False,
                                               fill_value=None)
                       for a in (self.alpha_x, self.alpha_z))
        object.__setattr__(self, "_interp", interp)

    def with_method(self, method: str) -> "StressTable":
        return StressTable(self.name, self.beta, self.gamma, self.alpha_z, self.alpha_x,
                           method, self.source)

    def alpha(self, beta, gamma):
        b, g, sign = wrap_angles(beta, gamma)
        # Numerical safety: exact grid ends.
        b = np.clip(b, self.beta[0], self.beta[-1])
        g = np.clip(g, self.gamma[0], self.gamma[-1])
        pts = np.stack([b.ravel(), g.ravel()], axis=-1)
        ax = self._interp[0](pts).reshape(b.shape) * sign
        az = self._interp[1](pts).reshape(b.shape)
        return ax, az

    def describe(self) -> dict:
        return {"kind": "measured-table", "name": self.name, "interp": self.method,
                "source": self.source}


def _validate_grid(name: str, rows: list[tuple[float, float, float, float]], source: str,
                   method: str) -> StressTable:
    a = finite_array(f"{source}: alpha table", rows, ndim=2)
    betas = np.unique(np.round(a[:, 0], 6))
    gammas = np.unique(np.round(a[:, 1], 6))
    if len(betas) < 2 or len(gammas) < 2:
        raise InputError(source, "needs at least 2 distinct beta and 2 distinct gamma values")
    if len(a) != len(betas) * len(gammas):
        raise InputError(source, f"rows for medium {name!r} do not form a full beta x gamma grid "
                                 f"({len(a)} rows for {len(betas)} beta x {len(gammas)} gamma)")
    tol = 1e-3
    if betas[0] > -np.pi / 2 + tol or betas[-1] < np.pi / 2 - tol:
        raise InputError(source, "beta_rad must cover [-pi/2, pi/2] (the plate's full half turn)")
    if gammas[0] > -np.pi / 2 + tol or gammas[-1] < np.pi / 2 - tol:
        raise InputError(source, "gamma_rad must cover [-pi/2, pi/2] (straight up to straight down)")
    if np.abs(a[:, :2]).max() > np.pi / 2 + tol:
        raise InputError(source, "beta_rad and gamma_rad must lie in [-pi/2, pi/2] (radians, not degrees)")
    ib = np.searchsorted(betas, np.round(a[:, 0], 6))
    ig = np.searchsorted(gammas, np.round(a[:, 1], 6))
    az = np.full((len(betas), len(gammas)), np.nan)
    ax = np.full_like(az, np.nan)
    az[ib, ig] = a[:, 2] * N_PER_CM3
    ax[ib, ig] = a[:, 3] * N_PER_CM3
    if np.isnan(az).any():
        raise InputError(source, f"duplicate (beta, gamma) rows for medium {name!r}")
    # Snap the grid ends to exactly +-pi/2 so the closed domain is covered.
    betas = betas.astype(float)
    gammas = gammas.astype(float)
    betas[0], betas[-1] = -np.pi / 2, np.pi / 2
    gammas[0], gammas[-1] = -np.pi / 2, np.pi / 2
    return StressTable(name, betas, gammas, az, ax, method, source)


_COLUMNS = ("medium", "beta_rad", "gamma_rad", "alpha_z_N_per_cm3", "alpha_x_N_per_cm3")


def read_tables(path: str | Path, method: str = "linear") -> dict[str, StressTable]:
    """Read a grid CSV in the Table S5 format (columns: medium, beta_rad, gamma_rad,
    alpha_z_N_per_cm3, alpha_x_N_per_cm3); one :class:`StressTable` per medium."""
    path = Path(path)
    if not path.is_file():
        raise InputError("table-file", f"file not found: {path}")
    with open_text(path, "table-file") as fh:
        try:
            return _parse_tables(fh, str(path), method)
        except InputError as e:
            if e.field != str(path):
                raise
            raise InputError("table-file", str(e)) from None


def _parse_tables(fh, source: str, method: str) -> dict[str, StressTable]:
    reader = csv.DictReader(fh)
    missing = [c for c in _COLUMNS if c not in (reader.fieldnames or [])]
    if missing:
        raise InputError(source, f"missing column(s) {', '.join(missing)}; expected {', '.join(_COLUMNS)}")
    per: dict[str, list] = {}
    for lineno, row in enumerate(reader, start=2):
        try:
            vals = tuple(float(row[c]) for c in _COLUMNS[1:])
        except (TypeError, ValueError):
            raise InputError(source, f"line {lineno}: non-numeric value in {row}") from None
        if not all(math.isfinite(v) for v in vals):
            raise InputError(source, f"line {lineno}: non-finite value in {row}")
        per.setdefault(row["medium"], []).append(vals)
    if not per:
        raise InputError(source, "no data rows")
    return {m: _validate_grid(m, rows, source, method) for m, rows in per.items()}


def packaged_tables(method: str = "linear") -> dict[str, StressTable]:
    """The five measured grids of Li 2013 (Table S5), shipped with terradyn."""
    ref = resources.files("terradyn") / "data" / "li2013_alpha_table_s5.csv"
    with ref.open("r", newline="") as fh:
        tabs = _parse_tables(fh, "li2013_alpha_table_s5.csv", method)
    return {k: StressTable(v.name, v.beta, v.gamma, v.alpha_z, v.alpha_x, method,
                           f"{LI2013}, supplement Table S5") for k, v in tabs.items()}


# --------------------------------------------------------------------------------------------
# Media
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Medium:
    """A dry granular medium. SI units. ``alpha_z_plate``: measured alpha_z(0, pi/2), N/m^3."""

    name: str
    grain_diameter: float  # m
    grain_density: float  # kg/m^3
    volume_fraction: float
    repose_angle: float  # rad
    alpha_z_plate: float | None = None  # N/m^3
    citation: str = LI2013

    @property
    def bulk_density(self) -> float:
        """Bulk density of the bed, kg/m^3."""
        return self.grain_density * self.volume_fraction


_DEG = math.pi / 180
#: Media of Li 2013 supplement Table S1 (properties) and the measured alpha_z(0, pi/2).
MEDIA: dict[str, Medium] = {
    "poppy LP": Medium("poppy LP", 0.7e-3, 1100.0, 0.58, 36 * _DEG, 0.35 * N_PER_CM3),
    "poppy CP": Medium("poppy CP", 0.7e-3, 1100.0, 0.62, 47 * _DEG, 0.56 * N_PER_CM3),
    "0.3 mm glass LP": Medium("0.3 mm glass LP", 0.3e-3, 2500.0, 0.58, 25 * _DEG, 0.24 * N_PER_CM3),
    "0.3 mm glass CP": Medium("0.3 mm glass CP", 0.3e-3, 2500.0, 0.62, 35 * _DEG, 0.40 * N_PER_CM3),
    "3 mm glass CP": Medium("3 mm glass CP", 3.0e-3, 2600.0, 0.63, 21 * _DEG, 0.29 * N_PER_CM3),
}

ALPHA_SOURCES = ("fit", "generic", "table")


def medium_names() -> list[str]:
    return list(MEDIA)


def stress_model(medium: str = "3 mm glass CP", alpha: str = "fit", zeta: float | None = None,
                 interp: str = "linear", table_file: str | Path | None = None) -> StressModel:
    """Resolve the stress model a user asks for.

    alpha="fit": the medium's own Fourier fit (Table S2);
    alpha="generic": generic fit x zeta (zeta defaults to the medium's Table S2 value);
    alpha="table": the measured grid (Table S5, or ``table_file``) with ``interp``.
    """
    choice("alpha", alpha, ALPHA_SOURCES)
    if alpha == "generic":
        if zeta is None:
            if medium not in ZETA:
                raise InputError("zeta", f"medium {medium!r} has no tabulated zeta; give --zeta")
            zeta = ZETA[medium]
        return generic(zeta)
    if zeta is not None:
        raise InputError("zeta", "only applies with alpha='generic'")
    if alpha == "fit":
        choice("medium", medium, list(FITS))
        return FITS[medium]
    choice("interp", interp, INTERPOLATORS)
    tables = read_tables(table_file, interp) if table_file else packaged_tables(interp)
    choice("medium", medium, list(tables))
    return tables[medium]
