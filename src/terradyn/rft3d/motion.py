"""Rigid 6-DoF motions of a 3D body, sampled in time, with exact velocities.

A motion gives, per sample, the time (s), the position X (m) of the body-frame origin, the
unit quaternion q = (w, x, y, z) (body to world), the velocity V (m/s) of the origin and the
angular velocity W (rad/s), both in the world frame (z up). Velocities are exact for the
sampled motion: analytic for :class:`AxisRotation`, the derivatives of cubic splines through
the samples for :class:`RigidMotion` (unless the user gives them): V = dX/dt and
W = 2 vec(dq/dt q*) from the spline of the quaternion components.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError, finite, finite_array, integer, positive
from ..motion import check_time, read_columns, spline_derivative
from ..units import CM, DEG
from .engine import check_quaternions


def quat_multiply(a, b) -> np.ndarray:
    """Hamilton product a b of quaternions (..., 4), (w, x, y, z)."""
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack([aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw], -1)


def axis_angle_quat(axis, angle) -> np.ndarray:
    """Unit quaternions (..., 4) of rotations by ``angle`` (rad, (...)) about unit ``axis`` (3,)."""
    axis = np.asarray(axis, float)
    h = 0.5 * np.asarray(angle, float)[..., None]
    return np.concatenate([np.cos(h), np.sin(h) * axis], -1)


@dataclass(frozen=True, eq=False)
class Poses:
    """A sampled 6-DoF trajectory: time (S,) s, position (S, 3) m, quaternion (S, 4),
    velocity (S, 3) m/s, angular_velocity (S, 3) rad/s; optional ``angle`` (S,) rad for
    rotations (the natural coordinate of a rotation test)."""

    time: np.ndarray
    position: np.ndarray
    quaternion: np.ndarray
    velocity: np.ndarray
    angular_velocity: np.ndarray
    angle: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.time)


@dataclass(frozen=True, eq=False)
class RigidMotion:
    """Any rigid 6-DoF motion from samples: time (S,) s, position (S, 3) m, quaternion (S, 4)
    unit (w, x, y, z); optional exact velocity (S, 3) m/s and angular_velocity (S, 3) rad/s
    (world frame), otherwise derivatives of cubic splines through the samples."""

    time: np.ndarray
    position: np.ndarray
    quaternion: np.ndarray
    velocity: np.ndarray | None = None
    angular_velocity: np.ndarray | None = None

    def __post_init__(self):
        t = check_time(self.time)
        object.__setattr__(self, "time", t)
        q = check_quaternions(self.quaternion)
        if q.shape != (len(t), 4):
            raise InputError("quaternion", f"must be ({len(t)}, 4) (w, x, y, z), got shape {q.shape}")
        # q and -q are the same rotation: keep neighbours in one hemisphere so splines are smooth
        sign = np.cumprod(np.where(np.einsum("ij,ij->i", q[1:], q[:-1]) < 0, -1.0, 1.0))
        q = q.copy()
        q[1:] *= sign[:, None]
        object.__setattr__(self, "quaternion", q)
        for name in ("position", "velocity", "angular_velocity"):
            v = getattr(self, name)
            if v is None:
                continue
            a = finite_array(name, v, ndim=2)
            if a.shape != (len(t), 3):
                raise InputError(name, f"must be ({len(t)}, 3), got shape {a.shape}")
            object.__setattr__(self, name, a)

    def poses(self) -> Poses:
        t = self.time
        V = self.velocity if self.velocity is not None else spline_derivative(t, self.position)
        if self.angular_velocity is not None:
            W = self.angular_velocity
        else:
            q = self.quaternion
            qd = spline_derivative(t, q)
            conj = q * np.array([1.0, -1, -1, -1])
            W = 2 * quat_multiply(qd, conj)[:, 1:]
        return Poses(t, self.position, self.quaternion, V, W)

    def describe(self) -> dict:
        return {"kind": "rigid-6dof", "samples": len(self.time), "t_start_s": float(self.time[0]),
                "t_end_s": float(self.time[-1])}


@dataclass(frozen=True, eq=False)
class AxisRotation:
    """Rotation about any world axis through a point at constant rate: the body starts at
    ``position0`` (m) with orientation ``quaternion0`` and turns by angle a from ``angle_start``
    to ``angle_end`` (rad) about ``axis`` (3,) through ``center`` (3,) m at ``omega`` (rad/s,
    > 0; the angle grows in time), ``n`` samples. Velocities are exact."""

    axis: tuple = (0.0, 1.0, 0.0)
    center: tuple = (0.0, 0.0, 0.0)
    omega: float = 0.2
    angle_start: float = 0.0
    angle_end: float = np.pi
    n: int = 181
    position0: tuple = (0.0, 0.0, 0.0)
    quaternion0: tuple = (1.0, 0.0, 0.0, 0.0)

    def __post_init__(self):
        ax = finite_array("axis", self.axis, ndim=1)
        if ax.shape != (3,) or np.linalg.norm(ax) == 0:
            raise InputError("axis", f"must be a non-zero 3-vector, got {self.axis!r}")
        object.__setattr__(self, "axis", tuple(ax / np.linalg.norm(ax)))
        c = finite_array("center", self.center, ndim=1)
        if c.shape != (3,):
            raise InputError("center", "must be a 3-vector in m")
        positive("omega", self.omega, "rad/s")
        a0 = finite("angle_start", self.angle_start, "rad")
        a1 = finite("angle_end", self.angle_end, "rad")
        if a1 <= a0:
            raise InputError("angle_end", f"must be > angle_start ({a0:g} rad), got {a1:g}")
        integer("n", self.n, 2)
        check_quaternions(self.quaternion0, "quaternion0")

    def poses(self) -> Poses:
        a = np.linspace(self.angle_start, self.angle_end, self.n)
        t = (a - self.angle_start) / self.omega
        ax = np.asarray(self.axis)
        c = np.asarray(self.center, float)
        qa = axis_angle_quat(ax, a)
        q = quat_multiply(qa, np.asarray(self.quaternion0, float))
        from .engine import rotation_matrices

        X = c + np.einsum("sij,j->si", rotation_matrices(qa), np.asarray(self.position0, float) - c)
        W = np.broadcast_to(self.omega * ax, X.shape).copy()
        V = np.cross(W, X - c)
        return Poses(t, X, q, V, W, angle=a)

    def describe(self) -> dict:
        return {"kind": "axis-rotation", "axis": list(self.axis), "center_m": list(self.center),
                "omega_rad_per_s": self.omega, "angle_start_deg": self.angle_start / DEG,
                "angle_end_deg": self.angle_end / DEG, "n": self.n,
                "position0_m": list(self.position0), "quaternion0": list(self.quaternion0)}


def planar_poses(motion) -> Poses:
    """A 2D motion (:class:`terradyn.motion.Rotation` / ``PlanarMotion``) as 3D poses: the
    x-z plane is the plane of motion, the leg angle (clockwise in x-z) a rotation about +y."""
    tr = motion.trajectory()
    S = len(tr)
    X = np.column_stack([tr.hip_x, np.zeros(S), tr.hip_z])
    V = np.column_stack([tr.hip_vx, np.zeros(S), tr.hip_vz])
    W = np.column_stack([np.zeros(S), tr.angular_velocity, np.zeros(S)])
    q = axis_angle_quat([0.0, 1.0, 0.0], tr.angle)
    return Poses(tr.time, X, q, V, W, angle=tr.angle if tr.coord == "theta" else None)


@dataclass(frozen=True, eq=False)
class PlanarAs3D:
    """Wrapper: a 2D motion driving a 3D body (see :func:`planar_poses`)."""

    motion: object

    def poses(self) -> Poses:
        return planar_poses(self.motion)

    def describe(self) -> dict:
        return {"kind": "planar-as-3d", "planar": self.motion.describe()}


MOTION_COLUMNS = ("time_s", "x_cm", "y_cm", "z_cm", "qw", "qx", "qy", "qz")


def read_motion3d_csv(path: str | Path) -> RigidMotion:
    """Read a 6-DoF motion CSV with columns time_s, x_cm, y_cm, z_cm, qw, qx, qy, qz
    (position of the body-frame origin, unit quaternion body to world)."""
    path = Path(path)
    a = read_columns(path, "motion", MOTION_COLUMNS)
    if len(a) < 2:
        raise InputError("motion", f"{path}: need at least 2 data rows")
    try:
        return RigidMotion(a[:, 0], a[:, 1:4] * CM, a[:, 4:8])
    except InputError as e:
        raise InputError("motion", f"{path}: {e}") from None
