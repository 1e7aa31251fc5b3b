"""Bit-for-bit regression check of the SPH solver (CPU backend) across code changes.

    python benchmarks/sph_bitwise.py save DIR    # on the old code: writes DIR/<case>.npz
    python benchmarks/sph_bitwise.py check DIR   # on the new code: exit 1 unless all equal

Cases: a flat leg rotating through a bed with settling and a snapshot ("leg"), the same with
the guard boundary and beta viscosity ("leg_guard"), the leg with Verlet lists too short for
anyone (the cell-search fallbacks, "overflow"), a bed with a grain thrown out of the
container (the drop of lost grains, "bed"), a plate pushed down with free-slip walls and
boundary viscosity ("plate"). Compared with np.array_equal: forces, positions, velocities,
densities, stresses, ghost velocities, per-particle leg forces, kinds, cell order, list
builds. Results depend on the machine (Numba compiles for the host CPU, with fastmath): save
and check on the same machine. Used for the re-layering of terradyn.sph (kernels.py split
into state / neighbours / physics / cpu / gpu).
"""
import sys, math
import numpy as np
import terradyn as td
from terradyn.sph import SPHConfig, scenes, solver
from terradyn.units import DEG

mode, out = sys.argv[1], sys.argv[2]
ARR = ("x", "z", "vx", "vz", "rho", "sxx", "szz", "sxz", "syy", "gvx", "gvz", "fleg", "kind",
       "cell_index", "cell_start", "dcl", "nox", "noz")

def state(s, extra):
    d = {k: np.array(getattr(s, k), copy=True) for k in ARR}
    d.update(extra)
    d["builds"] = np.array(s.backend.builds)
    d["t"] = np.array(s.t)
    return d

def leg_case(**kw):
    leg = td.flat_leg()
    traj = td.Rotation(omega=4.0, hip_height=0.02, theta_start=-65 * DEG, theta_end=-45 * DEG,
                       n_theta=5).trajectory()
    cfg = SPHConfig(dx=5e-3, settle_time=3e-4, **kw)
    sc = scenes.leg_scene(leg, traj, 0, bed_width=0.16, bed_depth=0.04, config=cfg)
    r = solver.run(sc, 0.02, snapshot_times=[0.005])
    s = r.solver
    return state(s, {"time": r.time, "Fx": r.Fx, "Fz": r.Fz, "torque": r.torque,
                     "snap_p": r.snapshots[0]["pressure"], "snap_x": r.snapshots[0]["x"],
                     "steps": np.array(r.steps)})

def overflow_case():
    leg = td.flat_leg()
    traj = td.Rotation(omega=4.0, hip_height=0.02, theta_start=-65 * DEG, theta_end=-45 * DEG,
                       n_theta=5).trajectory()
    s = solver.Solver(scenes.leg_scene(leg, traj, 0, bed_width=0.16, bed_depth=0.04,
                                       config=SPHConfig(dx=5e-3, settle_time=0.0)))
    be = s.backend
    be.nb = tuple(np.zeros((s.n, 3), a.dtype) if a.ndim == 2 else a for a in be.nb)
    be.bj = np.zeros((len(be.bidx), 3), np.int32)
    f = np.array([s.step() for _ in range(120)])
    return state(s, {"F": f})

def bed_case():
    s = solver.Solver(scenes.bed_scene(width=0.06, depth=0.03, dx=5e-3, settle_time=0.0))
    s.advance(30)
    i = int(s.sidx[0])
    s.x[i], s.z[i] = 0.0, -0.2
    t, f = s.advance(170)
    return state(s, {"lost": np.array(s.lost), "ts": t, "stress_szz": s.stress()["szz"]})

def plate_case():
    from terradyn.geometry import ArcLeg
    from terradyn.motion import PlanarMotion
    length, width, thickness, dx, speed = 0.0381, 0.0254, 0.0064, 4e-3, 0.3
    plate = ArcLeg(width, 20, length, 0.0, "plate", direction=math.pi / 2)
    z0 = 0.5 * thickness + 0.5 * dx
    T = 0.02
    t = np.linspace(0, T, 11)
    mot = PlanarMotion(t, np.full_like(t, -length / 2), z0 - speed * t, np.zeros_like(t),
                       hip_vx=np.zeros_like(t), hip_vz=np.full_like(t, -speed),
                       angular_velocity=np.zeros_like(t))
    cfg = SPHConfig(dx=dx, settle_time=2e-4, boundary="guard", av_boundary=True, noslip=False)
    sc = scenes.leg_scene(plate, mot.trajectory() if hasattr(mot, "trajectory") else mot, 0,
                          bed_width=0.12, bed_depth=0.05, thickness=thickness, config=cfg)
    r = solver.run(sc, 0.015)
    return state(r.solver, {"Fx": r.Fx, "Fz": r.Fz, "torque": r.torque, "lost": np.array(r.lost)})

cases = {"leg": lambda: leg_case(), "leg_guard": lambda: leg_case(boundary="guard", av_beta=0.5),
         "overflow": overflow_case, "bed": bed_case, "plate": plate_case}
bad = 0
for name, fn in cases.items():
    d = fn()
    path = f"{out}/{name}.npz"
    if mode == "save":
        np.savez(path, **d)
        print(name, "saved", {k: np.shape(v) for k, v in d.items() if k in ("x", "Fz", "F", "ts")})
    else:
        ref = np.load(path)
        diff = [k for k in ref.files if not np.array_equal(ref[k], d[k])]
        missing = set(ref.files) ^ set(d)
        print(name, "BITWISE EQUAL" if not diff and not missing else f"DIFF {diff} {missing}")
        bad += bool(diff or missing)
sys.exit(bad)
