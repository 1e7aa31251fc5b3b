"""Field-unit entry points (cm, deg) shared by the CLI and scripts: they convert at the
edge and call the SI API."""
from __future__ import annotations

from pathlib import Path

import xarray as xr

from .errors import positive
from .geometry import make_leg, read_leg_csv
from .media import stress_model
from .motion import Rotation, read_motion_csv
from .rft import simulate
from .units import CM, DEG


def rft_series(leg: str = "c", leg_file: Path | None = None, curvature: float | None = None,
               length_cm: float | None = None, width_cm: float | None = None,
               hip_height_cm: float | None = None, omega: float = 0.2,
               theta_start_deg: float | None = None, theta_end_deg: float | None = None,
               n_theta: int = 271, elements: int = 100, medium: str = "3 mm glass CP",
               alpha: str = "fit", zeta: float | None = None, interp: str = "linear",
               table_file: Path | None = None, motion_file: Path | None = None) -> xr.Dataset:
    """RFT force series from field-unit inputs; defaults follow the leg (standard test for
    flat/c/reverse-c, the thesis's foot test for the foot)."""
    is_foot = leg == "foot" and leg_file is None
    for name, v in (("length-cm", length_cm), ("width-cm", width_cm)):
        if v is not None:
            positive(name, v, "cm")
    if leg_file is not None:
        shape = read_leg_csv(leg_file, (width_cm if width_cm is not None else 2.54) * CM, elements)
        if curvature is not None:
            from .errors import InputError

            raise InputError("curvature", "cannot be combined with --leg-file")
    else:
        shape = make_leg(leg, None if length_cm is None else length_cm * CM,
                         None if width_cm is None else width_cm * CM, elements, curvature)
    model = stress_model(medium, alpha, zeta, interp, table_file)
    if motion_file is not None:
        motion = read_motion_csv(motion_file)
    else:
        h = hip_height_cm if hip_height_cm is not None else (0.0 if is_foot else 2.0)
        t0 = theta_start_deg if theta_start_deg is not None else (0.0 if is_foot else -135.0)
        t1 = theta_end_deg if theta_end_deg is not None else (3.0 if is_foot else 135.0)
        motion = Rotation(omega, h * CM, t0 * DEG, t1 * DEG, n_theta)
    return simulate(shape, motion, model, medium)
