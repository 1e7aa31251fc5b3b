"""``terradyn rft``: RFT forces for one leg and motion."""
from __future__ import annotations

from enum import Enum
from pathlib import Path
from typing import Optional

import typer

from ..media import ALPHA_SOURCES, FITS, INTERPOLATORS
from . import options as O

Alpha = Enum("Alpha", {s: s for s in ALPHA_SOURCES}, type=str)
Interp = Enum("Interp", {s: s for s in INTERPOLATORS}, type=str)

_MEDIA_HELP = ", ".join(f"'{m}'" for m in FITS)


def rft(
    leg: O.Leg = O.leg(),
    leg_file: Optional[Path] = O.LEG_FILE,
    curvature: Optional[float] = O.CURVATURE,
    length_cm: Optional[float] = O.LENGTH_CM,
    width_cm: Optional[float] = O.WIDTH_CM,
    hip_height_cm: Optional[float] = O.HIP_HEIGHT_CM,
    omega: float = O.OMEGA,
    theta_start_deg: Optional[float] = O.THETA_START_DEG,
    theta_end_deg: Optional[float] = O.THETA_END_DEG,
    n_theta: int = O.N_THETA,
    elements: int = typer.Option(100, help="Number of plate elements (>= 2)."),
    medium: str = typer.Option("3 mm glass CP", help=f"Medium: {_MEDIA_HELP}."),
    alpha: Alpha = typer.Option(Alpha.fit, help="Stress coefficients: Fourier fit, generic x zeta, or measured table."),
    zeta: Optional[float] = typer.Option(None, help="Scaling factor for --alpha generic (default: the medium's)."),
    interp: Optional[Interp] = typer.Option(None, help="Interpolator for --alpha table (default: linear; slinear = linear spline)."),
    table_file: Optional[Path] = typer.Option(None, help="Your own measured grid (Table S5 CSV format) for --alpha table."),
    motion_file: Optional[Path] = O.MOTION_FILE,
    dynamic_lambda: Optional[float] = typer.Option(
        None, help="Add the dynamic-RFT inertial term lambda rho (v.n)^2 (Agarwal et al. 2021; rho: the "
                   "medium's bulk density) with this lambda, in [0, 10]; 1.1 is Agarwal's value "
                   "[default: quasi-static]."),
    out: Optional[str] = O.out(),
    plot: Optional[Path] = O.PLOT,
):
    """Quasi-static RFT forces (Fx thrust, Fz lift, N; torque, N m) on a leg.

    Legs: flat, c, reverse-c, foot, any arc (--curvature) or polyline (--leg-file).
    Media (--medium): poppy LP, poppy CP, 0.3 mm glass LP, 0.3 mm glass CP, 3 mm glass CP,
    and for --alpha fit also 'generic'.
    """
    from .. import io, plots
    from ..fieldunits import series_from_field_units
    from . import err

    io.check_output(out, "out")
    io.check_plot(plot)
    if table_file is not None and alpha.value == "table":
        io.check_input(table_file, "table-file")
    ds = series_from_field_units(
        "rft", leg=leg.value, leg_file=leg_file, curvature=curvature, length_cm=length_cm,
        width_cm=width_cm, hip_height_cm=hip_height_cm, omega=omega, theta_start_deg=theta_start_deg,
        theta_end_deg=theta_end_deg, n_theta=n_theta, elements=elements, medium=medium,
        motion_file=motion_file, alpha=alpha.value, zeta=zeta,
        interp=None if interp is None else interp.value,
        table_file=None if table_file is None else str(table_file), dynamic_lambda=dynamic_lambda)
    io.emit(ds, out)
    if plot is not None:
        label = leg_file.stem if leg_file else leg.value
        plots.forces({label: ds}, plot, title=f"RFT, {label}, {medium} ({alpha.value})")
    if out not in (None, "-"):
        err(f"wrote {out}" + (f" and {plot}" if plot else ""))


def register(app: typer.Typer) -> None:
    app.command("rft")(rft)
