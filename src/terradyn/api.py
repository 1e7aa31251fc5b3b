"""Field-unit entry points (cm, deg) shared by the CLI and scripts: they convert at the
edge and call the SI API."""
from __future__ import annotations

from pathlib import Path

import xarray as xr

from .errors import InputError, positive
from .geometry import Leg, make_leg, read_leg_csv
from .media import stress_model
from .motion import Rotation, read_motion_csv
from .rft import simulate
from .units import CM, DEG


def leg_from_field_units(leg: str = "c", leg_file: Path | None = None,
                         curvature: float | None = None, length_cm: float | None = None,
                         width_cm: float | None = None, elements: int = 100) -> Leg:
    """A leg from CLI-style inputs: a preset (with optional curvature, length and width in
    cm) or a polyline CSV; unset sizes take the preset's defaults."""
    for name, v in (("length-cm", length_cm), ("width-cm", width_cm)):
        if v is not None:
            positive(name, v, "cm")
    if leg_file is not None:
        if curvature is not None:
            raise InputError("curvature", "cannot be combined with --leg-file")
        return read_leg_csv(leg_file, (width_cm if width_cm is not None else 2.54) * CM, elements)
    return make_leg(leg, None if length_cm is None else length_cm * CM,
                    None if width_cm is None else width_cm * CM, elements, curvature)


def motion_from_field_units(foot: bool = False, motion_file: Path | None = None,
                            omega: float = 0.2, hip_height_cm: float | None = None,
                            theta_start_deg: float | None = None,
                            theta_end_deg: float | None = None, n_theta: int = 271):
    """A planar motion CSV, or a rotation whose unset values follow the standard test
    (h = 2 cm, -135..135 deg) or, for the foot, the thesis's foot test (h = 0, 0..3 deg)."""
    if motion_file is not None:
        return read_motion_csv(motion_file)
    h = hip_height_cm if hip_height_cm is not None else (0.0 if foot else 2.0)
    t0 = theta_start_deg if theta_start_deg is not None else (0.0 if foot else -135.0)
    t1 = theta_end_deg if theta_end_deg is not None else (3.0 if foot else 135.0)
    return Rotation(omega, h * CM, t0 * DEG, t1 * DEG, n_theta)


def rft_series(leg: str = "c", leg_file: Path | None = None, curvature: float | None = None,
               length_cm: float | None = None, width_cm: float | None = None,
               hip_height_cm: float | None = None, omega: float = 0.2,
               theta_start_deg: float | None = None, theta_end_deg: float | None = None,
               n_theta: int = 271, elements: int = 100, medium: str = "3 mm glass CP",
               alpha: str = "fit", zeta: float | None = None, interp: str = "linear",
               table_file: Path | None = None, motion_file: Path | None = None) -> xr.Dataset:
    """RFT force series from field-unit inputs; defaults follow the leg (standard test for
    flat/c/reverse-c, the thesis's foot test for the foot)."""
    shape = leg_from_field_units(leg, leg_file, curvature, length_cm, width_cm, elements)
    model = stress_model(medium, alpha, zeta, interp, table_file)
    motion = motion_from_field_units(leg == "foot" and leg_file is None, motion_file, omega,
                                     hip_height_cm, theta_start_deg, theta_end_deg, n_theta)
    return simulate(shape, motion, model, medium)
