"""Rigid planar motions of a leg, as trajectories sampled in time.

World frame (SI): x forward, z up, the free surface of the bed at z = 0 (bed below). A leg's
body frame (see :mod:`terradyn.geometry`) is placed at the hip position and turned
**clockwise** by the leg angle theta: a body point s sits at ``hip + R(theta) s`` with
R(theta) = [[cos, sin], [-sin, cos]]. For a standard leg theta is the angle from the downward
vertical to the chord; theta < 0 (tip ahead of the hip, moving down) is intrusion, theta > 0
extraction (Li 2013; thesis ch. 2).

Velocities are exact rigid-body velocities, v = v_hip + omega x r, for the sampled motion:
analytic for :class:`Rotation`, the derivative of a cubic spline through the samples for
:class:`PlanarMotion` (or velocities the user gives).
"""
from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import InputError, open_text, finite, finite_array, integer, positive
from .units import CM, DEG


@dataclass(frozen=True, eq=False)
class Trajectory:
    """A sampled rigid motion. All arrays (S,): time s, hip_x/hip_z m, hip_vx/hip_vz m/s,
    angle rad (clockwise), angular_velocity rad/s. ``coord`` names the natural coordinate
    ("theta" for rotations, "time" otherwise)."""

    time: np.ndarray
    hip_x: np.ndarray
    hip_z: np.ndarray
    hip_vx: np.ndarray
    hip_vz: np.ndarray
    angle: np.ndarray
    angular_velocity: np.ndarray
    coord: str = "theta"

    def __len__(self) -> int:
        return len(self.time)

    def kernel_arrays(self, dtype=np.float64) -> tuple[np.ndarray, ...]:
        """(hip_x, hip_z, hip_vx, hip_vz, cos a, sin a, cos 2a, sin 2a, angular_velocity) as
        contiguous arrays of ``dtype``, computed once per trajectory and dtype."""
        cache = self.__dict__.setdefault("_kernel_cache", {})
        key = np.dtype(dtype).str
        if key not in cache:
            a = self.angle
            cache[key] = tuple(np.ascontiguousarray(x, dtype=dtype) for x in (
                self.hip_x, self.hip_z, self.hip_vx, self.hip_vz, np.cos(a), np.sin(a),
                np.cos(2 * a), np.sin(2 * a), self.angular_velocity))
        return cache[key]

    @property
    def hip_at_rest(self) -> bool:
        """True when the hip never moves (a rotation about a fixed axis); cached."""
        v = self.__dict__.get("_hip_at_rest")
        if v is None:
            v = self.__dict__["_hip_at_rest"] = not (np.any(self.hip_vx) or np.any(self.hip_vz))
        return v

    def kernel_rotation_table(self, dtype=np.float64) -> np.ndarray:
        """(8, S) array: hip z, cos/sin of a, 2a, 3a, angular velocity (cached)."""
        cache = self.__dict__.setdefault("_kernel_cache", {})
        key = "rot" + np.dtype(dtype).str
        if key not in cache:
            a = self.angle
            cache[key] = np.ascontiguousarray(np.stack([
                self.hip_z, np.cos(a), np.sin(a), np.cos(2 * a), np.sin(2 * a), np.cos(3 * a),
                np.sin(3 * a), self.angular_velocity]), dtype=dtype)
        return cache[key]


@dataclass(frozen=True)
class Rotation:
    """Constant-speed rotation about a fixed hip axis at height ``hip_height`` (m) above the
    surface, from ``theta_start`` to ``theta_end`` (rad) in ``n_theta`` samples, at
    ``omega`` (rad/s, > 0; the leg turns from start to end)."""

    omega: float = 0.2
    hip_height: float = 2.0 * CM
    theta_start: float = -135 * DEG
    theta_end: float = 135 * DEG
    n_theta: int = 271

    def __post_init__(self):
        positive("omega", self.omega, "rad/s")
        finite("hip-height", self.hip_height, "m")
        finite("theta-start", self.theta_start, "rad")
        finite("theta-end", self.theta_end, "rad")
        integer("n-theta", self.n_theta, 2)
        if self.theta_end == self.theta_start:
            raise InputError("theta range", "theta-start and theta-end are equal: empty range")

    @property
    def theta(self) -> np.ndarray:
        return np.linspace(self.theta_start, self.theta_end, self.n_theta)

    def trajectory(self) -> Trajectory:
        th = self.theta
        direction = 1.0 if self.theta_end > self.theta_start else -1.0
        w = direction * self.omega
        n = len(th)
        zeros = np.zeros(n)
        return Trajectory(time=(th - th[0]) / w, hip_x=zeros, hip_z=np.full(n, self.hip_height),
                          hip_vx=zeros, hip_vz=zeros, angle=th, angular_velocity=np.full(n, w),
                          coord="theta")

    def describe(self) -> dict:
        return {"kind": "rotation", "omega_rad_per_s": self.omega, "hip_height_m": self.hip_height,
                "theta_start_deg": self.theta_start / DEG, "theta_end_deg": self.theta_end / DEG,
                "n_theta": self.n_theta}


def check_time(time) -> np.ndarray:
    """Sample times (S,) s: finite, at least 2, strictly increasing; else InputError."""
    t = finite_array("time", time, ndim=1)
    if len(t) < 2:
        raise InputError("time", "need at least 2 samples")
    if (np.diff(t) <= 0).any():
        i = int(np.argmax(np.diff(t) <= 0))
        raise InputError("time", f"must be strictly increasing (sample {i + 1} is not after sample {i})")
    return t


def spline_derivative(t: np.ndarray, y: np.ndarray) -> np.ndarray:
    """d y / d t at the samples ``t`` (strictly increasing) of samples ``y`` (S, ...): the
    derivative of a cubic spline along axis 0; two samples: their constant slope."""
    if len(t) < 3:
        return np.broadcast_to((y[-1] - y[0]) / (t[-1] - t[0]), np.shape(y)).copy()
    from scipy.interpolate import CubicSpline

    return CubicSpline(t, y, axis=0)(t, 1)


def read_columns(path: str | Path, field: str, need: tuple[str, ...]) -> np.ndarray:
    """Rows (k, len(need)) of the named numeric columns of a CSV file; InputError naming
    ``field`` for a missing file or column, a non-numeric or non-finite value, or no rows."""
    path = Path(path)
    if not path.is_file():
        raise InputError(field, f"file not found: {path}")
    with open_text(path, field) as fh:
        reader = csv.DictReader(fh)
        missing = [c for c in need if c not in (reader.fieldnames or [])]
        if missing:
            raise InputError(field, f"{path}: missing column(s) {', '.join(missing)}; expected {','.join(need)}")
        rows = []
        for lineno, row in enumerate(reader, start=2):
            try:
                vals = [float(row[c]) for c in need]
            except (TypeError, ValueError):
                raise InputError(field, f"{path} line {lineno}: non-numeric value") from None
            if not all(np.isfinite(vals)):
                raise InputError(field, f"{path} line {lineno}: non-finite value")
            rows.append(vals)
    if not rows:
        raise InputError(field, f"{path}: no data rows")
    return np.array(rows)


@dataclass(frozen=True, eq=False)
class PlanarMotion:
    """A general planar rigid motion given as time series (SI): time (S,) s strictly
    increasing; hip_x, hip_z (S,) m; angle (S,) rad clockwise. Optional exact velocities;
    otherwise they are the derivatives of cubic splines through the samples."""

    time: np.ndarray
    hip_x: np.ndarray
    hip_z: np.ndarray
    angle: np.ndarray
    hip_vx: np.ndarray | None = None
    hip_vz: np.ndarray | None = None
    angular_velocity: np.ndarray | None = None

    def __post_init__(self):
        t = check_time(self.time)
        object.__setattr__(self, "time", t)
        for name in ("hip_x", "hip_z", "angle", "hip_vx", "hip_vz", "angular_velocity"):
            v = getattr(self, name)
            if v is None:
                continue
            a = finite_array(name, v, ndim=1)
            if a.shape != t.shape:
                raise InputError(name, f"has {len(a)} samples, time has {len(t)}")
            object.__setattr__(self, name, a)

    def trajectory(self) -> Trajectory:
        t = self.time
        d = lambda y: spline_derivative(t, y)  # noqa: E731
        vx = self.hip_vx if self.hip_vx is not None else d(self.hip_x)
        vz = self.hip_vz if self.hip_vz is not None else d(self.hip_z)
        w = self.angular_velocity if self.angular_velocity is not None else d(self.angle)
        return Trajectory(t, self.hip_x, self.hip_z, vx, vz, self.angle, w, coord="time")

    def describe(self) -> dict:
        return {"kind": "planar", "samples": len(self.time),
                "t_start_s": float(self.time[0]), "t_end_s": float(self.time[-1])}

    def mirrored(self) -> "PlanarMotion":
        """The mirror image x -> -x (hip x and the sense of rotation flip)."""
        neg = lambda a: None if a is None else -a  # noqa: E731
        return PlanarMotion(self.time, -self.hip_x, self.hip_z, -self.angle, neg(self.hip_vx),
                            self.hip_vz, neg(self.angular_velocity))


def read_motion_csv(path: str | Path) -> PlanarMotion:
    """Read a planar motion CSV with columns time_s, hip_x_cm, hip_z_cm, angle_deg."""
    path = Path(path)
    a = read_columns(path, "motion-file", ("time_s", "hip_x_cm", "hip_z_cm", "angle_deg"))
    try:
        return PlanarMotion(a[:, 0], a[:, 1] * CM, a[:, 2] * CM, a[:, 3] * DEG)
    except InputError as e:
        raise InputError("motion-file", f"{path}: {e}") from None


def standard_rotation(n_theta: int = 271, omega: float = 0.2) -> Rotation:
    """The brief's standard test: h = 2 cm, theta -135..135 deg, omega = 0.2 rad/s."""
    return Rotation(omega=omega, hip_height=2.0 * CM, theta_start=-135 * DEG,
                    theta_end=135 * DEG, n_theta=n_theta)


def foot_rotation(max_deg: float = 3.0, n_theta: int = 61, omega: float = 0.2) -> Rotation:
    """Foot test (thesis 2.4): ankle at the surface, rotation from 0 to ``max_deg``."""
    return Rotation(omega=omega, hip_height=0.0, theta_start=0.0, theta_end=max_deg * DEG,
                    n_theta=n_theta)


