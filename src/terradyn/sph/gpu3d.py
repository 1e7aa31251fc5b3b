"""GPU path of the 3D SPH (:mod:`terradyn.sph.plate3d`), Numba CUDA: ``Solver3D`` with
``SPHConfig(backend="gpu")``.

Import this module only when the GPU is asked for: it imports ``numba.cuda``. Under
``NUMBA_ENABLE_CUDASIM=1`` (set before numba.cuda is first imported) it runs in Numba's CUDA
simulator on the CPU; that is how the tests check it against the CPU kernels.

Design:

* **one source**: the per-particle functions of :mod:`~terradyn.sph.plate3d` that the CPU's
  ``prange`` loops inline (:data:`ONE_SOURCE`) are compiled again here as CUDA device
  functions, their global names bound to the device versions. The CPU passes visit each
  granular pair once and write the pair's terms into both particles, running chunks three
  apart at once so that no two threads write one particle; on the GPU every granular
  particle is a thread, so those writes (``bacc``, ``lg``, ``acc`` ``+=`` / ``-=``) become
  atomic adds: :func:`_atomic_source` rewrites exactly those statements of the source (an AST
  transform), nothing else. The physics is therefore written once.
* **the state lives on the device for one** :meth:`Solver3D.advance` **call** (a block of up
  to 2000 steps in :func:`~terradyn.sph.plate3d._run_blocks`): uploaded at its start,
  downloaded at its end, so checkpoints, ``state_dict`` and everything after a run read the
  host arrays as on the CPU path.
* **the Verlet lists are built on the host** with the CPU's own functions (ghosts, cell
  binning, the pair lists) when a particle has moved half the skin (about every 10-20 steps):
  positions and kinds go down, the lists and ghost maps go up. Every step's pair passes, the
  ghosts' refresh, the kick and the plate's placement run on the device.
* **not bitwise reproducible**: atomic float sums depend on the order the threads arrive in,
  so a GPU run differs from the CPU's (and from another GPU run) by rounding, which the
  chaotic flow grows over a long run, as between realizations. The tests hold the GPU path
  to the CPU's forces within 1e-9 (relative) over a short run in the simulator.
"""
from __future__ import annotations

import ast
import inspect
import math
import textwrap

import numpy as np
from numba import config, cuda

from . import plate3d as P

SIM = bool(config.ENABLE_CUDASIM)
#: Threads per block; in the simulator (every thread a Python thread) at most SIM_BLOCKS
#: blocks, each kernel looping over its items with a grid stride.
TPB = 32 if SIM else 128
SIM_BLOCKS = 2

#: The per-particle functions of plate3d compiled for the device (dependencies first).
ONE_SOURCE = ("dp_update3", "_add_grad", "_stress_term3", "_ghost_one", "_boundary_one",
              "_boundary_fin", "_strain_one", "_dp_one", "_psig_one", "_accel_one",
              "_kick_one", "_side_one", "_disp2_one", "_place_marker")
#: Arrays that many threads add into at once on the device (the pair terms' partners).
ATOMIC_ARRAYS = frozenset({"bacc", "lg", "acc"})


class _AtomicAdds(ast.NodeTransformer):
    """``a[i, j] += v`` -> ``_atomic_add(a, (i, j), v)`` (``-=``: ``-(v)``) for the arrays
    of :data:`ATOMIC_ARRAYS`; every other statement is left as it is."""

    def __init__(self):
        self.count = 0

    def visit_FunctionDef(self, node):
        node.decorator_list = []
        self.generic_visit(node)
        return node

    def visit_AugAssign(self, node):
        t = node.target
        if not (isinstance(t, ast.Subscript) and isinstance(t.value, ast.Name)
                and t.value.id in ATOMIC_ARRAYS):
            return node
        if not isinstance(node.op, (ast.Add, ast.Sub)):
            raise ValueError(f"{t.value.id}: only += and -= can be made atomic")
        val = node.value if isinstance(node.op, ast.Add) else ast.UnaryOp(ast.USub(), node.value)
        add = ast.Name("_atomic_add", ast.Load())
        self.count += 1
        call = ast.Call(add, [ast.Name(t.value.id, ast.Load()), t.slice, val], [])
        return ast.copy_location(ast.Expr(call), node)


def _atomic_source(fn) -> tuple[str, int]:
    """The source of ``fn`` (a plain function or a Numba dispatcher) without decorators and
    with its writes into :data:`ATOMIC_ARRAYS` made atomic; and how many were."""
    py = getattr(fn, "py_func", fn)
    tree = ast.parse(textwrap.dedent(inspect.getsource(py)))
    tr = _AtomicAdds()
    tree = ast.fix_missing_locations(tr.visit(tree))
    return ast.unparse(tree), tr.count


@cuda.jit(device=True)
def _atomic_add(a, i, v):
    """cuda.atomic.add, as a function of this module (whose ``cuda`` the simulator swaps for
    its own when a kernel runs)."""
    cuda.atomic.add(a, i, v)


def _device_functions() -> dict:
    """:data:`ONE_SOURCE` as CUDA device functions, in a namespace of plate3d's globals in
    which the other sources are their device versions (and :func:`_atomic_add`)."""
    ns = dict(vars(P))
    ns["_atomic_add"] = _atomic_add
    ns["math"] = math
    ns["np"] = np
    out = {}
    for name in ONE_SOURCE:
        src, _ = _atomic_source(getattr(P, name))
        exec(compile(src, f"<gpu3d:{name}>", "exec"), ns)  # noqa: S102 - our own source
        ns[name] = out[name] = cuda.jit(device=True)(ns[name])
    return out


_D = _device_functions()
_ghost_one = _D["_ghost_one"]
_boundary_one = _D["_boundary_one"]
_boundary_fin = _D["_boundary_fin"]
_strain_one = _D["_strain_one"]
_dp_one = _D["_dp_one"]
_psig_one = _D["_psig_one"]
_accel_one = _D["_accel_one"]
_kick_one = _D["_kick_one"]
_side_one = _D["_side_one"]
_disp2_one = _D["_disp2_one"]
_place_marker = _D["_place_marker"]
_F_H, _F_GZ, _F_C0, _F_AVA, _F_AVB, _F_HALFT = P.F_H, P.F_GZ, P.F_C0, P.F_AVA, P.F_AVB, P.F_HALFT
_W3D = P._W3D


def _blocks(n: int) -> int:
    b = max((n + TPB - 1) // TPB, 1)
    return min(b, SIM_BLOCKS) if SIM else b


# --------------------------------------------------------------------------------- kernels
@cuda.jit
def _k_pose(pose, s, fp):
    """The step's plate pose into fp (one thread): centre, chord direction, velocities."""
    if cuda.grid(1) == 0:
        fp[P.F_CX] = pose[s, 0]
        fp[P.F_CZ] = pose[s, 1]
        fp[P.F_UX] = math.cos(pose[s, 2])
        fp[P.F_UZ] = math.sin(pose[s, 2])
        fp[P.F_VX] = pose[s, 3]
        fp[P.F_VZ] = pose[s, 4]
        fp[P.F_OM] = pose[s, 5]


@cuda.jit
def _k_place(pos, vel, wn, bo, bn, lidx, fp):
    for kk in range(cuda.grid(1), lidx.shape[0], cuda.gridsize(1)):
        _place_marker(kk, pos, vel, wn, bo, bn, lidx, fp)


@cuda.jit
def _k_sides(pos, kind, side, fp, ip):
    for i in range(cuda.grid(1), ip[P.I_NR], cuda.gridsize(1)):
        _side_one(i, pos, kind, side, fp, ip)


@cuda.jit
def _k_disp2(pos, pb, kind, nr, out):
    """The largest squared displacement since the lists were built into out[0] (zeroed by
    the caller)."""
    for i in range(cuda.grid(1), nr, cuda.gridsize(1)):
        d = _disp2_one(i, pos, pb, kind)
        if d > 0.0:
            cuda.atomic.max(out, 0, d)


@cuda.jit
def _k_ghosts(pos, vel, gv, rho, mass, sig, kind, nz, wn, dcl, grd, side, src, gs, go, ip):
    nr = ip[P.I_NR]
    for g in range(nr + cuda.grid(1), nr + ip[P.I_NG], cuda.gridsize(1)):
        _ghost_one(g, pos, vel, gv, rho, mass, sig, kind, nz, wn, dcl, grd, side, src, gs, go)


@cuda.jit
def _k_zero_rows(a, n):
    for i in range(cuda.grid(1), n, cuda.gridsize(1)):
        for c in range(a.shape[1]):
            a[i, c] = 0.0


@cuda.jit
def _k_boundary(pos, vel, rho, sig, kind, wn, dcl, sb, sbo, wsb, reuse, bacc, fp, ip):
    h = fp[_F_H]
    n = ip[P.I_NR] + ip[P.I_NG]
    for f in range(cuda.grid(1), n, cuda.gridsize(1)):
        _boundary_one(f, pos, vel, rho, sig, kind, wn, dcl, sb, sbo, wsb, reuse, bacc, h,
                      fp[_F_GZ], ip[P.I_NR], 4.0 * h * h, _W3D / (h * h * h))


@cuda.jit
def _k_boundary_fin(vel, gv, sig, kind, bacc, nr):
    for w in range(cuda.grid(1), nr, cuda.gridsize(1)):
        _boundary_fin(w, vel, gv, sig, kind, bacc)


@cuda.jit
def _k_strain(pos, vel, gv, rho, mass, kind, wn, dcl, side, ss, sso, sb, sbo, fss, fsb, lg, fp,
              ip):
    h = fp[_F_H]
    nr = ip[P.I_NR]
    for a in range(cuda.grid(1), nr, cuda.gridsize(1)):
        _strain_one(a, pos, vel, gv, rho, mass, kind, wn, dcl, side, ss, sso, sb, sbo, fss, fsb,
                    lg, nr, 4.0 * h * h, -5.0 * _W3D / (h * h * h * h * h), 1.0 / h)


@cuda.jit
def _k_dp(rho, sig, kind, lg, fp, nr):
    for i in range(cuda.grid(1), nr, cuda.gridsize(1)):
        _dp_one(i, rho, sig, kind, lg, fp)


@cuda.jit
def _k_psig(rho, sig, psig, n):
    for i in range(cuda.grid(1), n, cuda.gridsize(1)):
        _psig_one(i, rho, sig, psig)


@cuda.jit
def _k_accel(pos, vel, rho, mass, psig, kind, nz, wn, dcl, grd, ss, sso, sb, sbo, fss, fsb, acc,
             cont, fp, ip):
    h = fp[_F_H]
    nr = ip[P.I_NR]
    for a in range(cuda.grid(1), nr, cuda.gridsize(1)):
        _accel_one(a, pos, vel, rho, mass, psig, kind, nz, wn, dcl, grd, ss, sso, sb, sbo, fss,
                   fsb, acc, cont, h, h * h, fp[_F_C0], fp[_F_AVA], fp[_F_AVB], fp[_F_HALFT],
                   ip[P.I_ARC] != 0, nr, fp)


@cuda.jit
def _k_kick(pos, vel, mass, rho, sig, kind, acc, cont, fdamp, fp, ip, forces, s, flags):
    """Kick and drift; the force on the plate summed into forces[s] (atomics); lost grains
    counted in flags[0], the highest index of a particle gone bad in flags[1] (-1: none)."""
    for i in range(cuda.grid(1), ip[P.I_NR], cuda.gridsize(1)):
        fx, fy, fz, lost, bad = _kick_one(i, pos, vel, mass, rho, sig, kind, acc, cont, fdamp,
                                          fp, ip)
        if fx != 0.0 or fy != 0.0 or fz != 0.0:
            cuda.atomic.add(forces, (s, 0), fx)
            cuda.atomic.add(forces, (s, 1), fy)
            cuda.atomic.add(forces, (s, 2), fz)
        if lost:
            cuda.atomic.add(flags, 0, 1)
        if bad:
            cuda.atomic.max(flags, 1, i)


# ------------------------------------------------------------------------------ the driver
#: Solver3D arrays the device reads or changes during steps (host -> device -> host).
STATE = ("pos", "vel", "gv", "rho", "mass", "sig", "kind", "nz", "wn", "dcl", "grd", "side",
         "src", "gs", "go", "pb", "ss", "sso", "sb", "sbo", "fss", "fsb", "wsb", "lg", "acc",
         "cont", "bacc", "psig", "fp", "ip")
#: Arrays the host's list rebuild changes (uploaded after each rebuild).
LISTS = ("src", "gs", "go", "ss", "sso", "sb", "sbo", "ip")
CONST = ("bo", "bn", "lidx")


def _rebuild(s) -> int:
    """The ghosts and pair lists from the device's positions and kinds, on the host with the
    CPU functions (s: the Solver3D, its host arrays; pos and kind of the real particles
    already downloaded). Returns OK, GHOSTS_FULL or PAIRS_FULL."""
    nr = s.nr
    ng = P._make_ghosts(s.pos, s.kind, s.src, s.gs, s.go, s.fp, s.ip)
    if ng < 0:
        return P.GHOSTS_FULL
    s.ip[P.I_NG] = ng
    g = slice(nr, nr + ng)
    src = s.src[g]
    s.pos[g] = s.gs[g] * s.pos[src] + s.go[g]  # the reflection of _ghost_one (z: 1 z + 0)
    s.kind[g] = s.kind[src]
    P._bin_cells(s.pos, s.kind, s.cell_start, s.cell_idx, s.rank, s.fp, s.ip)
    if not P._build_pairs(s.pos, s.kind, s.rank, s.cell_start, s.cell_idx, s.ss, s.sso, s.sb,
                          s.sbo, s.fp, s.ip):
        s.ip[P.I_BUILDS] = 0
        return P.PAIRS_FULL
    s.pb[:nr] = s.pos[:nr]
    s.ip[P.I_BUILDS] += 1
    return P.OK


def steps_gpu(s, pose, damp, out) -> tuple[int, int]:
    """:func:`~terradyn.sph.plate3d.steps3d` on the device for the Solver3D ``s``: len(pose)
    steps, forces into out (len(pose), 3). The state goes up at the start and comes back at
    the end (also when a step stops early: instability, lists or ghosts full). Returns
    (steps done, code)."""
    d = {k: cuda.to_device(np.ascontiguousarray(getattr(s, k))) for k in STATE + CONST}
    nsteps = len(pose)
    pose_d = cuda.to_device(pose)
    forces = cuda.to_device(np.zeros((nsteps, 3)))
    flags = cuda.to_device(np.array([0, -1], np.int64))
    disp = cuda.device_array(1, np.float64)
    nr = s.nr
    thr = (0.5 * P.SKIN * s.h) ** 2
    nl = len(s.lidx)
    has_plate = bool(s.ip[P.I_PLATE])
    ip = s.ip  # the host copy: nr, ng and the build count are decided here
    lost0 = int(ip[P.I_LOST])
    done, code = 0, P.OK
    B = _blocks
    for k in range(nsteps):
        _k_pose[1, 1](pose_d, k, d["fp"])
        if has_plate:
            _k_place[B(nl), TPB](d["pos"], d["vel"], d["wn"], d["bo"], d["bn"], d["lidx"], d["fp"])
            _k_sides[B(nr), TPB](d["pos"], d["kind"], d["side"], d["fp"], d["ip"])
        rebuild = ip[P.I_BUILDS] == 0
        if not rebuild:
            disp.copy_to_device(np.zeros(1))
            _k_disp2[B(nr), TPB](d["pos"], d["pb"], d["kind"], nr, disp)
            rebuild = disp.copy_to_host()[0] > thr
        if rebuild:
            d["pos"][:nr].copy_to_host(s.pos[:nr])
            d["kind"].copy_to_host(s.kind)
            code = _rebuild(s)
            if code != P.OK:
                break
            n_list = nr + int(ip[P.I_NG])
            used = {"ss": int(ip[P.I_NSS]), "sb": int(ip[P.I_NSB]), "sso": n_list + 1,
                    "sbo": n_list + 1, "src": n_list, "gs": n_list, "go": n_list,
                    "ip": len(ip)}
            for name in LISTS:  # only the part the passes read
                m = used[name]
                if m > 0:
                    d[name][:m].copy_to_device(getattr(s, name)[:m])
            d["pb"].copy_to_device(s.pb)
        n_all = nr + int(ip[P.I_NG])
        ghosts = (B(int(ip[P.I_NG])), TPB)
        gargs = (d["pos"], d["vel"], d["gv"], d["rho"], d["mass"], d["sig"], d["kind"], d["nz"],
                 d["wn"], d["dcl"], d["grd"], d["side"], d["src"], d["gs"], d["go"], d["ip"])
        bargs = (d["pos"], d["vel"], d["rho"], d["sig"], d["kind"], d["wn"], d["dcl"], d["sb"],
                 d["sbo"], d["wsb"])
        for reuse in (False, True):
            _k_ghosts[ghosts](*gargs)
            _k_zero_rows[B(nr), TPB](d["bacc"], nr)
            _k_boundary[B(n_all), TPB](*bargs, reuse, d["bacc"], d["fp"], d["ip"])
            _k_boundary_fin[B(nr), TPB](d["vel"], d["gv"], d["sig"], d["kind"], d["bacc"], nr)
            _k_ghosts[ghosts](*gargs)
            if not reuse:  # pass 1 between the two extrapolations
                _k_zero_rows[B(nr), TPB](d["lg"], nr)
                _k_strain[B(nr), TPB](d["pos"], d["vel"], d["gv"], d["rho"], d["mass"],
                                      d["kind"], d["wn"], d["dcl"], d["side"], d["ss"], d["sso"],
                                      d["sb"], d["sbo"], d["fss"], d["fsb"], d["lg"], d["fp"],
                                      d["ip"])
                _k_dp[B(nr), TPB](d["rho"], d["sig"], d["kind"], d["lg"], d["fp"], nr)
        _k_psig[B(n_all), TPB](d["rho"], d["sig"], d["psig"], n_all)
        _k_zero_rows[B(nr), TPB](d["acc"], nr)
        _k_accel[B(nr), TPB](d["pos"], d["vel"], d["rho"], d["mass"], d["psig"], d["kind"],
                             d["nz"], d["wn"], d["dcl"], d["grd"], d["ss"], d["sso"], d["sb"],
                             d["sbo"], d["fss"], d["fsb"], d["acc"], d["cont"], d["fp"], d["ip"])
        fdamp = 1.0 / (1.0 + damp[k] * s.dt)
        _k_kick[B(nr), TPB](d["pos"], d["vel"], d["mass"], d["rho"], d["sig"], d["kind"],
                            d["acc"], d["cont"], fdamp, d["fp"], d["ip"], forces, k, flags)
        done = k + 1
        fl = flags.copy_to_host()
        if fl[1] >= 0:
            ip[P.I_BAD] = int(fl[1])
            code = P.UNSTABLE
            break
    fl = flags.copy_to_host()
    for name in STATE:
        if name in LISTS:
            continue  # the host's lists, ghost maps and counters are the newest
        d[name].copy_to_host(getattr(s, name))
    ip[P.I_LOST] = lost0 + int(fl[0])
    out[:done] = forces.copy_to_host()[:done]
    return done, code
