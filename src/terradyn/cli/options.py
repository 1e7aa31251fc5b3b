"""Options shared by the commands: the same names, help and defaults everywhere."""
from __future__ import annotations

from enum import Enum
from pathlib import Path
from typing import Optional

import typer

from ..fieldunits import DEFAULT_LEG
from ..geometry import LEG_SHAPES

Leg = Enum("Leg", {s: s for s in LEG_SHAPES}, type=str)


def leg(default: str = DEFAULT_LEG):
    return typer.Option(Leg(default), "--leg", help="Leg shape (flat, c, reverse-c, foot).")


LEG_FILE = typer.Option(None, "--leg-file", help="CSV polyline x_cm,z_cm from hip to tip (overrides --leg).")
CURVATURE = typer.Option(None, "--curvature", help="Arc curvature chord/(2 radius) in [-1, 1]: 1 = C, 0 = flat, -1 = reverse C (not for the foot).")
LENGTH_CM = typer.Option(None, "--length-cm", help="Chord length, cm (default: 7.62; foot 25).")
WIDTH_CM = typer.Option(None, "--width-cm", help="Leg width, cm (default: 2.54; foot 8.5).")
HIP_HEIGHT_CM = typer.Option(None, "--hip-height-cm", help="Hip height above the surface, cm (default: 2; foot 0).")
OMEGA = typer.Option(0.2, "--omega", help="Angular speed, rad/s (> 0).")
THETA_START_DEG = typer.Option(None, "--theta-start-deg", help="First leg angle, deg (default: -135; foot 0).")
THETA_END_DEG = typer.Option(None, "--theta-end-deg", help="Last leg angle, deg (default: 135; foot 3).")
N_THETA = typer.Option(271, "--n-theta", help="Number of angles (>= 2).")
MOTION_FILE = typer.Option(None, "--motion-file", help="Planar motion CSV time_s,hip_x_cm,hip_z_cm,angle_deg (replaces the rotation).")
PLOT = typer.Option(None, "--plot", help="Write a figure (.png/.pdf/.svg).")


def out(what: str = "Output file .nc, .zarr or .csv", default: str = "CSV on stdout"):
    return typer.Option(None, "--out", "-o", help=f"{what} (default: {default}).")


__all__ = ["Leg", "leg", "LEG_FILE", "CURVATURE", "LENGTH_CM", "WIDTH_CM", "HIP_HEIGHT_CM", "OMEGA",
           "THETA_START_DEG", "THETA_END_DEG", "N_THETA", "MOTION_FILE", "PLOT", "out",
           "Optional", "Path"]
