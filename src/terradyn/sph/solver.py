"""The SPH solver: particle sets, the time loop, force recording, checkpoints.

A :class:`Scene` holds the particles (granular bed, fixed walls, optional rigid leg with its
trajectory); :class:`Solver` advances it with the compiled kernels of
:mod:`terradyn.sph.kernels` (symplectic Euler; time step from the CFL condition
dt = cfl * h / (c + v_max), c the P-wave speed, cfl = 0.2 after Bui et al. 2008).
"""
from __future__ import annotations

import hashlib
import json
import math
import os
import uuid
import zipfile
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from ..errors import InputError, in_range, integer, positive
from ..motion import Trajectory
from ..units import G
from . import kernels as K
from .materials import GranularMaterial


#: SPHConfig.backend values.
BACKENDS = ("cpu", "gpu", "auto")
#: SPHConfig.boundary values: "resolved" (the leg's own thickness, material on its two sides
#: kept apart, a contact guard at ``contact_gap`` dx, default 1/4) or "guard" (the model
#: before issue 17: no side test, grains held max(dx/4, h - t/2) off the surface).
BOUNDARIES = ("resolved", "guard")
#: Solver arrays that the GPU backend keeps on the device between steps: on that backend they
#: are detached from the solver while the device holds newer data, and reading one copies the
#: whole state back (see :meth:`Solver.__getattr__`).
DEVICE_OWNED = ("x", "z", "vx", "vz", "rho", "sxx", "szz", "sxz", "syy", "gvx", "gvz", "acc_x",
                "acc_z", "nox", "noz", "kind", "fleg", "bad", "sidx", "cell_start", "cell_index")


def gpu_available() -> bool:
    """Whether Numba sees a usable CUDA GPU (True under NUMBA_ENABLE_CUDASIM=1). Imports
    numba.cuda, so it is called only when a GPU backend may be wanted."""
    try:
        from numba import cuda
    except Exception:  # noqa: BLE001 - no numba.cuda at all: no GPU
        return False
    try:
        return bool(cuda.is_available())
    except Exception:  # noqa: BLE001 - a broken CUDA install counts as no GPU
        return False


def resolve_backend(name: str) -> str:
    """"cpu" or "gpu" for a :attr:`SPHConfig.backend` value."""
    if name == "cpu":
        return "cpu"
    ok = gpu_available()
    if name == "gpu" and not ok:
        raise InputError("backend", "no CUDA GPU available: use backend='cpu' (a GPU run needs "
                                    "an NVIDIA GPU and the 'gpu' extra: pip install "
                                    "'terradyn[gpu]')")
    return "gpu" if ok else "cpu"


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
    ``gpu`` extra are needed) or "auto" (the GPU when one is usable, else the CPU)."""

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
        if self.backend not in BACKENDS:
            raise InputError("backend", f"must be one of {', '.join(map(repr, BACKENDS))}, "
                                        f"got {self.backend!r}")

    @property
    def h(self) -> float:
        return self.hdx * self.dx


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


class Solver:
    """Advances a :class:`Scene`. ``step()`` one step; ``run(t_end)`` many, recording the
    force on the leg each step. The kernels run on the backend that ``config.backend`` names
    (:class:`CPUBackend`, or :class:`terradyn.sph.gpu.GPUBackend`, which keeps the particles
    on the GPU; its arrays here are brought up to date when read, see :meth:`sync_to_host`)."""

    def __init__(self, scene: Scene):
        self.scene = scene
        p = scene.particles
        cfg = scene.config
        mat = scene.material
        n = len(p)
        self.n = n
        self.kind = np.ascontiguousarray(p.kind, dtype=np.int8)
        self.mass = np.ascontiguousarray(p.mass, dtype=np.float64)
        for name in Particles.STATE:
            setattr(self, name, np.ascontiguousarray(getattr(p, name), dtype=np.float64).copy())
        self.gvx = np.zeros(n)
        self.gvz = np.zeros(n)
        self.acc_x = np.zeros(n)
        self.acc_z = np.zeros(n)
        self.nox = np.zeros(n)
        self.noz = np.zeros(n)
        self.dcl = np.zeros(n)
        self.sidx = np.flatnonzero(self.kind == K.SOIL).astype(np.int64)
        self.widx = np.flatnonzero(self.kind == K.WALL).astype(np.int64)
        self.lidx = np.flatnonzero(self.kind == K.LEG).astype(np.int64)
        if scene.leg is not None:
            if len(self.lidx) != len(scene.leg.bx):
                raise InputError("scene", "leg particle count does not match the rigid body")
            self.dcl[self.lidx] = scene.leg.dcl
        self.fleg = np.zeros((n, 3))
        self._srt = np.zeros((11, n))
        self._srtk = np.zeros((3, n))
        self.guard = np.zeros(n)
        self.half_t = 0.0
        if scene.leg is not None:
            self.guard[self.lidx] = scene.leg.guard
            self.half_t = 0.5 * scene.leg.thickness
        # Granular particles are kept `gap` off the leg's surface. "guard" (the old model):
        # at least dx/4, and far enough that particles on the two sides of a leg thinner than
        # the kernel support (2h) never interact through it. "resolved": the two sides are
        # kept apart by the side test of kernels._side_one instead, and the guard is only a
        # last-resort contact at contact_gap dx (default 1/4).
        if cfg.boundary == "guard":
            self.gap = (max(0.25 * cfg.dx, cfg.h - self.half_t) if cfg.contact_gap is None
                        else cfg.contact_gap * cfg.dx)
        else:
            self.gap = (0.25 if cfg.contact_gap is None else cfg.contact_gap) * cfg.dx
        self.sides = scene.leg is not None and cfg.boundary == "resolved"
        if self.sides and scene.leg.centre is None:
            raise InputError("scene", "the resolved boundary needs the leg's centre line "
                                      "(RigidBody.centre)")
        # pairs that may cross the leg: both particles within a support of its centre line
        self.side_reach = 2.0 * cfg.h + self.half_t
        self.bad = np.zeros(n, np.int8)
        # the container: granular particles that leave it (thrown over a wall) are dropped
        if len(self.widx):
            wx, wz = self.x[self.widx], self.z[self.widx]
            self._box = (wx.min(), wx.max(), wz.min())
        else:
            self._box = None
        self.lost = 0
        self.h = cfg.h
        self.c0 = mat.sound_speed
        vmax = self._max_leg_speed()
        self.dt = cfg.cfl * self.h / (self.c0 + vmax)
        self.vmax_allowed = self.c0  # a granular particle faster than sound: unstable
        self.t = 0.0
        self.step_count = 0
        self._grid()
        st = cfg.settle_time
        self.settle_time = st if st is not None else 15.0 * scene.depth_scale / self.c0
        self.settle_damping = 2.0 * self.c0 / max(scene.depth_scale, 1e-6)
        if cfg.threads:
            import numba

            numba.set_num_threads(int(cfg.threads))
        self._held = None
        self.backend_name = resolve_backend(cfg.backend)
        if self.backend_name == "gpu":
            from .gpu import GPUBackend

            self._backend = GPUBackend(self)
            self._detach()
        else:
            self._backend = CPUBackend(self)

    # ---------------------------------------------------------------------------------- setup
    def _max_leg_speed(self) -> float:
        leg = self.scene.leg
        if leg is None:
            return 0.0
        tr = leg.trajectory
        r = float(np.hypot(leg.bx, leg.bz).max())
        return float(np.max(np.hypot(tr.hip_vx, tr.hip_vz) + np.abs(tr.angular_velocity) * r))

    def _grid(self):
        cell = (2.0 + K.SKIN) * self.h / K.REACH  # cells reach the Verlet-list radius
        xs = [self.x.min(), self.x.max()]
        zs = [self.z.min(), self.z.max()]
        leg = self.scene.leg
        if leg is not None:
            tr = leg.trajectory
            r = float(np.hypot(leg.bx, leg.bz).max())
            xs += [tr.hip_x.min() - r, tr.hip_x.max() + r]
            zs += [tr.hip_z.min() - r, tr.hip_z.max() + r]
        self.xmin = min(xs) - 2 * cell
        self.zmin = min(zs) - 2 * cell
        self.ncx = int(math.ceil((max(xs) + 2 * cell - self.xmin) / cell))
        self.ncz = int(math.ceil((max(zs) + 2 * cell - self.zmin) / cell))
        self.inv_cell = 1.0 / cell
        self.cell_start = np.zeros(self.ncx * self.ncz + 1, np.int64)
        self.cell_index = np.zeros(self.n, np.int64)

    # ----------------------------------------------------------------------------------- step
    def step(self):
        """One time step; returns (Fx, Fz, torque) on the leg per unit depth (N/m, N) at the
        start of the step."""
        return tuple(self._block(1)[1][0].tolist())

    def advance(self, nsteps: int):
        """``nsteps`` time steps. Returns (t (nsteps,), forces (nsteps, 3)): the solver time
        at the start of each step and the force on the leg then, (Fx, Fz, torque) per unit
        depth (N/m, N), zero without a leg. Raises :class:`SPHInstabilityError` at the step
        where a particle went unstable. The CPU backend runs the steps in blocks without
        returning to Python (blocks end where grains thrown out of the container are
        dropped, every 50 steps): much faster than calling :meth:`step` in a loop for small
        beds."""
        nsteps = integer("nsteps", nsteps, 1)
        parts = []
        done = 0
        while done < nsteps:
            parts.append(self._block(nsteps - done))
            done += len(parts[-1][0])
        if len(parts) == 1:
            return parts[0]
        return (np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts]))

    def _block(self, n: int):
        """Up to ``n`` steps in one backend call, ending at the next drop of lost grains."""
        if self._box is not None:
            n = min(n, 50 - self.step_count % 50)
        ts = np.empty(n)
        t = self.t
        for i in range(n):  # the same sums as stepping one by one
            ts[i] = t
            t += self.dt
        settling = ts < self.settle_time
        dampings = np.where(settling, self.settle_damping, 0.0)
        leg = self.scene.leg
        if leg is None:
            poses = np.zeros((n, 9))
        else:
            poses = leg.poses(leg.t0 + np.maximum(ts - self.settle_time, 0.0))
            poses[settling, 2:6] = 0.0  # the leg waits at its start pose
            poses[settling, 7:] = 0.0
        forces = np.zeros((n, 3))
        done, nbad = self._backend.steps(poses, dampings, forces)
        self.t = ts[done] if done < n else t
        self.step_count += done
        if nbad:
            i = int(np.argmax(self.bad))  # on the GPU backend: copies the state back
            finite = np.isfinite([self.x[i], self.z[i], self.sxx[i], self.szz[i], self.rho[i]]).all()
            reason = (f"speed {math.hypot(self.vx[i], self.vz[i]):.3g} m/s exceeds the sound speed "
                      f"{self.c0:.3g} m/s" if finite else "non-finite position, density or stress")
            raise SPHInstabilityError(self.step_count, self.t, i, (self.x[i], self.z[i]), reason)
        if self._box is not None and self.step_count % 50 == 0:
            self._drop_lost()
        return ts[:done], forces[:done]

    def _drop_lost(self):
        """Park granular particles that left the container far away as kind LOST."""
        self.lost += self._backend.drop_lost(self._box)

    # ------------------------------------------------------------------ host/device state
    def _detach(self) -> None:
        """GPU backend: the device now holds the newer state; take the host copies out of the
        instance so that reading one goes through :meth:`__getattr__`."""
        d = self.__dict__
        self._held = {k: d.pop(k) for k in DEVICE_OWNED}

    def __getattr__(self, name):
        # Reached only when normal lookup fails: on the GPU backend, for the detached arrays.
        d = self.__dict__
        held = d.get("_held")
        if held is not None and name in DEVICE_OWNED:
            self.sync_to_host()
            return d[name]
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    def sync_to_host(self) -> None:
        """Bring the host arrays up to date (GPU backend: copies the device state back; the
        next step copies the host arrays, edits included, to the device). No-op on the CPU."""
        d = self.__dict__
        held = d.get("_held")
        if held is None:
            return
        self._backend.sync_to_host(held)
        d.update(held)
        d["_held"] = None

    # ------------------------------------------------------------------------------ snapshots
    def snapshot(self) -> dict:
        """Granular particles now: x, z (m), vx, vz (m/s), pressure (Pa, -trace/3)."""
        s = self.sidx
        return {"time": self.t, "x": self.x[s].copy(), "z": self.z[s].copy(),
                "vx": self.vx[s].copy(), "vz": self.vz[s].copy(),
                "pressure": -(self.sxx[s] + self.szz[s] + self.syy[s]) / 3.0}

    def stress(self) -> dict:
        s = self.sidx
        return {"x": self.x[s].copy(), "z": self.z[s].copy(), "sxx": self.sxx[s].copy(),
                "szz": self.szz[s].copy(), "sxz": self.sxz[s].copy(), "syy": self.syy[s].copy()}

    # ---------------------------------------------------------------------------- checkpoints
    def state_dict(self) -> dict:
        """Everything a later step reads: the particle state, the kinds (grains dropped as
        lost), the counters and, on the CPU backend, its neighbour search state (the cell
        order, Verlet lists and positions of the last list build, as ``cpu_*``), so that a
        run resumed from it on the CPU is bit-identical to one that was never stopped."""
        d = {name: getattr(self, name) for name in Particles.STATE}
        d.update(t=np.array(self.t), step_count=np.array(self.step_count), kind=self.kind,
                 lost=np.array(self.lost))
        backend_state = getattr(self._backend, "state_dict", None)
        if backend_state is not None:
            d.update({f"{self._backend.name}_{k}": v for k, v in backend_state().items()})
        return d

    def load_state(self, d) -> None:
        """Restore :meth:`state_dict` (a dict or an opened .npz). Entries that an older
        checkpoint or the other backend did not write are left as they are (without the
        neighbour state the lists are rebuilt at the next step)."""
        keys = set(d.keys())
        for name in Particles.STATE:
            getattr(self, name)[:] = d[name]
        self.t = float(d["t"])
        self.step_count = int(d["step_count"])
        if "kind" in keys:
            self.kind[:] = d["kind"]
            self.sidx = np.flatnonzero(self.kind == K.SOIL).astype(np.int64)
        if "lost" in keys:
            self.lost = int(d["lost"])
        pre = f"{self._backend.name}_"
        own = {k[len(pre):]: d[k] for k in keys if k.startswith(pre)}
        if own and hasattr(self._backend, "load_state"):
            self._backend.load_state(own)


class CPUBackend:
    """The solver's arrays on the host, advanced by the multi-threaded CPU kernels of
    :mod:`terradyn.sph.kernels` (a block of steps per call: :func:`~.kernels.cpu_steps`)."""

    name = "cpu"

    def __init__(self, solver: Solver):
        self.s = s = solver
        n = solver.n
        hdx = solver.scene.config.hdx
        self.nb = K.neighbour_list(n, hdx)
        # every boundary particle (walls, then leg) in one kernel call
        self.bidx = np.concatenate([s.widx, s.lidx]).astype(np.int64)
        nbl = K.neighbour_list(max(len(self.bidx), 1), hdx)
        self.bj, self.bn = nbl[0], nbl[1]  # the boundary particles' Verlet lists
        self.xb = np.full(n, np.inf)  # positions at the last list build: none yet
        self.zb = np.full(n, np.inf)
        # the pair passes' buffer for the other particle of a pair, and their chunks
        self.buf = np.zeros((n, 5))
        self.cont = np.zeros((n, 3))
        self.bounds = np.zeros(K.MAX_CHUNKS + 1, np.int64)
        leg = s.scene.leg
        self.body = (np.ascontiguousarray(np.stack([leg.bx, leg.bz, leg.bnx, leg.bnz]),
                                          dtype=np.float64)
                     if leg is not None else np.zeros((4, 0)))
        mat = s.scene.material
        cfg = s.scene.config
        gx, gz = s.scene.gravity
        val = dict(h=s.h, xmin=s.xmin, zmin=s.zmin, inv_cell=s.inv_cell, gx=gx, gz=gz, dt=s.dt,
                   shear_mod=mat.shear_modulus, bulk_mod=mat.bulk_modulus,
                   alpha_phi=mat.alpha_phi, k_c=mat.k_c, rho_min=0.9 * mat.density,
                   rho_max=1.1 * mat.density, c0=s.c0, av_alpha=cfg.av_alpha,
                   av_beta=cfg.av_beta, half_t=s.half_t, gap=s.gap, max_push=0.1 * cfg.dx,
                   vmax_allowed=s.vmax_allowed, side_reach2=s.side_reach ** 2)
        self.fp = np.array([val[k] for k in K.FP], dtype=np.float64)
        ival = dict(ncx=s.ncx, ncz=s.ncz, noslip=int(bool(cfg.noslip)),
                    av_boundary=int(bool(cfg.av_boundary)), has_leg=int(leg is not None),
                    nchunk=1, builds=0, sides=int(s.sides))
        self.ip = np.array([ival[k] for k in K.IP], dtype=np.int64)
        if s.sides:
            self.cl = np.ascontiguousarray(leg.centre, dtype=np.float64)
            self.clbox = leg.side_box(s.side_reach)
        else:
            self.cl = np.zeros((2, 2))
            self.clbox = np.zeros(4)

    @property
    def builds(self) -> int:
        """Verlet-list builds so far."""
        return int(self.ip[K.IP.index("builds")])

    def steps(self, poses, dampings, forces):
        """Advance len(poses) steps (see :func:`~.kernels.cpu_steps`); returns (steps done,
        unstable particles)."""
        s = self.s
        done, nbad = K.cpu_steps(
            poses, dampings, forces, s.x, s.z, s.vx, s.vz, s.rho, s.sxx, s.szz, s.sxz, s.syy,
            s.gvx, s.gvz, s.acc_x, s.acc_z, s.nox, s.noz, s.dcl, s.guard, s.mass, s.kind, s.fleg,
            s.bad, s._srt, s._srtk, s.cell_start, s.cell_index, self.bidx, s.lidx, self.body,
            self.xb, self.zb, *self.nb, self.bj, self.bn, self.buf, self.cont, self.bounds,
            self.fp, self.ip, self.cl, self.clbox)
        return int(done), int(nbad)

    def state_dict(self) -> dict:
        """The neighbour search state that persists between steps (see
        :meth:`Solver.state_dict`): positions at the last list build, the cell order and
        pair chunks made then, the Verlet lists of pass 1 and of the boundary particles (the
        columns up to the longest list) and the counters. Pass 2's lists (nbj, nbw, nbn) and
        the scratch buffers are rewritten every step before they are read."""
        s = self.s
        vj, vn = self.nb[0], self.nb[1]
        m = int(max(vn.max(initial=0), 0))
        mb = int(max(self.bn.max(initial=0), 0))
        return {"xb": self.xb, "zb": self.zb, "cell_start": s.cell_start,
                "cell_index": s.cell_index, "bounds": self.bounds, "ip": self.ip,
                "vj": vj[:, :m], "vn": vn, "bj": self.bj[:, :mb], "bn": self.bn}

    def load_state(self, d) -> None:
        s = self.s
        self.xb[:] = d["xb"]
        self.zb[:] = d["zb"]
        s.cell_start[:] = d["cell_start"]
        s.cell_index[:] = d["cell_index"]
        self.bounds[:] = d["bounds"]
        for k in ("nchunk", "builds"):
            i = K.IP.index(k)
            self.ip[i] = d["ip"][i]
        vj = np.asarray(d["vj"])
        self.nb[0][:, :vj.shape[1]] = vj
        self.nb[1][:] = d["vn"]
        bj = np.asarray(d["bj"])
        self.bj[:, :bj.shape[1]] = bj
        self.bn[:] = d["bn"]

    def drop_lost(self, box) -> int:
        s = self.s
        x0, x1, z0 = box
        sidx = s.sidx
        out = (s.x[sidx] < x0) | (s.x[sidx] > x1) | (s.z[sidx] < z0)
        if not out.any():
            return 0
        ids = sidx[out]
        s.kind[ids] = K.LOST
        s.x[ids] = 1e3 + np.arange(len(ids))  # beyond every kernel support
        s.z[ids] = 1e3
        for a in (s.vx, s.vz, s.sxx, s.szz, s.sxz, s.syy):
            a[ids] = 0.0
        s.fleg[ids] = 0.0
        s.sidx = np.flatnonzero(s.kind == K.SOIL).astype(np.int64)
        return len(ids)

    def sync_to_host(self, arrays) -> None:
        pass


def scene_key(scene: Scene, extra: dict | None = None) -> str:
    """A hash of everything that defines a run (for checkpoints)."""
    h = hashlib.sha256()
    # the backend does not change the run: a checkpoint of one resumes on the other
    cfg = {k: v for k, v in asdict(scene.config).items() if k != "backend"}
    h.update(json.dumps({"config": cfg, "material": scene.material.describe(),
                         "meta": scene.meta, "extra": extra or {}}, sort_keys=True,
                        default=str).encode())
    p = scene.particles
    for a in (p.x, p.z, p.kind):
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()[:16]


@dataclass
class RunResult:
    """Per-step record after settling: time (s, solver time minus the settling time), forces
    on the leg Fx, Fz (N) and torque (N m) (already multiplied by the leg width), snapshots."""

    time: np.ndarray
    Fx: np.ndarray
    Fz: np.ndarray
    torque: np.ndarray
    snapshots: list
    steps: int
    dt: float
    wall_seconds: float
    particles: int
    #: None, or where a rerun resumed from its checkpoint: {"checkpoint": path, "step": step
    #: count, "time_s": solver time (settling included), "total_s": the run's end time}
    resumed_from: dict | None = None


def run(scene: Scene, duration: float, *, snapshot_times=(), checkpoint: str | Path | None = None,
        checkpoint_every: float = 60.0, progress: Callable[[float, float], None] | None = None,
        record: bool = True) -> RunResult:
    """Settle the scene, then advance it ``duration`` seconds of motion.

    Forces on the leg are recorded every step after settling. ``snapshot_times``: motion times
    (s) at which to keep particle snapshots. ``checkpoint``: a file; the state is written there
    every ``checkpoint_every`` wall-clock seconds and a rerun of the same scene resumes from it
    (bit-identical to a run never stopped, on the CPU backend; the result's ``resumed_from``
    says where), and it is removed at the end. A file there that is not a checkpoint of this
    run is never overwritten or removed: the run refuses to start (:class:`InputError` on
    ``checkpoint``). ``progress(done_s, total_s)`` is called every few hundred steps.
    """
    import time as _time

    duration = float(duration)
    if not (duration >= 0 and math.isfinite(duration)):
        raise InputError("duration", f"must be >= 0 s, got {duration!r}")
    snap_times = sorted(float(t) for t in snapshot_times)
    key = scene_key(scene, {"duration": duration, "snaps": snap_times})
    ck = Path(checkpoint) if checkpoint else None
    resume = check_checkpoint(ck, key)  # before any work: never take over a file not ours
    solver = Solver(scene)
    t_total = solver.settle_time + duration
    nsteps = int(math.ceil(t_total / solver.dt))
    width = scene.leg.width if scene.leg is not None else 1.0
    rec = np.zeros((nsteps + 1, 4))
    nrec = 0
    snaps: list = []
    resumed_from = None
    if resume:
        try:
            with np.load(ck, allow_pickle=False) as d:
                nrec = int(d["nrec"])
                rec[:nrec] = d["rec"][:nrec]
                solver.load_state(d)
            resumed_from = {"checkpoint": str(ck), "step": solver.step_count,
                            "time_s": solver.t, "total_s": t_total}
        except (OSError, KeyError, ValueError, EOFError, zipfile.BadZipFile):
            # this run's checkpoint but damaged (its key is readable, a part is not): start
            # afresh from a new solver, and overwrite it at the next checkpoint
            solver = Solver(scene)
            nrec = 0
    t0 = _time.perf_counter()
    last_ck = t0
    if progress is not None:
        progress(solver.t, t_total)  # the work starts (from the resume point, if resumed)
    si = sum(1 for t in snap_times if t < solver.t - solver.settle_time)
    while solver.step_count < nsteps:
        tm = solver.t - solver.settle_time
        while si < len(snap_times) and tm >= snap_times[si] - 0.5 * solver.dt:
            snaps.append(solver.snapshot() | {"time": tm})
            si += 1
        # a block of steps: up to the next snapshot, progress report or the end
        n = min(nsteps - solver.step_count, 200 - solver.step_count % 200)
        if si < len(snap_times):
            n = min(n, max(1, int((snap_times[si] - 0.5 * solver.dt - tm) / solver.dt)))
        ts, f = solver.advance(n)
        if record:
            keep = ts >= solver.settle_time
            k = int(keep.sum())
            rec[nrec:nrec + k, 0] = ts[keep] - solver.settle_time
            rec[nrec:nrec + k, 1:] = f[keep] * width
            nrec += k
        if progress is not None and solver.step_count % 200 == 0:
            progress(solver.t, t_total)
        if ck is not None and _time.perf_counter() - last_ck > checkpoint_every:
            if not ck.exists() or _checkpoint_key(ck) == key:
                _save_checkpoint(ck, solver, key, rec, nrec)
            else:  # another file appeared there during the run: leave it, stop checkpointing
                import warnings

                warnings.warn(f"checkpoint: {ck} was replaced by a file this run did not "
                              "write; it is left alone and the run no longer checkpoints",
                              RuntimeWarning, stacklevel=2)
                ck = None
            last_ck = _time.perf_counter()
    tm = solver.t - solver.settle_time
    while si < len(snap_times):
        snaps.append(solver.snapshot() | {"time": tm})
        si += 1
    if progress is not None:
        progress(t_total, t_total)
    if ck is not None and _checkpoint_key(ck) == key:
        ck.unlink(missing_ok=True)  # two runs of one scene may race to finish
    rec = rec[:nrec]
    res = RunResult(rec[:, 0], rec[:, 1], rec[:, 2], rec[:, 3], snaps, solver.step_count,
                    solver.dt, _time.perf_counter() - t0, solver.n, resumed_from)
    res.solver = solver
    res.lost = solver.lost
    return res


def _checkpoint_key(path: Path) -> str | None:
    """The run key stored in the checkpoint file ``path``; None if there is no readable
    terradyn checkpoint there (missing, not an .npz, truncated, no ``key`` entry)."""
    if not path.is_file():
        return None
    try:
        d = np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile):
        return None
    if not isinstance(d, np.lib.npyio.NpzFile):  # a .npy array
        return None
    try:
        with d:
            k = d["key"] if "key" in d.files else None
    except (OSError, KeyError, ValueError, EOFError, zipfile.BadZipFile):
        return None
    if k is None or k.ndim != 0 or k.dtype.kind != "U":
        return None
    return str(k)


def check_checkpoint(path: str | Path | None, key: str | None = None) -> bool:
    """Check a checkpoint path before a run; True if there is a checkpoint to resume from.

    A missing file is fine (its folder must be writable). An existing one must be a terradyn
    checkpoint, and with ``key`` one of this run: anything else (another file, a truncated
    copy, another run's checkpoint) is refused with :class:`InputError` on ``checkpoint``
    rather than overwritten and removed."""
    if path is None:
        return False
    from ..io import check_writable

    path = Path(path)
    check_writable(path, "checkpoint")
    if not path.exists():
        return False
    got = _checkpoint_key(path)
    if got is None:
        raise InputError("checkpoint", f"{path} exists and is not a terradyn checkpoint: "
                                       "remove it or choose another path")
    if key is not None and got != key:
        raise InputError("checkpoint", f"{path} exists and is not a checkpoint of this run (it "
                                       "is of another scene, resolution or motion): remove it "
                                       "or choose another path")
    return True


def _save_checkpoint(path: Path, solver: Solver, key: str, rec, nrec) -> None:
    """Write the state next to ``path`` under a name of this process's own, then rename it
    over ``path`` (atomic): a kill leaves the old checkpoint or the new one, never half of
    one, and two processes checkpointing the same scene never write into one file."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f"{path.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.tmp.npz")
    try:
        np.savez(tmp, key=np.array(key), nrec=np.array(nrec), rec=rec[:nrec],
                 **solver.state_dict())
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def lowpass(t: np.ndarray, y: np.ndarray, cutoff_hz: float, order: int = 4) -> np.ndarray:
    """Zero-phase Butterworth low-pass (scipy ``filtfilt``) of a uniformly sampled record."""
    from scipy.signal import butter, filtfilt

    if len(t) < 3 * (order + 1) + 1:
        return y
    fs = 1.0 / float(np.median(np.diff(t)))
    wn = min(cutoff_hz / (0.5 * fs), 0.99)
    b, a = butter(order, wn)
    return filtfilt(b, a, y)


def warmup() -> None:
    """Compile all kernels on a tiny scene."""
    from .scenes import bed_scene

    sc = bed_scene(width=0.03, depth=0.02, dx=5e-3, settle_time=0.0)
    s = Solver(sc)
    s.step()
