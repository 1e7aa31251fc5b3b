"""``terradyn rft``: RFT forces for one leg and motion."""
from __future__ import annotations

from enum import Enum
from pathlib import Path
from typing import Optional

import typer

from ..geometry import LEG_SHAPES
from ..media import ALPHA_SOURCES, FITS, INTERPOLATORS

Leg = Enum("Leg", {s: s for s in LEG_SHAPES}, type=str)
Alpha = Enum("Alpha", {s: s for s in ALPHA_SOURCES}, type=str)
Interp = Enum("Interp", {s: s for s in INTERPOLATORS}, type=str)

_MEDIA_HELP = ", ".join(f"'{m}'" for m in FITS)


def rft(
    leg: Leg = typer.Option(Leg.c, "--leg", help="Leg shape (flat, c, reverse-c, foot)."),
    leg_file: Optional[Path] = typer.Option(None, "--leg-file", help="CSV polyline x_cm,z_cm from hip to tip (overrides --leg)."),
    curvature: Optional[float] = typer.Option(None, help="Arc curvature chord/(2 radius) in [-1, 1]: 1 = C, 0 = flat, -1 = reverse C."),
    length_cm: Optional[float] = typer.Option(None, help="Chord length, cm [default: 7.62; foot 25]."),
    width_cm: Optional[float] = typer.Option(None, help="Leg width, cm [default: 2.54; foot 8.5]."),
    hip_height_cm: Optional[float] = typer.Option(None, help="Hip height above the surface, cm [default: 2; foot 0]."),
    omega: float = typer.Option(0.2, help="Angular speed, rad/s (> 0)."),
    theta_start_deg: Optional[float] = typer.Option(None, help="First leg angle, deg [default: -135; foot 0]."),
    theta_end_deg: Optional[float] = typer.Option(None, help="Last leg angle, deg [default: 135; foot 3]."),
    n_theta: int = typer.Option(271, help="Number of angles."),
    elements: int = typer.Option(100, help="Number of plate elements (>= 2)."),
    medium: str = typer.Option("3 mm glass CP", help=f"Medium: {_MEDIA_HELP}."),
    alpha: Alpha = typer.Option(Alpha.fit, help="Stress coefficients: Fourier fit, generic x zeta, or measured table."),
    zeta: Optional[float] = typer.Option(None, help="Scaling factor for --alpha generic [default: the medium's]."),
    interp: Interp = typer.Option(Interp.linear, help="Interpolator for --alpha table (slinear = linear spline)."),
    table_file: Optional[Path] = typer.Option(None, help="Your own measured grid (Table S5 CSV format) for --alpha table."),
    motion_file: Optional[Path] = typer.Option(None, help="Planar motion CSV time_s,hip_x_cm,hip_z_cm,angle_deg (replaces the rotation)."),
    out: Optional[str] = typer.Option(None, "--out", "-o", help="Output file .nc, .zarr or .csv [default: CSV on stdout]."),
    plot: Optional[Path] = typer.Option(None, help="Write a figure (.png/.pdf/.svg)."),
):
    """Quasi-static RFT forces (Fx thrust, Fz lift, N; torque, N m) on a leg.

    Legs: flat, c, reverse-c, foot, any arc (--curvature) or polyline (--leg-file).
    Media (--medium): poppy LP, poppy CP, 0.3 mm glass LP, 0.3 mm glass CP, 3 mm glass CP,
    and for --alpha fit also 'generic'.
    """
    from .. import io, plots
    from ..api import rft_series

    ds = rft_series(leg=leg.value, leg_file=leg_file, curvature=curvature, length_cm=length_cm,
                    width_cm=width_cm, hip_height_cm=hip_height_cm, omega=omega,
                    theta_start_deg=theta_start_deg, theta_end_deg=theta_end_deg, n_theta=n_theta,
                    elements=elements, medium=medium, alpha=alpha.value, zeta=zeta,
                    interp=interp.value, table_file=table_file, motion_file=motion_file)
    io.emit(ds, out)
    if plot is not None:
        label = leg_file.stem if leg_file else leg.value
        plots.forces({label: ds}, plot, title=f"RFT, {label}, {medium} ({alpha.value})")
    from . import err

    if out not in (None, "-"):
        err(f"wrote {out}" + (f" and {plot}" if plot else ""))


def register(app: typer.Typer) -> None:
    app.command("rft")(rft)
