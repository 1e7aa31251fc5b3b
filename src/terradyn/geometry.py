"""Leg shapes in the leg's body frame, discretised into plate elements.

Body frame (SI, metres): the hip (rotation axis) is the origin, x points forward (the
direction a robot walks), z points up. A standard leg hangs down: its chord runs from the hip
(0, 0) to the tip (0, -L). With a positive angular speed the leg turns clockwise (see
:mod:`terradyn.motion`), so at theta = 0 its tip sweeps backwards (-x) and the sand pushes the
leg forwards (+x, thrust). A C-shaped leg bulges towards the tip's motion (-x, its convex side
leads), a reverse C-shaped leg the other way.

Every leg discretises into :class:`Elements`: centre points, unit tangents, lengths and areas,
one row per element. Elements are cut at equal arc length and represented by their midpoints
(second-order accurate in the element size).
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import InputError, open_text, finite_array, in_range, integer, positive
from .units import CM


@dataclass(frozen=True, eq=False)
class Elements:
    """Plate elements of a leg in its body frame.

    centers: (n, 2) m; tangents: (n, 2) unit vectors; lengths: (n,) m; areas: (n,) m^2.
    """

    centers: np.ndarray
    tangents: np.ndarray
    lengths: np.ndarray
    areas: np.ndarray

    def __len__(self) -> int:
        return len(self.lengths)


@dataclass(frozen=True)
class Leg:
    """Base of all legs: a width (m) and a number of elements."""

    width: float
    n_elements: int

    def _check(self):
        positive("width", self.width, "m")
        integer("elements", self.n_elements, 2)

    def elements(self) -> Elements:  # pragma: no cover - abstract
        raise NotImplementedError

    def outline(self, n: int = 200) -> np.ndarray:
        """(n, 2) points along the leg from hip to tip, for plots."""
        raise NotImplementedError  # pragma: no cover

    def describe(self) -> dict:
        raise NotImplementedError  # pragma: no cover

    def mirrored(self) -> "Leg":
        """The mirror image x -> -x."""
        raise NotImplementedError  # pragma: no cover


@dataclass(frozen=True)
class ArcLeg(Leg):
    """A circular arc from the hip to the tip, chord ``chord`` (m) pointing down.

    ``curvature`` is dimensionless: k = chord / (2 * radius), signed. k = 0 is a flat plate,
    k = +1 the C-shaped half circle (bulging towards -x, the tip's direction of motion),
    k = -1 the reverse C. ``direction`` (rad) turns the chord from straight down,
    anticlockwise (pi/2 makes the leg point forward: used for the foot).
    """

    chord: float = 7.62 * CM
    curvature: float = 0.0
    name: str = "arc"
    direction: float = 0.0

    def __post_init__(self):
        self._check()
        positive("length", self.chord, "m")
        in_range("curvature", self.curvature, -1.0, 1.0, "(chord / (2 radius))")

    @property
    def half_angle(self) -> float:
        return math.asin(abs(self.curvature))

    @property
    def arc_length(self) -> float:
        phi = self.half_angle
        return self.chord if phi == 0 else self.chord * phi / math.sin(phi)

    def _points_tangents(self, u: np.ndarray):
        """Points and unit tangents at arc parameter u in [-1 (tip), 1 (hip)]."""
        L, k = self.chord, self.curvature
        phi = self.half_angle
        if k == 0:
            x = np.zeros_like(u)
            z = -L / 2 + (L / 2) * u
            tx, tz = np.zeros_like(u), np.ones_like(u)
        else:
            rho = L / (2 * abs(k))
            psi = phi * u
            # x = -rho (cos psi - cos phi), written without cancellation for small curvature.
            x = -2 * rho * np.sin((phi + psi) / 2) * np.sin((phi - psi) / 2)
            z = -L / 2 + rho * np.sin(psi)
            tx, tz = np.sin(psi), np.cos(psi)
            if k < 0:
                x, tx = -x, -tx
        pts = _rotate_ccw(np.stack([x, z], -1), self.direction)
        tan = _rotate_ccw(np.stack([tx, tz], -1), self.direction)
        return pts, tan

    def elements(self) -> Elements:
        n = self.n_elements
        return self.elements_at(1 - (2 * np.arange(1, n + 1) - 1) / n)  # hip to tip

    def elements_at(self, u) -> Elements:
        """Elements at arc parameters ``u`` in [-1 (tip), 1 (hip)], each carrying an equal
        share of the arc (for quadrature-rule studies; :meth:`elements` uses midpoints)."""
        u = np.asarray(u, dtype=float)
        pts, tan = self._points_tangents(u)
        ds = np.full(len(u), self.arc_length / len(u))
        return Elements(pts, tan, ds, ds * self.width)

    def outline(self, n: int = 200) -> np.ndarray:
        return self._points_tangents(np.linspace(1, -1, n))[0]

    def mirrored(self) -> "ArcLeg":
        return ArcLeg(self.width, self.n_elements, self.chord, -self.curvature,
                      f"mirror of {self.name}", -self.direction)

    def describe(self) -> dict:
        return {"shape": self.name, "kind": "arc", "chord_m": self.chord, "width_m": self.width,
                "curvature": self.curvature, "direction_rad": self.direction,
                "elements": self.n_elements}


@dataclass(frozen=True, eq=False)
class PolylineLeg(Leg):
    """An open polyline in the body frame (m), hip at the origin, resampled by arc length."""

    points: np.ndarray = None
    name: str = "polyline"

    def __post_init__(self):
        self._check()
        pts = finite_array("leg points", self.points, ndim=2)
        if pts.shape[1] != 2 or len(pts) < 2:
            raise InputError("leg points", f"need at least 2 points of (x, z); got shape {pts.shape}")
        seg = np.diff(pts, axis=0)
        seglen = np.hypot(seg[:, 0], seg[:, 1])
        if (seglen <= 1e-12 * max(1.0, np.abs(pts).max())).any():
            i = int(np.argmax(seglen <= 1e-12 * max(1.0, np.abs(pts).max())))
            raise InputError("leg points", f"points {i} and {i + 1} coincide (zero-length segment)")
        _check_simple(pts)
        object.__setattr__(self, "points", pts)

    @property
    def arc_length(self) -> float:
        return float(np.hypot(*np.diff(self.points, axis=0).T).sum())

    def elements(self) -> Elements:
        pts = self.points
        seg = np.diff(pts, axis=0)
        seglen = np.hypot(seg[:, 0], seg[:, 1])
        s = np.concatenate([[0.0], np.cumsum(seglen)])
        n = self.n_elements
        edges = np.linspace(0, s[-1], n + 1)
        mids = 0.5 * (edges[1:] + edges[:-1])
        j = np.clip(np.searchsorted(s, mids, side="right") - 1, 0, len(seg) - 1)
        frac = (mids - s[j]) / seglen[j]
        centers = pts[j] + frac[:, None] * seg[j]
        tangents = seg[j] / seglen[j, None]
        # An element that straddles a vertex takes the tangent of its chord (keeps sum of
        # projected areas right at corners).
        a = np.searchsorted(s, edges[:-1], side="right") - 1
        b = np.searchsorted(s, edges[1:], side="left") - 1
        corner = np.clip(a, 0, len(seg) - 1) != np.clip(b, 0, len(seg) - 1)
        if corner.any():
            pa = _interp_path(pts, s, edges[:-1][corner])
            pb = _interp_path(pts, s, edges[1:][corner])
            d = pb - pa
            tangents[corner] = d / np.hypot(d[:, 0], d[:, 1])[:, None]
        ds = np.diff(edges)
        return Elements(centers, tangents, ds, ds * self.width)

    def outline(self, n: int = 200) -> np.ndarray:
        return self.points

    def mirrored(self) -> "PolylineLeg":
        return PolylineLeg(self.width, self.n_elements, self.points * [-1.0, 1.0],
                           f"mirror of {self.name}")

    def describe(self) -> dict:
        return {"shape": self.name, "kind": "polyline", "width_m": self.width,
                "elements": self.n_elements, "points_m": self.points.round(9).tolist()}


def _interp_path(pts, s, q):
    return np.stack([np.interp(q, s, pts[:, 0]), np.interp(q, s, pts[:, 1])], -1)


def _rotate_ccw(v: np.ndarray, a: float) -> np.ndarray:
    if a == 0:
        return v
    c, s = math.cos(a), math.sin(a)
    return np.stack([c * v[..., 0] - s * v[..., 1], s * v[..., 0] + c * v[..., 1]], -1)


def _check_simple(pts: np.ndarray) -> None:
    """Raise if the polyline folds back on itself or crosses itself."""
    seg = np.diff(pts, axis=0)
    # Fold: consecutive segments pointing (almost) opposite ways.
    if len(seg) > 1:
        u = seg / np.hypot(seg[:, 0], seg[:, 1])[:, None]
        dots = (u[1:] * u[:-1]).sum(1)
        crossz = u[:-1, 0] * u[1:, 1] - u[:-1, 1] * u[1:, 0]
        fold = (dots < 0) & (np.abs(crossz) < 1e-9)
        if fold.any():
            i = int(np.argmax(fold)) + 1
            raise InputError("leg points", f"the polyline folds back on itself at point {i}")
    m = len(seg)
    if m < 3:
        return
    p, r = pts[:-1], seg
    i, j = np.triu_indices(m, k=2)
    rxs = r[i, 0] * r[j, 1] - r[i, 1] * r[j, 0]
    qp = p[j] - p[i]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (qp[:, 0] * r[j, 1] - qp[:, 1] * r[j, 0]) / rxs
        w = (qp[:, 0] * r[i, 1] - qp[:, 1] * r[i, 0]) / rxs
    hit = (np.abs(rxs) > 1e-15) & (t >= 0) & (t <= 1) & (w >= 0) & (w <= 1)
    if hit.any():
        k = int(np.argmax(hit))
        raise InputError("leg points", f"the polyline crosses itself (segments {i[k]} and {j[k]})")


# --------------------------------------------------------------------------------------------
# Presets
# --------------------------------------------------------------------------------------------
#: Standard rotating-leg test (Li 2013; thesis ch. 2): chord 7.62 cm, width 2.54 cm.
STANDARD_CHORD = 7.62 * CM
STANDARD_WIDTH = 2.54 * CM
LEG_SHAPES = ("flat", "c", "reverse-c", "foot")


def flat_leg(length: float = STANDARD_CHORD, width: float = STANDARD_WIDTH, n: int = 100) -> ArcLeg:
    return ArcLeg(width, n, length, 0.0, "flat")


def c_leg(length: float = STANDARD_CHORD, width: float = STANDARD_WIDTH, n: int = 100) -> ArcLeg:
    return ArcLeg(width, n, length, 1.0, "c")


def reverse_c_leg(length: float = STANDARD_CHORD, width: float = STANDARD_WIDTH, n: int = 100) -> ArcLeg:
    return ArcLeg(width, n, length, -1.0, "reverse-c")


def foot(length: float = 25.0 * CM, width: float = 8.5 * CM, n: int = 100) -> ArcLeg:
    """Human-sized foot (thesis 2.4): a flat plate pointing forward from the ankle (the
    rotation axis), so theta is the plantar-flexion angle from horizontal."""
    return ArcLeg(width, n, length, 0.0, "foot", direction=math.pi / 2)


def make_leg(shape: str, length: float | None = None, width: float | None = None, n: int = 100,
             curvature: float | None = None) -> Leg:
    """A preset leg by name; ``curvature`` overrides the shape's (arc legs)."""
    if shape not in LEG_SHAPES:
        raise InputError("leg", f"unknown leg {shape!r}; allowed: {', '.join(LEG_SHAPES)}")
    if shape == "foot":
        leg = foot(length if length is not None else 25 * CM,
                   width if width is not None else 8.5 * CM, n)
    else:
        leg = {"flat": flat_leg, "c": c_leg, "reverse-c": reverse_c_leg}[shape](
            length if length is not None else STANDARD_CHORD,
            width if width is not None else STANDARD_WIDTH, n)
    if curvature is not None:
        leg = ArcLeg(leg.width, leg.n_elements, leg.chord, curvature,
                     shape if curvature == leg.curvature else f"arc k={curvature:g}", leg.direction)
    return leg


def read_leg_csv(path: str | Path, width: float = STANDARD_WIDTH, n: int = 100) -> PolylineLeg:
    """Read a polyline leg from CSV with columns ``x_cm,z_cm`` (or ``x_m,z_m``): body-frame
    points from the hip (origin) to the tip, the leg hanging down at theta = 0."""
    path = Path(path)
    if not path.is_file():
        raise InputError("leg-file", f"file not found: {path}")
    with open_text(path, "leg-file") as fh:
        reader = csv.DictReader(fh)
        cols = reader.fieldnames or []
        if {"x_cm", "z_cm"} <= set(cols):
            scale, cx, cz = CM, "x_cm", "z_cm"
        elif {"x_m", "z_m"} <= set(cols):
            scale, cx, cz = 1.0, "x_m", "z_m"
        else:
            raise InputError("leg-file", f"{path}: need columns x_cm,z_cm (or x_m,z_m); got {cols}")
        pts = []
        for lineno, row in enumerate(reader, start=2):
            try:
                pts.append((float(row[cx]) * scale, float(row[cz]) * scale))
            except (TypeError, ValueError):
                raise InputError("leg-file", f"{path} line {lineno}: non-numeric value {row}") from None
    if len(pts) < 2:
        raise InputError("leg-file", f"{path}: need at least 2 points, got {len(pts)}")
    try:
        return PolylineLeg(width, n, np.array(pts), name=path.stem)
    except InputError as e:
        raise InputError("leg-file", f"{path}: {e}") from None
