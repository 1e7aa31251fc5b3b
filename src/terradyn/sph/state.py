"""State and configuration types of the SPH model: particle kinds, the numerical config, the
particle sets, the rigid leg, the scene. Imports nothing else of :mod:`terradyn.sph`, so that
every other module (scenes, physics, backends, solver) can import it.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from ..errors import InputError, in_range, integer, positive
from ..motion import Trajectory
from ..units import G
from .materials import GranularMaterial

#: Particle kinds: granular, fixed wall, leg (moving rigid body), lost (left the container;
#: parked far away and ignored).
SOIL, WALL, LEG, LOST = 0, 1, 2, 3

#: SPHConfig.backend values.
BACKENDS = ("cpu", "gpu", "auto")
#: Allowed ``SPHConfig.bed_pad`` (m): the bed beyond the path of the leg or plate.
BED_PAD_RANGE = (0.01, 0.5)


def bed_pad_m(field: str, value_cm: float) -> float:
    """A bed pad given in cm at the edge (``field`` names it in errors), checked, in m."""
    lo, hi = BED_PAD_RANGE
    return in_range(field, value_cm, lo * 100, hi * 100, "cm") / 100
#: SPHConfig.boundary values: "resolved" (the leg's own thickness, material on its two sides
#: kept apart, a contact guard at ``contact_gap`` dx, default 1/4) or "guard" (the model
#: before issue 17: no side test, grains held max(dx/4, h - t/2) off the surface).
BOUNDARIES = ("resolved", "guard")

#: Columns of a pose row (:meth:`RigidBody.poses`, the ``poses`` of the backends' steps).
POSE = ("hip_x", "hip_z", "hip_vx", "hip_vz", "hip_ax", "hip_az", "angle", "omega", "alpha")
(POSE_HIP_X, POSE_HIP_Z, POSE_HIP_VX, POSE_HIP_VZ, POSE_HIP_AX, POSE_HIP_AZ, POSE_ANGLE,
 POSE_OMEGA, POSE_ALPHA) = range(len(POSE))
#: Rows of a leg's body array (4, n_leg) on the backends: the :class:`RigidBody` attributes
#: (body coordinates and outward normals).
BODY = ("bx", "bz", "bnx", "bnz")
BODY_BX, BODY_BZ, BODY_BNX, BODY_BNZ = range(len(BODY))


class SPHInstabilityError(RuntimeError):
    """The run went unstable: non-finite values or a particle faster than the sound speed."""

    def __init__(self, step: int, time: float, particle: int, position, reason: str):
        self.step, self.time, self.particle, self.position, self.reason = step, time, particle, position, reason
        super().__init__(f"SPH run unstable at step {step} (t = {time:.6g} s): particle {particle} "
                         f"at (x, z) = ({position[0]:.4g}, {position[1]:.4g}) m: {reason}. "
                         "Try a smaller --cfl, a finer resolution or a slower motion.")


@dataclass(frozen=True)
class SPHConfig:
    """Numerical parameters. dx: particle spacing (m); hdx: smoothing length / dx (Wendland C2,
    support 2h); cfl: Courant number; av_alpha, av_beta: Monaghan artificial viscosity (between granular particles; also on
    wall/leg pairs if av_boundary);
    wall_layers: layers of dummy particles; noslip: no-slip (True) or free-slip walls and leg;
    settle_time: damped settling before the motion starts (s; None: 15 bed-depth / sound-speed
    transits); lowpass_hz: optional zero-phase Butterworth low-pass of the recorded forces
    (None: raw); threads: CPU threads (None: Numba's default); backend: "cpu" (Numba,
    multi-threaded), "gpu" (Numba CUDA, :mod:`terradyn.sph.gpu`; an NVIDIA GPU and the
    ``gpu`` extra are needed) or "auto" (the GPU when one is usable, else the CPU);
    channel_width: side walls of a quasi-2D channel this far apart (m; None: plane strain
    without walls), each with Coulomb friction wall_friction (rad; None: the material's
    friction angle, walls as rough as the medium) pressed by the out-of-plane stress
    (:func:`terradyn.sph.physics._kick_one`); leg_friction: grain-leg friction angle (rad;
    None: a rough, no-slip leg, the default): Coulomb slip of the grains on the leg's surface
    (:func:`terradyn.sph.physics._leg_slip`); bed_pad: granular bed around the leg's path
    below the surface in the leg scenes (m; None: 6 cm, 3 cm with ``quick``; see "Bed size"
    in docs/sph.md)."""

    dx: float = 2.5e-3
    hdx: float = 1.3
    cfl: float = 0.2
    av_alpha: float = 0.1
    av_beta: float = 0.0
    av_boundary: bool = False
    wall_layers: int = 3
    noslip: bool = True
    settle_time: float | None = None
    lowpass_hz: float | None = None
    threads: int | None = None
    backend: str = "cpu"
    boundary: str = "resolved"
    contact_gap: float | None = None
    channel_width: float | None = None
    wall_friction: float | None = None
    bed_pad: float | None = None
    leg_friction: float | None = None

    def __post_init__(self):
        positive("dx", self.dx, "m")
        in_range("hdx", self.hdx, 1.0, 2.5)
        in_range("cfl", self.cfl, 1e-3, 0.5)
        in_range("av-alpha", self.av_alpha, 0.0, 5.0)
        in_range("av-beta", self.av_beta, 0.0, 5.0)
        integer("wall-layers", self.wall_layers, 2)
        if self.settle_time is not None:
            in_range("settle-time", self.settle_time, 0.0, 100.0, "s")
        if self.lowpass_hz is not None:
            positive("lowpass", self.lowpass_hz, "Hz")
        if self.boundary not in BOUNDARIES:
            raise InputError("boundary", f"must be one of {', '.join(map(repr, BOUNDARIES))}, "
                                         f"got {self.boundary!r}")
        if self.contact_gap is not None:
            in_range("contact-gap", self.contact_gap, 0.0, 1.0, "dx")
        if self.channel_width is not None:
            positive("channel-width", self.channel_width, "m")
        if self.wall_friction is not None:
            in_range("wall-friction", self.wall_friction, 0.0, math.radians(60.0), "rad")
        if self.bed_pad is not None:
            in_range("bed-pad", self.bed_pad, *BED_PAD_RANGE, "m")
        if self.leg_friction is not None:
            in_range("leg-friction", self.leg_friction, 0.0, math.radians(60.0), "rad")
            if not self.noslip:
                raise InputError("leg-friction", "is the friction of a no-slip leg's surface; "
                                 "with noslip off the leg is already frictionless")
        if self.backend not in BACKENDS:
            raise InputError("backend", f"must be one of {', '.join(map(repr, BACKENDS))}, "
                                        f"got {self.backend!r}")

    @property
    def h(self) -> float:
        return self.hdx * self.dx

    def run_items(self) -> dict:
        """The settings that define a run, for checkpoint keys: all but the backend (a
        checkpoint of one resumes on the other), and the side walls only where set (so
        checkpoints written before they existed still resume)."""
        d = asdict(self)
        d.pop("backend")
        for k in ("channel_width", "wall_friction", "bed_pad", "leg_friction"):
            if d[k] is None:
                d.pop(k)
        return d


@dataclass
class Particles:
    """Struct of arrays, (N,) each. kind: 0 granular, 1 wall, 2 leg."""

    x: np.ndarray
    z: np.ndarray
    kind: np.ndarray
    mass: np.ndarray
    rho: np.ndarray
    vx: np.ndarray = None
    vz: np.ndarray = None
    sxx: np.ndarray = None
    szz: np.ndarray = None
    sxz: np.ndarray = None
    syy: np.ndarray = None

    def __post_init__(self):
        n = len(self.x)
        for name in ("vx", "vz", "sxx", "szz", "sxz", "syy"):
            if getattr(self, name) is None:
                setattr(self, name, np.zeros(n))

    def __len__(self):
        return len(self.x)

    STATE = ("x", "z", "vx", "vz", "rho", "sxx", "szz", "sxz", "syy")


@dataclass
class RigidBody:
    """A rigid leg: body-frame particle coordinates (n,), body outward normals (n,), offset
    of each particle from the leg's centre line along its outward normal (n,); trajectory;
    ``t0``: trajectory time at solver time 0; ``width``: out-of-plane width (m) that turns
    per-unit-depth forces into newtons."""

    bx: np.ndarray
    bz: np.ndarray
    bnx: np.ndarray
    bnz: np.ndarray
    dcl: np.ndarray
    trajectory: Trajectory
    t0: float
    width: float
    thickness: float = 0.0
    guard: np.ndarray | None = None  # (n,) 1 where the penetration guard applies (not the tip)
    centre: np.ndarray | None = None  # (2, m) body-frame centre line, hip to tip (side test)

    def side_box(self, reach: float) -> np.ndarray:
        """(x0, x1, z0, z1): the centre line's body-frame bounding box grown by ``reach``."""
        c = self.centre
        return np.array([c[0].min() - reach, c[0].max() + reach, c[1].min() - reach,
                         c[1].max() + reach])

    def poses(self, t_traj) -> np.ndarray:
        """(n, 9) rows (hip_x, hip_z, hip_vx, hip_vz, hip_ax, hip_az, angle, omega, alpha) at
        the trajectory times ``t_traj`` (n,) (linear interpolation of the samples, clamped to
        the trajectory's ends; accelerations by differences)."""
        tab = self.__dict__.get("_tab")
        tr = self.trajectory
        tt = tr.time
        if tab is None:
            acc = [np.gradient(a, tt) if len(tt) > 2 else np.zeros_like(tt)
                   for a in (tr.hip_vx, tr.hip_vz, tr.angular_velocity)]
            tab = np.stack([tr.hip_x, tr.hip_z, tr.hip_vx, tr.hip_vz, acc[0], acc[1], tr.angle,
                            tr.angular_velocity, acc[2]])
            self.__dict__["_tab"] = tab
        t = np.clip(np.asarray(t_traj, dtype=float), tt[0], tt[-1])
        k = np.minimum(np.searchsorted(tt, t, side="right") - 1, len(tt) - 2)
        f = (t - tt[k]) / (tt[k + 1] - tt[k])
        return (tab[:, k] + f * (tab[:, k + 1] - tab[:, k])).T


@dataclass
class Scene:
    """Particles, material, numerical config, optional rigid leg; ``meta`` describes it."""

    particles: Particles
    material: GranularMaterial
    config: SPHConfig
    leg: RigidBody | None = None
    gravity: tuple[float, float] = (0.0, -G)
    meta: dict = field(default_factory=dict)
    depth_scale: float = 0.1  # a length for the settling time (bed depth), m
