"""The SPH solver: the time loop, force recording, checkpoints.

A :class:`~.state.Scene` holds the particles (granular bed, fixed walls, optional rigid leg with
its trajectory); :class:`Solver` advances it on a backend (:class:`~.cpu.CPUBackend` or
:class:`~.gpu.GPUBackend`; symplectic Euler; time step from the CFL condition
dt = cfl * h / (c + v_max), c the P-wave speed, cfl = 0.2 after Bui et al. 2008).

The layers of :mod:`terradyn.sph`: :mod:`~.state` (config and state types, particle kinds),
:mod:`~.source` (the one-source registry), :mod:`~.neighbours` (cells, Verlet lists,
binning), :mod:`~.physics` (per-particle and per-pair physics, written once),
:mod:`~.cpu` and :mod:`~.gpu` (the loops around them, one backend each), this module (the
time loop over a backend). Every backend has one interface: ``Backend(solver)``,
``steps(poses, dampings, forces) -> (done, nbad)``, ``drop_lost(box) -> count``,
``to_host()`` (bring the solver's arrays up to date).
"""
from __future__ import annotations

import hashlib
import json
import math
import os
import uuid
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from ..errors import InputError, integer
from .cpu import CPUBackend
from .neighbours import REACH, SKIN
from .state import (BACKENDS, BOUNDARIES, LEG, LOST, POSE_ALPHA, POSE_HIP_AZ, POSE_HIP_VX,
                    POSE_OMEGA, SOIL, WALL, Particles, RigidBody, Scene, SPHConfig,
                    SPHInstabilityError)

__all__ = ["BACKENDS", "BOUNDARIES", "CPUBackend", "LEG", "LOST", "Particles", "RigidBody",
           "RunResult", "SOIL", "SPHConfig", "SPHInstabilityError", "Scene", "Solver", "WALL",
           "check_checkpoint", "gpu_available", "lowpass", "resolve_backend", "run",
           "scene_key", "warmup"]

#: Solver arrays that a backend may hold newer data of than the host (the GPU's): up to date
#: after :meth:`Solver.sync_to_host` (or through :attr:`Solver.state`).
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


class Solver:
    """Advances a :class:`Scene`. ``step()`` one step; ``run(t_end)`` many, recording the
    force on the leg each step. The kernels run on the backend that ``config.backend`` names
    (:class:`~.cpu.CPUBackend`, whose state is this solver's arrays, or
    :class:`terradyn.sph.gpu.GPUBackend`, which keeps the particles on the GPU: there the
    arrays here (:data:`DEVICE_OWNED`) are brought up to date by :meth:`sync_to_host`, which
    :attr:`state`, the snapshots, checkpoints and error reports call; edits made to them after
    it go to the device with the next step)."""

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
        self.sidx = np.flatnonzero(self.kind == SOIL).astype(np.int64)
        self.widx = np.flatnonzero(self.kind == WALL).astype(np.int64)
        self.lidx = np.flatnonzero(self.kind == LEG).astype(np.int64)
        if scene.leg is not None:
            if len(self.lidx) != len(scene.leg.bx):
                raise InputError("scene", "leg particle count does not match the rigid body")
            self.dcl[self.lidx] = scene.leg.dcl
        self.fleg = np.zeros((n, 3))
        # the cell-ordered copy of the particle state the CPU passes read (rows: SRT_* of
        # terradyn.sph.cpu; kinds and side offsets: SRTK_*), public for inspection and tests
        self.srt = np.zeros((11, n))
        self.srtk = np.zeros((3, n))
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
        # side walls (a quasi-2D channel): 2 mu_w / W, 0 without them
        if cfg.channel_width is None:
            self.wall_k = 0.0
        else:
            mu_w = math.tan(cfg.wall_friction if cfg.wall_friction is not None else mat.friction)
            self.wall_k = 2.0 * mu_w / cfg.channel_width
        # grain-leg friction coefficient; -1: a rough (no-slip) leg
        self.leg_mu = -1.0 if cfg.leg_friction is None else math.tan(cfg.leg_friction)
        self.t = 0.0
        self.step_count = 0
        self._grid()
        st = cfg.settle_time
        self.settle_time = st if st is not None else 15.0 * scene.depth_scale / self.c0
        self.settle_damping = 2.0 * self.c0 / max(scene.depth_scale, 1e-6)
        if cfg.threads:
            import numba

            numba.set_num_threads(int(cfg.threads))
        self.backend_name = resolve_backend(cfg.backend)
        if self.backend_name == "gpu":
            from .gpu import GPUBackend

            self.backend = GPUBackend(self)  # the kernels' state (public: steps, to_host, counters)
        else:
            self.backend = CPUBackend(self)

    # ---------------------------------------------------------------------------------- setup
    def _max_leg_speed(self) -> float:
        leg = self.scene.leg
        if leg is None:
            return 0.0
        tr = leg.trajectory
        r = float(np.hypot(leg.bx, leg.bz).max())
        return float(np.max(np.hypot(tr.hip_vx, tr.hip_vz) + np.abs(tr.angular_velocity) * r))

    def _grid(self):
        cell = (2.0 + SKIN) * self.h / REACH  # cells reach the Verlet-list radius
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
            # the leg waits at its start pose: no velocities, accelerations, angular rates
            poses[settling, POSE_HIP_VX:POSE_HIP_AZ + 1] = 0.0
            poses[settling, POSE_OMEGA:POSE_ALPHA + 1] = 0.0
        forces = np.zeros((n, 3))
        done, nbad = self.backend.steps(poses, dampings, forces)
        self.t = ts[done] if done < n else t
        self.step_count += done
        if nbad:
            self.sync_to_host()
            i = int(np.argmax(self.bad))
            finite = np.isfinite([self.x[i], self.z[i], self.sxx[i], self.szz[i], self.rho[i]]).all()
            reason = (f"speed {math.hypot(self.vx[i], self.vz[i]):.3g} m/s exceeds the sound speed "
                      f"{self.c0:.3g} m/s" if finite else "non-finite position, density or stress")
            raise SPHInstabilityError(self.step_count, self.t, i, (self.x[i], self.z[i]), reason)
        if self._box is not None and self.step_count % 50 == 0:
            self.drop_lost()
        return ts[:done], forces[:done]

    def drop_lost(self):
        """Park granular particles that left the container far away as kind LOST."""
        self.lost += self.backend.drop_lost(self._box)

    # ------------------------------------------------------------------ host/device state
    def sync_to_host(self) -> None:
        """Bring the solver's arrays (:data:`DEVICE_OWNED`) up to date from the backend (GPU:
        copies the device state back, and the next step copies the host arrays, edits
        included, to the device; CPU: nothing to do)."""
        self.backend.to_host()

    @property
    def state(self) -> "Solver":
        """The solver with its arrays up to date (:meth:`sync_to_host`): ``solver.state.x``
        reads the positions now on any backend."""
        self.sync_to_host()
        return self

    # ------------------------------------------------------------------------------ snapshots
    def snapshot(self) -> dict:
        """Granular particles now: x, z (m), vx, vz (m/s), pressure (Pa, -trace/3)."""
        self.sync_to_host()
        s = self.sidx
        return {"time": self.t, "x": self.x[s].copy(), "z": self.z[s].copy(),
                "vx": self.vx[s].copy(), "vz": self.vz[s].copy(),
                "pressure": -(self.sxx[s] + self.szz[s] + self.syy[s]) / 3.0}

    def stress(self) -> dict:
        """Granular particles now: x, z (m) and the stress components (Pa, tension positive)."""
        self.sync_to_host()
        s = self.sidx
        return {"x": self.x[s].copy(), "z": self.z[s].copy(), "sxx": self.sxx[s].copy(),
                "szz": self.szz[s].copy(), "sxz": self.sxz[s].copy(), "syy": self.syy[s].copy()}

    # ---------------------------------------------------------------------------- checkpoints
    def state_dict(self) -> dict:
        """Everything a later step reads: the particle state, the kinds (grains dropped as
        lost), the counters and, on the CPU backend, its neighbour search state (the cell
        order, Verlet lists and positions of the last list build, as ``cpu_*``), so that a
        run resumed from it on the CPU is bit-identical to one that was never stopped."""
        self.sync_to_host()
        d = {name: getattr(self, name) for name in Particles.STATE}
        d.update(t=np.array(self.t), step_count=np.array(self.step_count), kind=self.kind,
                 lost=np.array(self.lost))
        backend_state = getattr(self.backend, "state_dict", None)
        if backend_state is not None:
            d.update({f"{self.backend.name}_{k}": v for k, v in backend_state().items()})
        return d

    def load_state(self, d) -> None:
        """Restore :meth:`state_dict` (a dict or an opened .npz). Entries that an older
        checkpoint or the other backend did not write are left as they are (without the
        neighbour state the lists are rebuilt at the next step)."""
        keys = set(d.keys())
        self.sync_to_host()  # the arrays not in d must be current before the next step
        for name in Particles.STATE:
            getattr(self, name)[:] = d[name]
        self.t = float(d["t"])
        self.step_count = int(d["step_count"])
        if "kind" in keys:
            self.kind[:] = d["kind"]
            self.sidx = np.flatnonzero(self.kind == SOIL).astype(np.int64)
        if "lost" in keys:
            self.lost = int(d["lost"])
        pre = f"{self.backend.name}_"
        own = {k[len(pre):]: d[k] for k in keys if k.startswith(pre)}
        if own and hasattr(self.backend, "load_state"):
            self.backend.load_state(own)


def scene_key(scene: Scene, extra: dict | None = None) -> str:
    """A hash of everything that defines a run (for checkpoints)."""
    h = hashlib.sha256()
    # the backend does not change the run: a checkpoint of one resumes on the other
    cfg = scene.config.run_items()
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
    solver.sync_to_host()  # the result's solver: its arrays read the final state on any backend
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


def atomic_savez(path: Path, **arrays) -> None:
    """Write ``arrays`` as an .npz next to ``path`` under a name of this process's own, then
    rename it over ``path`` (atomic): a kill leaves the old checkpoint or the new one, never
    half of one, and two processes checkpointing the same scene never write into one file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f"{path.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.tmp.npz")
    try:
        np.savez(tmp, **arrays)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def _save_checkpoint(path: Path, solver: Solver, key: str, rec, nrec) -> None:
    """The 2D run's checkpoint: its key, force record and :meth:`Solver.state_dict`
    (:func:`atomic_savez`)."""
    atomic_savez(path, key=np.array(key), nrec=np.array(nrec), rec=rec[:nrec],
                 **solver.state_dict())


def lowpass(t: np.ndarray, y: np.ndarray, cutoff_hz: float, order: int = 4) -> np.ndarray:
    """Zero-phase Butterworth low-pass (:func:`terradyn.signal.lowpass`) of a uniformly
    sampled record; a record too short to filter is returned as it is, with a warning."""
    import warnings

    from ..signal import lowpass as _lowpass, min_samples

    if len(t) < min_samples(order):
        warnings.warn(f"lowpass-hz: the force record has {len(t)} samples, too few to filter; "
                      "left unfiltered", stacklevel=2)
        return y
    fs = 1.0 / float(np.median(np.diff(t)))
    return _lowpass(y, fs, cutoff_hz, order, field="lowpass-hz")


def warmup() -> None:
    """Compile all kernels on a tiny scene."""
    from .scenes import bed_scene

    sc = bed_scene(width=0.03, depth=0.02, dx=5e-3, settle_time=0.0)
    s = Solver(sc)
    s.step()
