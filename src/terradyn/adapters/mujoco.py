"""Granular terrain for MuJoCo: 3D-RFT forces on chosen bodies of any robot model.

A :class:`GranularTerrain` is bound to a compiled ``mujoco.MjModel``, the bodies (or geoms)
that touch the ground, a medium (:func:`terradyn.rft3d.medium3d`) and the height of the bed's
free surface. Each physics step (:meth:`GranularTerrain.step`):

1. ``mj_step1`` - positions and velocities of the current state (``xpos``, ``xmat``,
   ``xipos``, ``cvel``);
2. the 3D-RFT wrench of every terrain body's geoms (one compiled call for all bodies; the
   per-element law is :mod:`terradyn.rft3d`'s kernel, optionally with the dynamic-RFT term) is
   **added** to ``data.xfrc_applied`` - force in the world frame and the torque about the
   body's centre of mass, i.e. the RFT moment of the element forces about the CoM, not about
   the contact;
3. ``mj_step2`` - integration; then the terrain wrench is taken out of ``xfrc_applied`` again,
   so the user's own applied forces there are kept.

:meth:`GranularTerrain.run` runs many such steps in ONE compiled call: MuJoCo's C
``mj_step1`` / ``mj_step2`` (ctypes, from the library the ``mujoco`` wheel ships) and the
terrain kernel in a Numba loop on MjData's own arrays, ctrl held or set from a schedule
(the control-rate contract is in its doc); the trajectory is the per-step path's. Where the
library cannot be used it warns and falls back to :meth:`GranularTerrain.step`.

Culling (exact): a body whose box of element centres is above the surface gets a zero
wrench; inside a body, the elements are ordered into spatially compact clusters of
:data:`CLUSTER`, each with its box, and only the elements in the bed of the clusters that
reach below the surface go to the element law (gathered into one block per body).
``precision="float32"`` runs rft3d's single-precision element loop.

Geoms: boxes, capsules, cylinders, spheres, ellipsoids and meshes are turned into closed
triangle meshes in the body frame (trimesh), all geoms of one body into one
:class:`terradyn.rft3d.Body`. Geoms of one body should not overlap much (faces inside another
geom would still feel the medium). Rigid contact between the terrain geoms and the floor geoms
(by default the plane and height-field geoms of the world body) is switched off by clearing
the collision bits they share (``geom_contype`` / ``geom_conaffinity``, in place on the model);
their contacts with anything else that uses other bits are kept.

Stiffness and the time step (see docs/mujoco.md): the terrain force is explicit, with a
stiffness per body ``k <= xi_n |a|max A / 2`` (N/m), A the body's surface area (A/2 bounds its
projected area in any direction) and ``|a|max`` the largest generic stress per depth over all
directions (:func:`max_generic_stress`). MuJoCo's semi-implicit Euler with this explicit
spring is stable when ``omega dt < 2``, ``omega = sqrt(k / m_eff)`` with ``m_eff`` the body's
smallest effective mass in the model (from MuJoCo's inverse mass matrix, the robot's joints
included). :meth:`GranularTerrain.stable_timestep` returns ``safety * 2 / max omega``
(default safety 0.5, i.e. omega dt <= 1) and :meth:`GranularTerrain.step` takes ``substeps``
to split a model step that is longer than that.

Rest and chatter (``stick=True``, the default): RFT is rate-independent, a yield force that
depends on the direction of motion only, so a body at rest on the bed is an explicit
integrator's worst case - the force flips with the sign of a tiny velocity, the body
chatters at about g dt and ratchets deeper. With ``stick`` each body's wrench is evaluated
at the twist it would have at the end of the step without the terrain (``qvel + dt
qacc_smooth``: gravity, actuators, springs, the user's forces), and where its impulse along
the wrench would more than stop that twist (in the body's kinetic-energy metric), the body is
held: the wrench that stops its whole predicted twist is applied if it is no stronger than
the RFT wrench, else the RFT wrench is scaled down to the one that just stops the twist along
it - the discrete form of a plastic (Coulomb-like) resistance. A loaded body then rests
exactly, at the quasi-static RFT depth when loaded slowly, and the terrain never reverses a
body's motion. It costs MuJoCo's actuation and acceleration stages once more per step
(``mj_fwdActuation`` + ``mj_fwdAcceleration``); ``stick=False`` is the plain explicit force.

The compiled kernel uses the default 3D-RFT coefficient table (``rft3d.coefficients()``).

Units SI; world z up; MuJoCo quaternions are (w, x, y, z) like :mod:`terradyn.rft3d`.
"""
from __future__ import annotations

from .._jitcache import bind_to_sources as _bind_cache

import os

os.environ.setdefault("MUJOCO_GL", "egl")  # offscreen GL; read when mujoco is first imported

import math
from dataclasses import dataclass, field

import numba
import numpy as np

from ..errors import InputError, finite, positive
from ..rft3d import Body, Medium3D, from_trimesh, rotation_matrices
from ..rft3d.engine import _block
from ..rft3d.model import cap_tangential, coefficients, generic_alpha


try:
    import mujoco
except ImportError as e:  # pragma: no cover - the extra is installed by the test extra
    raise ImportError("terradyn.adapters.mujoco needs the 'mujoco' package: "
                      "pip install 'terradyn[mujoco]'") from e

GEOM_TYPES = {int(mujoco.mjtGeom.mjGEOM_BOX): "box", int(mujoco.mjtGeom.mjGEOM_CAPSULE): "capsule",
              int(mujoco.mjtGeom.mjGEOM_CYLINDER): "cylinder", int(mujoco.mjtGeom.mjGEOM_SPHERE): "sphere",
              int(mujoco.mjtGeom.mjGEOM_ELLIPSOID): "ellipsoid", int(mujoco.mjtGeom.mjGEOM_MESH): "mesh"}
FLOOR_TYPES = (int(mujoco.mjtGeom.mjGEOM_PLANE), int(mujoco.mjtGeom.mjGEOM_HFIELD))


# ------------------------------------------------------------------------------------------
# Geoms -> triangle meshes in the body frame
# ------------------------------------------------------------------------------------------
def _geom_trimesh(model, g: int, max_edge: float, sections: int):
    """The geom's surface as a trimesh in its body's frame (m)."""
    import trimesh

    kind = GEOM_TYPES.get(int(model.geom_type[g]))
    name = model.geom(g).name or f"#{g}"
    if kind is None:
        raise InputError("geoms", f"geom {name!r} has type {mujoco.mjtGeom(model.geom_type[g]).name}; "
                                  f"terrain geoms must be one of: {', '.join(GEOM_TYPES.values())}")
    s = np.asarray(model.geom_size[g], float)
    if kind == "box":
        tm = trimesh.creation.box(extents=2 * s)
    elif kind == "capsule":
        tm = trimesh.creation.capsule(height=2 * s[1], radius=s[0], count=[sections, sections])
    elif kind == "cylinder":
        tm = trimesh.creation.cylinder(radius=s[0], height=2 * s[1], sections=sections)
    elif kind == "sphere":
        tm = trimesh.creation.icosphere(subdivisions=2, radius=s[0])
    elif kind == "ellipsoid":
        tm = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
        tm.vertices = tm.vertices * s
    else:
        mid = int(model.geom_dataid[g])
        a, n = int(model.mesh_vertadr[mid]), int(model.mesh_vertnum[mid])
        fa, fn = int(model.mesh_faceadr[mid]), int(model.mesh_facenum[mid])
        tm = trimesh.Trimesh(np.array(model.mesh_vert[a:a + n], float),
                             np.array(model.mesh_face[fa:fa + fn], np.int64), process=False)
    if kind in ("box", "capsule", "cylinder") and max_edge:
        v, f = trimesh.remesh.subdivide_to_size(tm.vertices, tm.faces, max_edge, max_iter=20)
        tm = trimesh.Trimesh(v, f, process=False)
    if kind == "capsule":  # trimesh's capsule may not be centred on the origin
        lo, hi = tm.bounds
        tm.vertices = tm.vertices - (lo + hi) / 2
    R = rotation_matrices(np.asarray(model.geom_quat[g], float))
    return trimesh.Trimesh(np.asarray(tm.vertices) @ R.T + model.geom_pos[g], tm.faces, process=False)


def body_surface(model, geoms: list[int], name: str, max_edge: float | None = None,
                 sections: int = 16) -> Body:
    """One :class:`terradyn.rft3d.Body` (body frame) from the geoms of one MuJoCo body."""
    import trimesh

    parts = [_geom_trimesh(model, g, max_edge, sections) for g in geoms]
    tm = parts[0] if len(parts) == 1 else trimesh.util.concatenate(parts)
    return from_trimesh(tm, name, require_closed=True, field=f"geoms of body {name!r}",
                        info={"geoms": [model.geom(g).name for g in geoms]})


def _max_generic_stress(n_dir: int = 400) -> float:
    """Largest |generic stress per depth| (dimensionless, capped at mu_surf = 1) over many
    (normal, direction) pairs with n . v >= 0 - the bound in the stiffness rule."""
    i = np.arange(n_dir) + 0.5
    z = 1 - 2 * i / n_dir
    phi = np.pi * (1 + 5 ** 0.5) * i
    u = np.column_stack([np.sqrt(1 - z * z) * np.cos(phi), np.sqrt(1 - z * z) * np.sin(phi), z])
    n = np.repeat(u, n_dir, 0)
    v = np.tile(u, (n_dir, 1))
    ok = np.einsum("ij,ij->i", n, v) >= 0
    a = cap_tangential(generic_alpha(n[ok], v[ok]), n[ok], 1.0)
    return float(np.linalg.norm(a, axis=1).max())


_A_MAX: list[float] = []


def max_generic_stress() -> float:
    if not _A_MAX:
        _A_MAX.append(_max_generic_stress())
    return _A_MAX[0]


# ------------------------------------------------------------------------------------------
# Compiled step: all terrain bodies in one call
# ------------------------------------------------------------------------------------------
@numba.njit(cache=True, fastmath=True, error_model="numpy")
def _terrain_wrenches(G, C, P, meta, anc, S, box, T, o, cl, Gc, wk, xpos, xmat, xipos, cvel, subtree_com, cdof,
                      qacc, surface, stick_dt, out):  # pragma: no cover - compiled
    """RFT wrench (about the CoM, world frame) of every terrain body into out (nb, 6).

    G (7, n) elements of all bodies (rft3d's struct-of-arrays layout: cx, cy, cz, nx, ny, nz,
    area), body b's in [meta[b, 2], meta[b, 3]); C the coefficient table and P (nb, 7) rft3d's
    kernel parameters per body (xi_n, mu_surf, lambda rho, bounding sphere about the body
    origin), T (nb, 22) pose rows and o (nb, 6) scratch, all four in the element loop's float
    type (float64 or float32: G's dtype); the poses are written relative to the body's CoM, so
    float32 loses nothing to large world coordinates. meta[b, 0] body id, meta[b, 1] its root
    body, meta[b, 4:6] its range in ``anc`` (the dofs that move it). box (nb, 6): the box
    around the body's element centres in the body frame (centre, half sizes): a body whose
    lowest possible element centre is above the surface is skipped (zero wrench; exact, the
    elements there feel nothing). The same test per cluster: cl (ncl, 8) float64 rows [first
    element, end, box centre (3), half sizes (3)] of spatially compact runs of a body's elements
    (body b's clusters: meta[b, 6]..meta[b, 7]); the element law runs only on the clusters
    that may touch the bed: with Gc (7, n, G's type) non-empty, their elements whose centre
    is in the bed are gathered into Gc[:, meta[b, 2]:] and evaluated in one call, else the
    runs of touching clusters are evaluated as they are. wk (5, 6) float64 scratch. S (nb, 76) static floats per body: [0] the largest
    element distance from the body origin, [4:40] the 6 x 6 mobility J M^-1 J^T of the CoM
    twist (v, omega) in the body frame, [40:76] its (pseudo-)inverse, the effective inertia M_b.
    cdof (nv, 6), qacc (nv,): with stick_dt > 0 the body twists are the predicted ones,
    cvel + stick_dt * sum(cdof qacc) (qacc = qacc_smooth), and the no-reversal cap applies:
    where the wrench's impulse would more than stop that twist along the wrench (in the
    kinetic-energy metric), the body is held: the wrench that stops its whole twist,
    -M_b xi / dt, is applied if it is no stronger than the RFT wrench (in the same metric),
    else the RFT wrench scaled down to the one that just stops the twist along it."""
    for b in range(meta.shape[0]):
        bid = meta[b, 0]
        for k in range(6):
            out[b, k] = 0.0
        low = xpos[bid, 2]  # lowest point of the box of element centres
        for k in range(3):
            r2k = xmat[bid, 6 + k]
            low += r2k * box[b, k] - abs(r2k) * box[b, 3 + k]
        if low - 1e-12 >= surface:
            continue
        root = meta[b, 1]
        cv = wk[0]
        for k in range(6):
            cv[k] = cvel[bid, k]
        if stick_dt > 0.0:
            for a in range(meta[b, 4], meta[b, 5]):
                j = anc[a]
                for k in range(6):
                    cv[k] += stick_dt * cdof[j, k] * qacc[j]
        wx, wy, wz = cv[0], cv[1], cv[2]
        dx = xpos[bid, 0] - subtree_com[root, 0]
        dy = xpos[bid, 1] - subtree_com[root, 1]
        dz = xpos[bid, 2] - subtree_com[root, 2]
        for k in range(3):  # body origin relative to the CoM (the torque point: 0)
            T[b, k] = xpos[bid, k] - xipos[bid, k]
            T[b, 15 + k] = cv[k]
            T[b, 18 + k] = 0.0
        for k in range(9):
            T[b, 3 + k] = xmat[bid, k]
        T[b, 12] = cv[3] + wy * dz - wz * dy
        T[b, 13] = cv[4] + wz * dx - wx * dz
        T[b, 14] = cv[5] + wx * dy - wy * dx
        T[b, 21] = surface - xipos[bid, 2]
        # rft3d's compiled element law (the same kernel as rft3d.wrench) on the clusters whose
        # box reaches below the surface: their elements in the bed gathered into Gc (one
        # kernel call per body), or (Gc empty) the runs of such clusters as they are
        r20, r21, r22 = xmat[bid, 6], xmat[bid, 7], xmat[bid, 8]
        a20, a21, a22 = abs(r20), abs(r21), abs(r22)
        gather = Gc.shape[1] > 0
        h0 = surface - xpos[bid, 2]
        n_in = meta[b, 2]
        start = -1
        end = -1
        for c in range(meta[b, 6], meta[b, 7] + 1):
            touch = False
            if c < meta[b, 7]:
                lowc = (r20 * cl[c, 2] + r21 * cl[c, 3] + r22 * cl[c, 4]
                        - a20 * cl[c, 5] - a21 * cl[c, 6] - a22 * cl[c, 7])
                touch = lowc - 1e-12 < h0
            if gather:
                if touch:
                    for i in range(int(cl[c, 0]), int(cl[c, 1])):
                        if r20 * G[0, i] + r21 * G[1, i] + r22 * G[2, i] < h0:
                            for r in range(7):
                                Gc[r, n_in] = G[r, i]
                            n_in += 1
            elif touch:
                if start < 0:
                    start = int(cl[c, 0])
                end = int(cl[c, 1])
            elif start >= 0:  # flush the run of touching clusters
                _block(G, T, b, start, end, C, P[b], o, b)
                for k in range(6):
                    out[b, k] += o[b, k]
                start = -1
        if gather and n_in > meta[b, 2]:
            _block(Gc, T, b, meta[b, 2], n_in, C, P[b], o, b)
            for k in range(6):
                out[b, k] += o[b, k]
        Fx, Fy, Fz, Tx, Ty, Tz = out[b, 0], out[b, 1], out[b, 2], out[b, 3], out[b, 4], out[b, 5]
        if stick_dt > 0.0:  # no-reversal cap: the terrain impulse can at most stop the body
            ex = xipos[bid, 0] - subtree_com[root, 0]
            ey = xipos[bid, 1] - subtree_com[root, 1]
            ez = xipos[bid, 2] - subtree_com[root, 2]
            xi = wk[1]  # predicted twist at the CoM: v_com, omega (world)
            xi[0] = cv[3] + wy * ez - wz * ey
            xi[1] = cv[4] + wz * ex - wx * ez
            xi[2] = cv[5] + wx * ey - wy * ex
            xi[3], xi[4], xi[5] = wx, wy, wz
            power = 0.0
            for k in range(6):
                power += xi[k] * out[b, k]
            if power < 0.0:
                wb = wk[2]  # the wrench in the body frame (R^T F, R^T tau)
                for k in range(3):
                    wb[k] = xmat[bid, k] * Fx + xmat[bid, 3 + k] * Fy + xmat[bid, 6 + k] * Fz
                    wb[3 + k] = xmat[bid, k] * Tx + xmat[bid, 3 + k] * Ty + xmat[bid, 6 + k] * Tz
                ww = 0.0
                for i in range(6):
                    for j in range(6):
                        ww += wb[i] * S[b, 4 + 6 * i + j] * wb[j]
                if ww > 0.0:
                    sc = -power / (stick_dt * ww)  # the scale that stops the twist along w
                    if sc < 1.0:
                        # the wrench that stops the whole predicted twist: -M_b xi / dt (body
                        # frame); held if it is no stronger than the RFT wrench (same metric)
                        xb = wk[3]
                        for k in range(3):
                            xb[k] = xmat[bid, k] * xi[0] + xmat[bid, 3 + k] * xi[1] + xmat[bid, 6 + k] * xi[2]
                            xb[3 + k] = xmat[bid, k] * xi[3] + xmat[bid, 3 + k] * xi[4] + xmat[bid, 6 + k] * xi[5]
                        ws = wk[4]
                        for k in range(6):
                            ws[k] = 0.0
                        kin = 0.0
                        for i in range(6):
                            for j in range(6):
                                ws[i] -= S[b, 40 + 6 * i + j] * xb[j] / stick_dt
                            kin -= xb[i] * ws[i] / stick_dt
                        if kin <= ww:
                            for k in range(3):
                                out[b, k] = xmat[bid, 3 * k] * ws[0] + xmat[bid, 3 * k + 1] * ws[1] + xmat[bid, 3 * k + 2] * ws[2]
                                out[b, 3 + k] = xmat[bid, 3 * k] * ws[3] + xmat[bid, 3 * k + 1] * ws[4] + xmat[bid, 3 * k + 2] * ws[5]
                        else:
                            for k in range(6):
                                out[b, k] *= sc


@numba.njit(cache=True, fastmath=True, error_model="numpy")
def _run_steps(step1, step2, actuation, acceleration, m, d, nsteps, substeps, ctrl, schedule, xfrc,
               G, C, P, meta, anc, S, box, T, o, cl, Gc, wk, xpos, xmat, xipos, cvel, subtree_com, cdof, qacc,
               surface, stick_dt, out, use_terrain, clock, ts, times):  # pragma: no cover - compiled
    """``nsteps`` model steps of ``substeps`` rounds of mj_step1, terrain, mj_step2 each, in
    one compiled call: MuJoCo's C functions (``step1`` ...: ctypes functions, ``m``, ``d``
    the MjModel / MjData addresses) and the terrain kernel on MjData's own arrays. ctrl[:] =
    schedule[i] before model step i if schedule has rows, else ctrl is held. With
    use_terrain False only MuJoCo runs (the benchmark's reference). With times (nsteps, 2)
    the seconds of each step in MuJoCo and in the terrain are added into it (``clock``: libc
    clock_gettime, CLOCK_MONOTONIC; ts a (2,) int64 timespec)."""
    nb = meta.shape[0]
    timed = times.shape[0] > 0
    t0 = t1 = t2 = 0.0
    for i in range(nsteps):
        if schedule.shape[0] > 0:
            for k in range(ctrl.shape[0]):
                ctrl[k] = schedule[i, k]
        for _ in range(substeps):
            if timed:
                clock(1, ts.ctypes.data)
                t0 = ts[0] + 1e-9 * ts[1]
            step1(m, d)
            if timed:
                clock(1, ts.ctypes.data)
                t1 = ts[0] + 1e-9 * ts[1]
            if use_terrain:
                if stick_dt > 0.0:
                    actuation(m, d)
                    acceleration(m, d)
                _terrain_wrenches(G, C, P, meta, anc, S, box, T, o, cl, Gc, wk, xpos, xmat, xipos, cvel,
                                  subtree_com, cdof, qacc, surface, stick_dt, out)
                for b in range(nb):
                    for k in range(6):
                        xfrc[meta[b, 0], k] += out[b, k]
            if timed:
                clock(1, ts.ctypes.data)
                t2 = ts[0] + 1e-9 * ts[1]
            step2(m, d)
            if use_terrain:
                for b in range(nb):
                    for k in range(6):
                        xfrc[meta[b, 0], k] -= out[b, k]
            if timed:
                clock(1, ts.ctypes.data)
                times[i, 0] += (t1 - t0) + (ts[0] + 1e-9 * ts[1] - t2)
                times[i, 1] += t2 - t1


_ENTRY: dict = {}


def _entry(dispatcher, args):
    """The compiled entry point of ``dispatcher`` for arguments like ``args`` (Numba's
    per-call typing of the ~35 arguments costs more than ten physics steps), compiled on
    first use; keyed by the element data's float type (the only type that varies)."""
    key = (dispatcher.__name__, args[11].dtype if dispatcher is _run_steps else args[0].dtype)
    if key not in _ENTRY:
        sig = tuple(numba.typeof(a) for a in args)
        if sig not in dispatcher.overloads:
            dispatcher.compile(sig)
        _ENTRY[key] = getattr(dispatcher.overloads[sig], "entry_point", dispatcher)
    return _ENTRY[key]


# ------------------------------------------------------------------------------------------
# MuJoCo's C library, for the compiled stepping loop
# ------------------------------------------------------------------------------------------
_LIB: dict = {}


def mujoco_c_functions():
    """(functions, reason): ctypes handles of MuJoCo's ``mj_step1``, ``mj_step2``,
    ``mj_fwdActuation``, ``mj_fwdAcceleration`` and libc's ``clock_gettime`` from the shared
    library the ``mujoco`` package ships next to its ``__init__.py``
    (``libmujoco.so*`` / ``mujoco*.dll`` / ``libmujoco*.dylib``), or (None, why not)."""
    if "f" not in _LIB:
        import ctypes
        import ctypes.util
        import glob

        here = os.path.dirname(mujoco.__file__)
        found = sorted(glob.glob(os.path.join(here, "libmujoco.so*")) + glob.glob(os.path.join(here, "libmujoco*.dylib"))
                       + glob.glob(os.path.join(here, "mujoco*.dll")))
        funcs, why = None, None
        if not found:
            why = f"MuJoCo's shared library was not found next to the mujoco package ({here})"
        else:
            try:
                lib = ctypes.CDLL(found[-1])
                libc = ctypes.CDLL(ctypes.util.find_library("c") or None)
                funcs = {}
                for name in ("mj_step1", "mj_step2", "mj_fwdActuation", "mj_fwdAcceleration"):
                    fn = getattr(lib, name)
                    fn.argtypes, fn.restype = [ctypes.c_void_p, ctypes.c_void_p], None
                    funcs[name] = fn
                clk = libc.clock_gettime
                clk.argtypes, clk.restype = [ctypes.c_int, ctypes.c_void_p], ctypes.c_int
                funcs["clock_gettime"] = clk
                if not hasattr(mujoco.MjModel, "_address"):
                    raise AttributeError("mujoco.MjModel has no _address (raw pointer) in this version")
            except (OSError, AttributeError) as e:
                funcs, why = None, f"MuJoCo's shared library {found[-1]} could not be used: {e}"
        _LIB["f"], _LIB["why"] = funcs, why
    return _LIB["f"], _LIB["why"]


# ------------------------------------------------------------------------------------------
# The terrain
# ------------------------------------------------------------------------------------------
#: Elements per cluster (the unit of the per-cluster bed test).
CLUSTER = 16
#: Gather the elements in the bed of the touching clusters (one kernel call per body).
GATHER = True


def _centre_box(x: np.ndarray) -> tuple:
    """(centre x, y, z, half sizes x, y, z) of the box around points x (3, n)."""
    lo, hi = x.min(axis=1), x.max(axis=1)
    return (*((lo + hi) / 2), *((hi - lo) / 2))


def _clusters(x: np.ndarray, size: int):
    """(perm, runs): an order of the points x (3, n) and [lo, hi) runs of at most ``size``
    consecutive points in it, each spatially compact (split at the median of the longest
    extent, recursively)."""
    perm, runs = [], []

    def split(idx):
        if len(idx) <= size:
            runs.append((len(perm), len(perm) + len(idx)))
            perm.extend(idx.tolist())
            return
        pts = x[:, idx]
        ax = int(np.argmax(pts.max(axis=1) - pts.min(axis=1)))
        order = idx[np.argsort(pts[ax], kind="stable")]
        half = len(order) // 2
        split(order[:half])
        split(order[half:])

    split(np.arange(x.shape[1]))
    return np.array(perm, dtype=np.int64), runs


def _names(model, objtype, n: int) -> list[str]:
    return [mujoco.mj_id2name(model, objtype, i) or "" for i in range(n)]


@dataclass
class GranularTerrain:
    """3D-RFT ground for the named bodies (or geoms) of a MuJoCo model; see the module doc.

    ``model``: compiled ``mujoco.MjModel`` (its collision bits are changed in place).
    ``bodies``: names of bodies whose geoms touch the ground (all their supported geoms);
    ``geoms``: names of single geoms instead or in addition. ``medium``: a
    :class:`~terradyn.rft3d.Medium3D`. ``surface``: height of the bed's free surface, m.
    ``dynamic_lambda``: dynamic-RFT lambda (None: quasi-static). ``floor``: names of the geoms
    whose rigid contact with the terrain geoms is switched off (None: the plane/height-field
    geoms of the world body). ``max_edge``: mesh resolution of boxes, capsules, cylinders, m
    (None: a quarter of the largest half-size of each body's geoms). ``stick``: the
    no-reversal (rest) rule of the module doc. ``precision``: the element loop's float type,
    "float64" (default) or "float32" (within 1e-4 of it).
    """

    model: object
    medium: Medium3D
    bodies: tuple[str, ...] = ()
    geoms: tuple[str, ...] = ()
    surface: float = 0.0
    dynamic_lambda: float | None = None
    floor: tuple[str, ...] | None = None
    max_edge: float | None = None
    stick: bool = True
    sections: int = 16
    precision: str = "float64"
    surfaces: dict = field(default_factory=dict, init=False)

    def __post_init__(self):
        m = self.model
        if not isinstance(m, mujoco.MjModel):
            raise InputError("model", f"must be a compiled mujoco.MjModel, got {type(m).__name__}")
        if not isinstance(self.medium, Medium3D):
            raise InputError("medium", "must be a terradyn.rft3d.Medium3D (e.g. rft3d.medium3d('poppy LP'))")
        self.surface = finite("surface", self.surface, "m")
        self.stick = bool(self.stick)
        if self.precision not in ("float64", "float32"):
            raise InputError("precision", f"must be 'float64' or 'float32', got {self.precision!r}")
        dt = np.dtype(self.precision)
        if self.dynamic_lambda is not None:
            positive("dynamic_lambda", self.dynamic_lambda)
        if self.max_edge is not None:
            positive("max_edge", self.max_edge, "m")
        self.bodies = tuple(self.bodies)
        self.geoms = tuple(self.geoms)
        if not self.bodies and not self.geoms:
            raise InputError("bodies", "name at least one body (or geom) that touches the ground")
        body_names = _names(m, mujoco.mjtObj.mjOBJ_BODY, m.nbody)
        geom_names = _names(m, mujoco.mjtObj.mjOBJ_GEOM, m.ngeom)
        per_body: dict[int, list[int]] = {}
        for b in self.bodies:
            if b not in body_names or not b:
                raise InputError("bodies", f"the model has no body named {b!r}; its bodies: "
                                           f"{', '.join(n for n in body_names if n) or '(none named)'}")
            bid = body_names.index(b)
            gs = [g for g in range(m.ngeom) if m.geom_bodyid[g] == bid]
            if not gs:
                raise InputError("bodies", f"body {b!r} has no geoms to feel the terrain")
            per_body.setdefault(bid, []).extend(gs)
        for gname in self.geoms:
            if gname not in geom_names or not gname:
                raise InputError("geoms", f"the model has no geom named {gname!r}; its geoms: "
                                          f"{', '.join(n for n in geom_names if n) or '(none named)'}")
            g = geom_names.index(gname)
            lst = per_body.setdefault(int(m.geom_bodyid[g]), [])
            if g not in lst:
                lst.append(g)
        if 0 in per_body:
            raise InputError("bodies", "the world body cannot feel the terrain (it does not move)")
        self.body_ids = np.array(sorted(per_body), dtype=np.int64)
        self.geom_ids = np.array(sorted(g for gs in per_body.values() for g in gs), dtype=np.int64)
        # surfaces
        G, meta, rad, runs = [], [], [], []
        lo = 0
        for bid in self.body_ids:
            name = body_names[bid] or f"body{bid}"
            gs = sorted(per_body[bid])
            me = self.max_edge
            if me is None:  # a quarter of the smallest dimension of the body's geoms
                me = 0.25 * max(float(np.max(m.geom_size[g])) for g in gs
                                if int(m.geom_type[g]) != int(mujoco.mjtGeom.mjGEOM_MESH)) \
                    if any(int(m.geom_type[g]) != int(mujoco.mjtGeom.mjGEOM_MESH) for g in gs) else None
            surf = body_surface(m, gs, name, me, self.sections)
            self.surfaces[name] = surf
            p = surf.packed()  # (7, n): rft3d's struct-of-arrays layout
            perm, body_runs = _clusters(p[:3], CLUSTER)
            p = p[:, perm]  # elements in cluster order (the sum is the same up to rounding)
            runs.append(body_runs)
            G.append(p)
            meta.append((bid, int(m.body_rootid[bid]), lo, lo + p.shape[1]))
            rad.append(float(np.linalg.norm(p[:3], axis=0).max()))
            lo += p.shape[1]
        G64 = np.ascontiguousarray(np.concatenate(G, axis=1))
        self._G = G64.T  # (n, 7) rows, for per-element reads (float64)
        self._GT = np.ascontiguousarray(G64, dtype=dt)  # the kernel's copy, in its precision
        self._C = np.ascontiguousarray(coefficients(), dtype=dt)
        self._wk = np.zeros((5, 6))
        self._Gc = np.zeros((7, self._GT.shape[1] if GATHER else 0), dt)  # gathered elements in the bed
        # box of the element centres of each body and of each cluster (body frame)
        self._box = np.zeros((len(meta), 6))
        cl = []
        for k, (_, _, a, b) in enumerate(meta):
            self._box[k] = _centre_box(G64[:3, a:b])
            c0 = len(cl)
            for lo_, hi_ in runs[k]:
                cl.append((a + lo_, a + hi_, *_centre_box(G64[:3, a + lo_:a + hi_])))
            meta[k] = meta[k] + (c0, len(cl))
        self._cl = np.array(cl, dtype=float)
        anc = []
        for k, bid in enumerate(self.body_ids):  # the dofs that move each body (its ancestors')
            start = len(anc)
            b = int(bid)
            while b > 0:
                anc.extend(int(j) for j in range(m.nv) if m.dof_bodyid[j] == b)
                b = int(m.body_parentid[b])
            meta[k] = meta[k][:4] + (start, len(anc)) + meta[k][4:]
        self._anc = np.array(anc + [0], dtype=np.int64)
        self._meta = np.array(meta, dtype=np.int64)
        nb = len(self.body_ids)
        self._S = np.zeros((nb, 76))
        self._S[:, 0] = rad
        self._P = np.zeros((nb, 7), dt)  # rft3d's kernel parameters; sphere about the body origin
        self._P[:, 0:3] = (self.medium.xi_n, self.medium.mu_surf,
                           (self.dynamic_lambda or 0.0) * self.medium.bulk_density)
        self._P[:, 6] = rad
        self._mobility_set = False
        self._bound = None
        self._T = np.zeros((nb, 22), dt)
        self._o = np.zeros((nb, 6), dt)
        self._out = np.zeros((nb, 6))
        self._disable_floor_contact(geom_names)

    # ---------------------------------------------------------------- contact with the floor
    def _disable_floor_contact(self, geom_names):
        m = self.model
        if self.floor is None:
            fl = [g for g in range(m.ngeom) if m.geom_bodyid[g] == 0 and int(m.geom_type[g]) in FLOOR_TYPES]
        else:
            fl = []
            for f in self.floor:
                if f not in geom_names or not f:
                    raise InputError("floor", f"the model has no geom named {f!r}")
                fl.append(geom_names.index(f))
        self.floor_ids = np.array(fl, dtype=np.int64)
        for g in self.geom_ids:
            for f in fl:
                m.geom_contype[g] &= ~int(m.geom_conaffinity[f])
                m.geom_conaffinity[g] &= ~int(m.geom_contype[f])

    # ---------------------------------------------------------------- forces
    @property
    def n_elements(self) -> int:
        return len(self._G)

    def wrenches(self, data) -> np.ndarray:
        """(nb, 6) terrain wrenches [F (N), torque about the CoM (N m)], world frame, of the
        terrain bodies (order :attr:`body_ids`) in ``data``'s current kinematics (after
        ``mj_step1`` or ``mj_forward``). With ``stick`` the velocities are the predicted
        end-of-step ones and the no-reversal cap applies (module doc)."""
        m = self.model
        stick_dt = 0.0
        if self.stick:
            if not self._mobility_set:
                self._set_mobility(data)
            stick_dt = m.opt.timestep
            mujoco.mj_fwdActuation(m, data)
            mujoco.mj_fwdAcceleration(m, data)
        self._bind(data)
        args = (*self._args, self.surface, stick_dt, self._out)
        _entry(_terrain_wrenches, args)(*args)
        return self._out

    def _bind(self, data) -> None:
        if self._bound is not data:  # MjData arrays never move: bind their views once
            self._args = (self._GT, self._C, self._P, self._meta, self._anc, self._S, self._box, self._T,
                          self._o, self._cl, self._Gc, self._wk, data.xpos, data.xmat, data.xipos, data.cvel, data.subtree_com,
                          data.cdof, data.qacc_smooth)
            self._xfrc = data.xfrc_applied
            self._bound = data

    def _set_mobility(self, data) -> None:
        mob = self.mobility(data)
        self._S[:, 4:40] = mob.reshape(-1, 36)
        self._S[:, 40:76] = np.linalg.pinv(mob, hermitian=True).reshape(-1, 36)
        self._mobility_set = True

    def apply(self, data) -> np.ndarray:
        """Add the terrain wrenches to ``data.xfrc_applied``; returns them ((nb, 6), a view
        overwritten by the next call). Take them out again after ``mj_step2``
        (:meth:`remove`), or use :meth:`step`."""
        w = self.wrenches(data)
        self._xfrc[self.body_ids] += w
        return w

    def remove(self, data) -> None:
        """Take the last applied terrain wrenches out of ``data.xfrc_applied``."""
        self._xfrc[self.body_ids] -= self._out

    def step(self, data, substeps: int = 1) -> None:
        """One model step (``model.opt.timestep``) with the terrain: ``substeps`` rounds of
        mj_step1, terrain, mj_step2 of ``timestep / substeps`` each."""
        m = self.model
        if substeps == 1:
            mujoco.mj_step1(m, data)
            self.apply(data)
            mujoco.mj_step2(m, data)
            self.remove(data)
            return
        dt = m.opt.timestep
        m.opt.timestep = dt / substeps
        try:
            for _ in range(substeps):
                mujoco.mj_step1(m, data)
                self.apply(data)
                mujoco.mj_step2(m, data)
                self.remove(data)
        finally:
            m.opt.timestep = dt

    def run(self, data, nsteps: int, ctrl=None, substeps: int = 1, compiled: bool = True,
            terrain: bool = True, timing: bool = False) -> dict:
        """``nsteps`` model steps with the terrain in ONE compiled call (MuJoCo's C
        ``mj_step1`` / ``mj_step2`` and the terrain kernel in a Numba loop on MjData's own
        arrays; no Python per step). Same physics as calling :meth:`step` ``nsteps`` times.

        Control-rate contract: the controller runs between calls, physics inside them.
        ``ctrl=None`` holds ``data.ctrl`` constant for the ``nsteps`` steps (a controller at
        1 / (nsteps timestep)); an array (nsteps, nu) sets ``data.ctrl`` to row i before step
        i (a precomputed schedule, e.g. a gait's targets: then the trajectory is the one of a
        per-step controller). The user's ``xfrc_applied`` / ``qfrc_applied`` are held too.

        ``compiled=False``, or MuJoCo's C library not found (:func:`mujoco_c_functions`;
        a warning says why, once), runs the same steps through the per-step Python path
        (:meth:`step`). ``terrain=False`` runs MuJoCo alone (the benchmark's reference);
        ``timing=True`` times each step's MuJoCo and terrain parts (clock_gettime in the
        loop). Returns {"compiled": bool, "step_times_s": (steps, 2) seconds in MuJoCo and in
        the terrain per compiled step (timing only; the first step is not in it when the rest
        rule's first step ran in Python)}."""
        m = self.model
        nsteps = int(nsteps)
        if nsteps < 0:
            raise InputError("nsteps", f"must be >= 0, got {nsteps}")
        substeps = int(substeps)
        if substeps < 1:
            raise InputError("substeps", f"must be >= 1, got {substeps}")
        sched = np.zeros((0, m.nu))
        if ctrl is not None:
            sched = np.ascontiguousarray(ctrl, dtype=float)
            if sched.shape != (nsteps, m.nu):
                raise InputError("ctrl", f"must have shape (nsteps, nu) = ({nsteps}, {m.nu}), got {sched.shape}")
            if not np.isfinite(sched).all():
                raise InputError("ctrl", "must be finite")
        funcs = None
        if compiled:
            funcs, why = mujoco_c_functions()
            if funcs is None and not _WARNED:
                import warnings

                warnings.warn(f"GranularTerrain.run: {why}; running the per-step Python path instead",
                              RuntimeWarning, stacklevel=2)
                _WARNED.append(True)
        res = {"compiled": funcs is not None}
        if nsteps == 0:
            return res
        first = 0
        if terrain and self.stick and not self._mobility_set:  # the rest rule's M_b: first step in Python
            if len(sched):
                data.ctrl[:] = sched[0]
            self.step(data, substeps)
            first = 1
        if funcs is None:
            import time

            times = np.full((nsteps - first, 2), np.nan)
            for i in range(first, nsteps):
                if len(sched):
                    data.ctrl[:] = sched[i]
                tic = time.perf_counter()
                if terrain:
                    self.step(data, substeps)
                else:
                    _plain_step(m, data, substeps)
                times[i - first, 0] = time.perf_counter() - tic
            if timing:
                res["step_times_s"] = times  # whole steps (the split is not timed here)
            return res
        self._bind(data)
        times = np.zeros((nsteps - first if timing else 0, 2))
        dt = m.opt.timestep
        args = (funcs["mj_step1"], funcs["mj_step2"], funcs["mj_fwdActuation"], funcs["mj_fwdAcceleration"],
                m._address, data._address, nsteps - first, substeps, data.ctrl,
                sched[first:] if len(sched) else sched, self._xfrc, *self._args, self.surface,
                m.opt.timestep / substeps if self.stick else 0.0, self._out, bool(terrain),
                funcs["clock_gettime"], np.zeros(2, np.int64), times)
        m.opt.timestep = dt / substeps
        try:
            _entry(_run_steps, args)(*args)
        finally:
            m.opt.timestep = dt
        if timing:
            res["step_times_s"] = times
        return res

    # ---------------------------------------------------------------- stiffness rule
    def stiffness(self) -> np.ndarray:
        """(nb,) bound on each body's terrain stiffness dF/d(depth), N/m:
        xi_n |a|max A/2 (A the body's surface area)."""
        areas = np.array([self._G[r[2]:r[3], 6].sum() for r in self._meta])
        return self.medium.xi_n * max_generic_stress() * 0.5 * areas

    def mobility(self, data) -> np.ndarray:
        """(nb, 6, 6) mobility J M^-1 J^T of each terrain body's CoM twist (v, omega), in the
        body's frame, in ``data``'s configuration (after ``mj_forward`` / ``mj_step1``). The
        no-reversal cap takes it from the first step and turns it with the body (exact for a
        free rigid body, an estimate for a linked one whose joints move)."""
        m = self.model
        out = np.empty((len(self.body_ids), 6, 6))
        J = np.zeros((6, m.nv))
        X = np.zeros((6, m.nv))
        for i, bid in enumerate(self.body_ids):
            jp, jr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
            mujoco.mj_jacBodyCom(m, data, jp, jr, int(bid))
            R = np.asarray(data.xmat[bid]).reshape(3, 3)
            J[:3], J[3:] = R.T @ jp, R.T @ jr
            mujoco.mj_solveM(m, data, X, J)
            out[i] = J @ X.T
        return out

    def effective_mass(self, data) -> np.ndarray:
        """(nb,) smallest effective mass of each terrain body in the model, kg: 1 / the largest
        mobility of a point of the body (MuJoCo's inverse mass matrix, joints included), in
        ``data``'s configuration (after ``mj_forward`` or ``mj_step1``)."""
        m = self.model
        out = np.empty(len(self.body_ids))
        jp = np.zeros((3, m.nv))
        jr = np.zeros((3, m.nv))
        for i, bid in enumerate(self.body_ids):
            mujoco.mj_jacBodyCom(m, data, jp, jr, int(bid))
            xp = np.zeros((3, m.nv))
            xr = np.zeros((3, m.nv))
            mujoco.mj_solveM(m, data, xp, jp)
            mujoco.mj_solveM(m, data, xr, jr)
            lam = np.linalg.eigvalsh(jp @ xp.T).max() + self._S[i, 0] ** 2 * np.linalg.eigvalsh(jr @ xr.T).max()
            out[i] = 1.0 / lam
        return out

    def stable_timestep(self, data, safety: float = 0.5) -> float:
        """Largest time step (s) of the rule omega dt <= 2 safety, omega = sqrt(k / m_eff)
        over the terrain bodies (:meth:`stiffness`, :meth:`effective_mass`)."""
        safety = positive("safety", safety)
        omega = np.sqrt(self.stiffness() / self.effective_mass(data))
        return float(2 * safety / omega.max())

    def substeps_for(self, data, safety: float = 0.5) -> int:
        """Substeps that bring ``model.opt.timestep`` within :meth:`stable_timestep`."""
        return max(1, math.ceil(self.model.opt.timestep / self.stable_timestep(data, safety) - 1e-12))

    def describe(self) -> dict:
        return {"bodies": [self.model.body(int(b)).name for b in self.body_ids],
                "elements": self.n_elements, "medium": self.medium.describe(),
                "surface_m": self.surface, "dynamic_lambda": self.dynamic_lambda,
                "stick": self.stick, "precision": self.precision,
                "floor_geoms": [self.model.geom(int(g)).name for g in self.floor_ids]}


_WARNED: list = []


def _plain_step(m, data, substeps: int) -> None:
    dt = m.opt.timestep
    m.opt.timestep = dt / substeps
    try:
        for _ in range(substeps):
            mujoco.mj_step1(m, data)
            mujoco.mj_step2(m, data)
    finally:
        m.opt.timestep = dt


def energy(model, data) -> float:
    """Kinetic + gravitational potential energy of ``data``'s state (J), from MuJoCo
    (``mj_forward`` first: after ``mj_step`` the derived positions are one step old)."""
    mujoco.mj_forward(model, data)
    mujoco.mj_energyPos(model, data)
    mujoco.mj_energyVel(model, data)
    return float(data.energy.sum())


__all__ = ["GranularTerrain", "body_surface", "energy", "max_generic_stress", "mujoco_c_functions", "GEOM_TYPES"]

# Cached kernels above use jitted code and constants of other modules: make their on-disk
# cache stale when those change too (terradyn._jitcache; Numba checks only this file).
_bind_cache(globals(), 'terradyn.rft3d.engine', 'terradyn.rft3d.model')
