"""``terradyn rft3d``: 3D RFT forces on a mesh or preset body in a 6-DoF motion."""
from __future__ import annotations

from enum import Enum
from pathlib import Path
from typing import Optional

import typer

from ..media import ALPHA_SOURCES, MEDIA
from ..rft3d.body import MESH_UNITS
from ..rft3d.model import DEFAULT_MU_SURF, XI_SOURCES
from ..rft3d.presets import PRESETS

Body = Enum("Body", {s: s for s in PRESETS}, type=str)
Model = Enum("Model", {s: s for s in ("agarwal", "treers")}, type=str)
Alpha = Enum("Alpha", {s: s for s in ALPHA_SOURCES}, type=str)
Units = Enum("Units", {s: s for s in MESH_UNITS}, type=str)
XiFrom = Enum("XiFrom", {s: s for s in XI_SOURCES}, type=str)

_MEDIA_HELP = ", ".join(f"'{m}'" for m in MEDIA)


def rft3d(
    mesh: Optional[Path] = typer.Option(None, "--mesh", help="Body mesh file (.stl, .obj, .ply); overrides --body."),
    mesh_units: Units = typer.Option(Units.mm, help="Units of the mesh file's coordinates."),
    open_surface: bool = typer.Option(False, "--open-surface", help="Accept a mesh that is not closed (a sheet); normals as wound."),
    max_edge_cm: Optional[float] = typer.Option(None, help="Refine the mesh until no edge is longer than this, cm."),
    body: Body = typer.Option(Body.c, "--body", help="Preset body (the standard legs flat, c, reverse-c: 2.54 x 0.64 cm; plate, cylinder, sphere, wheel, foot sole 25 x 8.5 cm)."),
    motion: Optional[Path] = typer.Option(None, "--motion", help="6-DoF motion CSV time_s,x_cm,y_cm,z_cm,qw,qx,qy,qz (replaces the rotation)."),
    axis: str = typer.Option("0,1,0", help="Rotation axis x,y,z (world; +y turns a leg like the 2D leg angle)."),
    center_cm: str = typer.Option("0,0,2", help="Point on the rotation axis x,y,z, cm (the body-frame origin starts there unless --position-cm)."),
    position_cm: Optional[str] = typer.Option(None, help="Start position of the body-frame origin x,y,z, cm [default: --center-cm]."),
    quat: str = typer.Option("1,0,0,0", help="Orientation at angle 0 as a unit quaternion w,x,y,z."),
    omega: float = typer.Option(0.2, help="Rotation speed, rad/s (> 0)."),
    angle_start_deg: float = typer.Option(-135.0, help="First rotation angle, deg."),
    angle_end_deg: float = typer.Option(135.0, help="Last rotation angle, deg."),
    n_angles: int = typer.Option(271, help="Number of samples of the rotation."),
    surface_cm: float = typer.Option(0.0, help="Height of the free surface, cm (bed below)."),
    medium: str = typer.Option("3 mm glass CP", help=f"Medium: {_MEDIA_HELP}."),
    model: Model = typer.Option(Model.agarwal, help="agarwal: 3D-RFT (Agarwal 2023); treers: 2D coefficients on 3D bodies (Treers 2021)."),
    xi_from: XiFrom = typer.Option(XiFrom.plate, help="agarwal: medium scale xi_n from the measured plate alpha_z(0, pi/2) (Li 2013) or from friction (Agarwal 2023, tan(repose angle): 2-5x too strong for these media)."),
    mu_surf: float = typer.Option(DEFAULT_MU_SURF, help="agarwal: body-grain friction coefficient (tangential cap)."),
    alpha: Alpha = typer.Option(Alpha.fit, help="treers: 2D coefficients (Fourier fit, generic x zeta, measured table)."),
    table_file: Optional[Path] = typer.Option(None, help="treers: your own measured grid (Table S5 CSV format), with --alpha table."),
    dynamic: bool = typer.Option(False, "--dynamic", help="Add the dynamic-RFT inertial term (Agarwal 2021)."),
    lam: float = typer.Option(1.1, "--lambda", help="Dynamic-RFT lambda (with --dynamic)."),
    out: Optional[str] = typer.Option(None, "--out", "-o", help="Output .nc, .zarr or .csv [default: CSV on stdout]."),
    elements_out: Optional[Path] = typer.Option(None, help="Also write the per-element tractions (time x element) to this .nc or .zarr file."),
    plot: Optional[Path] = typer.Option(None, help="Figure of the body with its element tractions and the forces (.png/.pdf/.svg)."),
    frame_deg: Optional[float] = typer.Option(None, help="Angle (rotation) of the frame in the figure, deg [default: at the largest |F|]."),
):
    """3D RFT force series (Fx, Fy, Fz in N; Tx, Ty, Tz in N m about the body-frame origin).

    World frame x forward, y left, z up; the bed below z = --surface-cm. Default: the standard
    rotating-leg test (hip 2 cm above the surface, -135..135 deg about +y at 0.2 rad/s).
    """
    from .. import io
    from ..fieldunits import rft3d_series

    if lam != 1.1 and not dynamic:
        from ..errors import InputError

        raise InputError("lambda", "only applies with --dynamic")
    io.check_output(out)
    io.check_plot(plot)
    if elements_out is not None:
        io.check_output(elements_out, "elements-out", (".nc", ".zarr"))
    res = rft3d_series(
        mesh=mesh, mesh_units=mesh_units.value, open_surface=open_surface, max_edge_cm=max_edge_cm,
        body=body.value, motion=motion, axis=axis, center_cm=center_cm, position_cm=position_cm,
        quat=quat, omega=omega, angle_start_deg=angle_start_deg, angle_end_deg=angle_end_deg,
        n_angles=n_angles, surface_cm=surface_cm, medium=medium, model=model.value,
        xi_from=xi_from.value, mu_surf=mu_surf, alpha=alpha.value, table_file=table_file,
        dynamic_lambda=lam if dynamic else None, frame_deg=frame_deg if plot else None,
        want_frame=plot is not None, want_elements=elements_out is not None)
    ds, frame, b = res[:3]
    io.emit(ds, out)
    if elements_out is not None:
        io.write(res[3], elements_out)
    if plot is not None:
        from ..plots_rft3d import body_tractions

        body_tractions(b, frame, ds, plot, title=f"{b.name} in {medium} ({model.value})",
                       surface=surface_cm / 100)
    from . import err

    written = [str(x) for x in (None if out in (None, "-") else out, elements_out, plot) if x]
    if written:
        err("wrote " + ", ".join(written))


def register(app: typer.Typer) -> None:
    app.command("rft3d")(rft3d)
