"""SPH as force series: the functions users call (same legs and motions as RFT)."""
from __future__ import annotations

from dataclasses import asdict, replace

import numpy as np
import xarray as xr

from ..errors import InputError, positive
from ..geometry import Leg
from ..motion import PlanarMotion, Rotation
from ..series import force_series
from ..units import DEG
from .materials import GranularMaterial, material as _material
from .scenes import LEG_THICKNESS, _body_to_world, _centre_line, contact_window, leg_scene
from .solver import RunResult, lowpass, run
from .state import SPHConfig

#: Particle spacing of the full runs (m) and of the quick form used by tests.
FULL_DX = 2.5e-3
QUICK_DX = 4.0e-3
#: Memory per particle (state, neighbour lists, work arrays), bytes: an upper estimate.
PARTICLE_BYTES = 4096


def default_config(quick: bool = False, **kw) -> SPHConfig:
    """:class:`SPHConfig` with the full (or ``quick``) resolution unless ``dx`` is given
    (None: the default; 0 or less is an error, not the default)."""
    dx = kw.pop("dx", None)
    return SPHConfig(dx=(QUICK_DX if quick else FULL_DX) if dx is None else dx, **kw)


def bed_extent(leg: Leg, traj, i0: int, i1: int, pad: float) -> tuple[float, float]:
    """Bed (width, depth) that holds the leg's path below the surface with ``pad`` (m) around."""
    P, _, _ = _centre_line(leg, 2e-3)
    xs, zs = [], []
    for k in range(i0, i1 + 1):
        x, z = _body_to_world(P[:, 0], P[:, 1], traj.hip_x[k], traj.hip_z[k], traj.angle[k])
        below = z < 0
        xs.append(x[below] if below.any() else np.array([traj.hip_x[k]]))
        zs.append(z[below] if below.any() else np.array([0.0]))
    xs = np.concatenate(xs)
    zs = np.concatenate(zs)
    xc = float(np.mean(traj.hip_x))
    half = max(abs(xs.max() - xc), abs(xs.min() - xc)) + pad
    return 2 * half, -zs.min() + pad


def simulate(leg: Leg, motion: Rotation | PlanarMotion, medium: str | GranularMaterial = "3 mm glass CP",
             *, quick: bool = False, config: SPHConfig | None = None, thickness: float | None = None,
             bed_width: float | None = None, bed_depth: float | None = None,
             checkpoint=None, progress=None, material: str | GranularMaterial | None = None) -> xr.Dataset:
    """SPH forces on ``leg`` following ``motion`` through a bed of ``medium`` (a Li 2013
    medium name or a :class:`GranularMaterial`; ``material=`` is the same argument by
    another name): the force series of :func:`simulate_run`."""
    if material is not None:
        medium = material
    return simulate_run(leg, motion, medium, quick=quick, config=config, thickness=thickness,
                        bed_width=bed_width, bed_depth=bed_depth, checkpoint=checkpoint,
                        progress=progress)[0]


def simulate_run(leg: Leg, motion: Rotation | PlanarMotion, medium: str | GranularMaterial = "3 mm glass CP",
                 *, quick: bool = False, config: SPHConfig | None = None, thickness: float | None = None,
                 bed_width: float | None = None, bed_depth: float | None = None,
                 snapshot_times=(), checkpoint=None, progress=None) -> tuple[xr.Dataset, RunResult | None]:
    """SPH forces on ``leg`` following ``motion`` through a bed of ``medium``, and the run.

    Only the part of the motion where the leg is within one kernel support of the bed is
    simulated; before and after it the force is exactly zero (the leg is in air). Returns a
    force series (coordinate ``theta`` in deg for rotations, ``time`` in s otherwise) with
    Fx, Fz (N) and torque (N m) about the hip, sampled at the motion's samples from the
    per-step record (optionally low-passed, ``config.lowpass_hz``), and the
    :class:`RunResult` (None when the leg never nears the bed: per-step forces from the
    contact start; particle snapshots at ``snapshot_times``: s since the motion's start,
    those inside the simulated part)."""
    cfg = config or default_config(quick)
    mat = _material(medium, cfg.dx)
    thickness = LEG_THICKNESS if thickness is None else thickness
    positive("thickness", thickness, "m")
    traj = motion.trajectory()
    margin = 2.0 * cfg.h + cfg.dx
    i0, i1 = contact_window(leg, traj, margin)
    n = len(traj)
    Fx = np.zeros(n)
    Fz = np.zeros(n)
    Tq = np.zeros(n)
    res = None
    meta = {}
    if i0 >= 0 and i1 > i0:
        pad = cfg.bed_pad if cfg.bed_pad is not None else (0.03 if quick else 0.06)
        w_auto, d_auto = bed_extent(leg, traj, i0, i1, pad)
        bw = bed_width or w_auto
        bd = bed_depth or d_auto
        from ..errors import check_memory

        n_est = (bw / cfg.dx + 2 * cfg.wall_layers) * (bd / cfg.dx + cfg.wall_layers)
        check_memory("dx-mm", n_est * PARTICLE_BYTES, f"a bed of about {n_est:,.0f} particles "
                                                      f"(dx = {cfg.dx * 1e3:g} mm)")
        scene = leg_scene(leg, traj, i0, mat, bed_width=bw, bed_depth=bd, thickness=thickness,
                          config=cfg)
        duration = float(traj.time[i1] - traj.time[i0])
        offset = float(traj.time[i0] - traj.time[0])
        snaps = [float(t) - offset for t in snapshot_times if 0 <= float(t) - offset <= duration]
        res = run(scene, duration, snapshot_times=snaps, checkpoint=checkpoint,
                  progress=progress)
        for sn in res.snapshots:
            sn["time"] += offset  # back to time since the motion's start
        t_rel = traj.time[i0:i1 + 1] - traj.time[i0]
        comps = [res.Fx, res.Fz, res.torque]
        if cfg.lowpass_hz is not None:
            comps = [lowpass(res.time, c, cfg.lowpass_hz) for c in comps]
        for out, c in zip((Fx, Fz, Tq), comps):
            out[i0:i1 + 1] = np.interp(t_rel, res.time, c) if len(res.time) else 0.0
        meta = {"bed_width_m": bw, "bed_depth_m": bd, "contact_samples": [int(i0), int(i1)],
                "particles": res.particles, "steps": res.steps, "dt_s": res.dt,
                "wall_seconds": round(res.wall_seconds, 3), "lost_particles": int(res.lost),
                "particle_steps_per_s": res.particles * res.steps / max(res.wall_seconds, 1e-9)}
        if res.resumed_from is not None:
            meta["resumed_from"] = res.resumed_from
    inputs = {"leg": leg.describe(), "motion": motion.describe(), "medium": mat.name,
              "material": mat.describe(), "sph": asdict(cfg) | {"quick": quick},
              "thickness_m": thickness, "run": meta}
    coord, values = ("theta", traj.angle / DEG) if traj.coord == "theta" else ("time", traj.time)
    ds = force_series(coord, values, Fx, Fz, Tq, model="sph", inputs=inputs,
                      time=traj.time if coord == "theta" else None)
    ds.attrs["filter"] = (f"zero-phase Butterworth low-pass {cfg.lowpass_hz} Hz (order 4)"
                          if cfg.lowpass_hz else "none (instantaneous per-step force)")
    return ds, res


def simulate_speeds(leg: Leg, omegas, medium="3 mm glass CP", *, quick=False, config=None,
                    n_theta: int = 271, theta_start=-135 * DEG, theta_end=135 * DEG,
                    hip_height=0.02, progress=None) -> xr.Dataset:
    """The same leg at several angular speeds (thesis Table 4.1): a stack along ``case`` with
    coordinate ``omega`` (rad/s)."""
    from ..series import stack

    out = []
    for w in omegas:
        mot = Rotation(omega=float(w), hip_height=hip_height, theta_start=theta_start,
                       theta_end=theta_end, n_theta=n_theta)
        out.append(simulate(leg, mot, medium, quick=quick, config=config, progress=progress))
    return stack(out, case_coords={"omega": np.asarray(omegas, float)})


def snapshots_dataset(res: RunResult) -> xr.Dataset:
    """Particle snapshots of a run as a Dataset (snapshot, particle): x, z (m), vx, vz (m/s),
    pressure (Pa)."""
    if res is None or not res.snapshots:
        raise InputError("snapshots", "the run kept no snapshots")
    names = ("x", "z", "vx", "vz", "pressure")
    units = {"x": "m", "z": "m", "vx": "m/s", "vz": "m/s", "pressure": "Pa"}
    ds = xr.Dataset({k: (("snapshot", "particle"), np.stack([s[k] for s in res.snapshots]))
                     for k in names},
                    coords={"snapshot_time": ("snapshot", [s["time"] for s in res.snapshots])})
    for k in names:
        ds[k].attrs["units"] = units[k]
    ds["snapshot_time"].attrs["units"] = "s"
    return ds


def with_lowpass(cfg: SPHConfig, hz: float | None) -> SPHConfig:
    return replace(cfg, lowpass_hz=hz)
