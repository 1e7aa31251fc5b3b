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
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from ..errors import InputError, in_range, integer, positive
from ..motion import Trajectory
from ..units import G
from . import kernels as K
from .materials import GranularMaterial


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
    (None: raw)."""

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

    def pose(self, t_traj: float):
        """(hip_x, hip_z, hip_vx, hip_vz, hip_ax, hip_az, angle, omega, alpha) at trajectory
        time ``t_traj`` (linear interpolation of the samples; accelerations by differences)."""
        tab = self.__dict__.get("_tab")
        tr = self.trajectory
        tt = tr.time
        if tab is None:
            acc = [np.gradient(a, tt) if len(tt) > 2 else np.zeros_like(tt)
                   for a in (tr.hip_vx, tr.hip_vz, tr.angular_velocity)]
            tab = np.stack([tr.hip_x, tr.hip_z, tr.hip_vx, tr.hip_vz, acc[0], acc[1], tr.angle,
                            tr.angular_velocity, acc[2]])
            self.__dict__["_tab"] = tab
        t = min(max(t_traj, tt[0]), tt[-1])
        k = min(int(np.searchsorted(tt, t, side="right")) - 1, len(tt) - 2)
        f = (t - tt[k]) / (tt[k + 1] - tt[k])
        return tuple((tab[:, k] + f * (tab[:, k + 1] - tab[:, k])).tolist())


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
    force on the leg each step."""

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
        # Granular particles are kept `gap` off the leg's surface: at least dx/4, and far
        # enough that particles on the two sides of a leg thinner than the kernel support
        # (2h) never interact through it.
        self.gap = max(0.25 * cfg.dx, cfg.h - self.half_t)
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

    # ---------------------------------------------------------------------------------- setup
    def _max_leg_speed(self) -> float:
        leg = self.scene.leg
        if leg is None:
            return 0.0
        tr = leg.trajectory
        r = float(np.hypot(leg.bx, leg.bz).max())
        return float(np.max(np.hypot(tr.hip_vx, tr.hip_vz) + np.abs(tr.angular_velocity) * r))

    def _grid(self):
        cell = 2.0 * self.h / K.REACH
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
    @property
    def settling(self) -> bool:
        return self.t < self.settle_time

    def place_leg(self):
        leg = self.scene.leg
        if leg is None:
            return None
        if self.settling:  # the leg waits at its start pose
            hx, hz, _, _, _, _, ang, _, _ = leg.pose(leg.t0)
            pose = (hx, hz, 0.0, 0.0, 0.0, 0.0, ang, 0.0, 0.0)
        else:
            pose = leg.pose(leg.t0 + self.t - self.settle_time)
        K.place_rigid(self.x, self.z, self.vx, self.vz, self.acc_x, self.acc_z, self.nox,
                      self.noz, self.lidx, leg.bx, leg.bz, leg.bnx, leg.bnz, *pose)
        return pose

    def step(self):
        """One time step; returns (Fx, Fz, torque) on the leg per unit depth (N/m, N) at the
        start of the step."""
        mat = self.scene.material
        cfg = self.scene.config
        gx, gz = self.scene.gravity
        pose = self.place_leg()
        hip_x, hip_z, hip_vx, hip_vz = pose[:4] if pose is not None else (0.0,) * 4
        omega = pose[7] if pose is not None else 0.0
        K.bin_particles(self.x, self.z, self.xmin, self.zmin, self.inv_cell, self.ncx, self.ncz,
                        self.cell_start, self.cell_index)
        grid = (self.xmin, self.zmin, self.inv_cell, self.ncx, self.ncz, self.cell_start,
                self.cell_index)
        self._boundaries(gx, gz)
        K.gather(self.cell_index, self.x, self.z, self.vx, self.vz, self.gvx, self.gvz, self.rho,
                 self.mass, self.kind, self.nox, self.noz, self.dcl, self.guard, self.sxx, self.szz,
                 self.sxz, self._srt, self._srtk)
        K.strain_stress(self._srt, self._srtk, self.cell_index, self.h, *grid[:6], self.rho,
                        self.sxx, self.szz, self.sxz, self.syy, self.dt, mat.shear_modulus,
                        mat.bulk_modulus, mat.alpha_phi, mat.k_c, 0.9 * mat.density,
                        1.1 * mat.density)
        self._boundaries(gx, gz)
        K.regather(self.cell_index, self.vx, self.vz, self.gvx, self.gvz, self.rho, self.mass,
                   self.kind, self.sxx, self.szz, self.sxz, self._srt)
        damping = self.settle_damping if self.settling else 0.0
        nbad = K.accelerations_kick(
            self._srt, self._srtk, self.cell_index, self.mass, self.h, self.c0, cfg.av_alpha,
            cfg.av_beta, cfg.av_boundary, gx, gz, hip_x, hip_z, hip_vx, hip_vz, omega,
            self.half_t, self.gap, 0.1 * cfg.dx, *grid[:6], self.x, self.z, self.vx, self.vz,
            self.rho, self.sxx, self.szz, self.dt, damping, self.vmax_allowed, self.fleg,
            self.bad)
        if nbad:
            i = int(np.argmax(self.bad))
            finite = np.isfinite([self.x[i], self.z[i], self.sxx[i], self.szz[i], self.rho[i]]).all()
            reason = (f"speed {math.hypot(self.vx[i], self.vz[i]):.3g} m/s exceeds the sound speed "
                      f"{self.c0:.3g} m/s" if finite else "non-finite position, density or stress")
            raise SPHInstabilityError(self.step_count, self.t, i, (self.x[i], self.z[i]), reason)
        self.t += self.dt
        self.step_count += 1
        if self._box is not None and self.step_count % 50 == 0:
            self._drop_lost()
        if self.scene.leg is None:
            return (0.0, 0.0, 0.0)
        f = self.fleg.sum(axis=0)  # rows of non-granular particles stay 0
        return (float(f[0]), float(f[1]), float(f[2]))

    def _drop_lost(self):
        """Park granular particles that left the container far away as kind LOST."""
        x0, x1, z0 = self._box
        s = self.sidx
        out = (self.x[s] < x0) | (self.x[s] > x1) | (self.z[s] < z0)
        if not out.any():
            return
        ids = s[out]
        self.kind[ids] = K.LOST
        self.x[ids] = 1e3 + np.arange(len(ids))  # beyond every kernel support
        self.z[ids] = 1e3
        for a in (self.vx, self.vz, self.sxx, self.szz, self.sxz, self.syy):
            a[ids] = 0.0
        self.fleg[ids] = 0.0
        self.sidx = np.flatnonzero(self.kind == K.SOIL).astype(np.int64)
        self.lost += len(ids)

    def _boundaries(self, gx, gz):
        grid = (self.xmin, self.zmin, self.inv_cell, self.ncx, self.ncz, self.cell_start,
                self.cell_index)
        for idx in (self.widx, self.lidx):
            if len(idx):
                K.boundary_state(self.x, self.z, self.vx, self.vz, self.rho, self.mass, self.kind,
                                 self.nox, self.noz, self.dcl, self.sxx, self.szz, self.sxz,
                                 self.syy, self.gvx, self.gvz, idx, self.acc_x, self.acc_z,
                                 gx, gz, self.h, *grid, self.scene.config.noslip)

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
        d = {name: getattr(self, name) for name in Particles.STATE}
        d.update(t=np.array(self.t), step_count=np.array(self.step_count))
        return d

    def load_state(self, d) -> None:
        for name in Particles.STATE:
            getattr(self, name)[:] = d[name]
        self.t = float(d["t"])
        self.step_count = int(d["step_count"])


def scene_key(scene: Scene, extra: dict | None = None) -> str:
    """A hash of everything that defines a run (for checkpoints)."""
    h = hashlib.sha256()
    h.update(json.dumps({"config": asdict(scene.config), "material": scene.material.describe(),
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


def run(scene: Scene, duration: float, *, snapshot_times=(), checkpoint: str | Path | None = None,
        checkpoint_every: float = 60.0, progress: Callable[[float, float], None] | None = None,
        record: bool = True) -> RunResult:
    """Settle the scene, then advance it ``duration`` seconds of motion.

    Forces on the leg are recorded every step after settling. ``snapshot_times``: motion times
    (s) at which to keep particle snapshots. ``checkpoint``: a file; the state is written there
    every ``checkpoint_every`` wall-clock seconds and a rerun of the same scene resumes from it
    (it is removed at the end). ``progress(done_s, total_s)`` is called every few hundred steps.
    """
    import time as _time

    duration = float(duration)
    if not (duration >= 0 and math.isfinite(duration)):
        raise InputError("duration", f"must be >= 0 s, got {duration!r}")
    solver = Solver(scene)
    t_total = solver.settle_time + duration
    nsteps = int(math.ceil(t_total / solver.dt))
    width = scene.leg.width if scene.leg is not None else 1.0
    rec = np.zeros((nsteps + 1, 4))
    nrec = 0
    snaps: list = []
    snap_times = sorted(float(t) for t in snapshot_times)
    key = scene_key(scene, {"duration": duration, "snaps": snap_times})
    ck = Path(checkpoint) if checkpoint else None
    if ck is not None and ck.is_file():
        try:
            with np.load(ck, allow_pickle=False) as d:
                if str(d["key"]) == key:
                    solver.load_state(d)
                    nrec = int(d["nrec"])
                    rec[:nrec] = d["rec"][:nrec]
        except (OSError, KeyError, ValueError):
            pass  # unreadable checkpoint: start afresh
    t0 = _time.perf_counter()
    last_ck = t0
    si = sum(1 for t in snap_times if t < solver.t - solver.settle_time)
    while solver.step_count < nsteps:
        tm = solver.t - solver.settle_time
        while si < len(snap_times) and tm >= snap_times[si] - 0.5 * solver.dt:
            snaps.append(solver.snapshot() | {"time": tm})
            si += 1
        was_settling = solver.settling
        f = solver.step()
        if record and not was_settling:
            rec[nrec] = (tm, f[0] * width, f[1] * width, f[2] * width)
            nrec += 1
        if progress is not None and solver.step_count % 200 == 0:
            progress(solver.t, t_total)
        if ck is not None and _time.perf_counter() - last_ck > checkpoint_every:
            _save_checkpoint(ck, solver, key, rec, nrec)
            last_ck = _time.perf_counter()
    tm = solver.t - solver.settle_time
    while si < len(snap_times):
        snaps.append(solver.snapshot() | {"time": tm})
        si += 1
    if progress is not None:
        progress(t_total, t_total)
    if ck is not None and ck.exists():
        ck.unlink()
    rec = rec[:nrec]
    res = RunResult(rec[:, 0], rec[:, 1], rec[:, 2], rec[:, 3], snaps, solver.step_count,
                    solver.dt, _time.perf_counter() - t0, solver.n)
    res.solver = solver
    res.lost = solver.lost
    return res


def _save_checkpoint(path: Path, solver: Solver, key: str, rec, nrec) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp.npz")
    np.savez(tmp, key=np.array(key), nrec=np.array(nrec), rec=rec[:nrec], **solver.state_dict())
    os.replace(tmp, path)


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
