"""GPU backend of the SPH solver (Numba CUDA): the one-source physics of
:mod:`terradyn.sph.physics` and :mod:`terradyn.sph.neighbours`, compiled as CUDA device
functions, in one-thread-per-particle loops; :class:`GPUBackend` has the interface of
:class:`terradyn.sph.cpu.CPUBackend` (``GPUBackend(solver)``, ``steps``, ``drop_lost``,
``to_host``).

Import this module only when the GPU backend is asked for: it imports ``numba.cuda``.
Under ``NUMBA_ENABLE_CUDASIM=1`` (set before numba.cuda is first imported) everything here
runs in Numba's CUDA simulator, on the CPU, without a GPU; that is how the tests check it.

Design:

* one source: every per-particle function in :data:`terradyn.sph.source.SOURCES` is compiled
  here with ``cuda.jit(device=True)`` (its global names re-bound to the device versions), and
  each ``@cuda.jit`` kernel below is a thin one-thread-per-particle wrapper around it;
* the particle state stays on the device across steps, in one (18, N) float64 array ``S``
  (rows :data:`ROWS`) plus ``kind``, ``fleg`` and ``bad``; per step only four numbers come back
  (the force on the leg Fx, Fz, torque, summed with atomics, and the count of unstable
  particles); the whole state is copied back when the host asks for it (snapshots,
  checkpoints, the end of a run, an instability);
* binning is a counting sort on the device: per-cell counts with atomics (each particle keeps
  the slot the atomic gave it), an exclusive scan of the counts (a scan per block, a one-block
  scan of the block sums, a pass adding them), a scatter, then each cell's ids are sorted (cells hold about two particles) so the cell lists, and with them the order of
  every neighbour sum, are the CPU's exactly: GPU runs are deterministic and differ from the
  CPU's by rounding only. Cells of more than :data:`MAX_CELL_SORT` particles (only the clamped
  edge cell where lost particles are parked can get there) are left in atomic order.
"""
from __future__ import annotations

import math
import sys
import types

import numpy as np
from numba import config, cuda

from .neighbours import (SKIN, SRT, SRT_NOX, SRT_NOZ, SRT_PXX, SRT_PXZ, SRT_PZZ, SRT_RHO,
                         SRT_VOL, SRT_VX, SRT_VZ, SRT_X, SRT_Z, SRTK, SRTK_DCL, SRTK_GRD,
                         SRTK_KIND, neighbour_list)
from .physics import FLEG_TQ, FLEG_X, FLEG_Z, Gravity, Grid, StrainPar
from .source import SOURCE_MODULES, SOURCES
from .state import (BODY, BODY_BNX, BODY_BNZ, BODY_BX, BODY_BZ, LOST, POSE_ALPHA, POSE_ANGLE,
                    POSE_HIP_AX, POSE_HIP_AZ, POSE_HIP_VX, POSE_HIP_VZ, POSE_HIP_X, POSE_HIP_Z,
                    POSE_OMEGA, SOIL)

SIM = bool(config.ENABLE_CUDASIM)
#: Threads per block. Every kernel loops over its items with a grid stride: on a GPU it is
#: launched with one thread per item; in the simulator, which runs every thread as a Python
#: thread (~0.2 ms each), with at most SIM_BLOCKS blocks, so a test step costs hundreds of
#: threads rather than thousands.
TPB = 32 if SIM else 128
SIM_BLOCKS = 2
#: The scan: SCAN_TPB threads per block, each scanning SCAN_CHUNK consecutive counts.
SCAN_TPB = 32 if SIM else 256
SCAN_CHUNK = 8 if SIM else 1
MAX_CELL_SORT = 128

#: Rows of the device state array ``S`` (host attribute names of :class:`Solver`).
ROWS = ("x", "z", "vx", "vz", "rho", "sxx", "szz", "sxz", "syy", "gvx", "gvz", "acc_x", "acc_z",
        "nox", "noz", "dcl", "guard", "mass")
(X, Z, VX, VZ, RHO, SXX, SZZ, SXZ, SYY, GVX, GVZ, AX, AZ, NOX, NOZ, DCL, GRD, MASS) = range(18)
#: Rows that the device changes (copied back by :meth:`GPUBackend.to_host`).
CHANGING = ROWS[:15]


def _device_functions() -> dict:
    """The one-source functions compiled as CUDA device functions: each plain function gets a
    namespace, the union of the modules that define sources (:data:`SOURCE_MODULES`: their
    constants, named tuples, math), in which the names of the other sources are their device
    versions."""
    ns = {}
    for mod in SOURCE_MODULES:
        ns.update(vars(sys.modules[mod]))
    out = {}
    for name, fn in SOURCES.items():
        f = types.FunctionType(fn.__code__, ns, name, fn.__defaults__, fn.__closure__)
        f.__doc__ = fn.__doc__
        ns[name] = out[name] = cuda.jit(device=True)(f)
    return out


_D = _device_functions()
_cell_of = _D["_cell_of"]
_boundary_one = _D["_boundary_one"]
_gather_one = _D["_gather_one"]
_regather_one = _D["_regather_one"]
_strain_stress_one = _D["_strain_stress_one"]
_accel_kick_one = _D["_accel_kick_one"]
_place_one = _D["_place_one"]
_side_one = _D["_side_one"]


def _blocks(n: int) -> int:
    b = max((n + TPB - 1) // TPB, 1)
    return min(b, SIM_BLOCKS) if SIM else b


# ------------------------------------------------------------------------------- binning
@cuda.jit
def _k_count(S, xmin, zmin, inv_cell, ncx, ncz, counts, cell_of, rank):
    for i in range(cuda.grid(1), cell_of.shape[0], cuda.gridsize(1)):
        c = _cell_of(S[0, i], S[1, i], xmin, zmin, inv_cell, ncx, ncz)
        cell_of[i] = c
        rank[i] = cuda.atomic.add(counts, c, 1)


@cuda.jit(device=True)
def _block_scan(tmp, j, t):
    """Inclusive Hillis-Steele scan of the block's SCAN_TPB values tmp[j - t .. j - t +
    SCAN_TPB) (thread t holds tmp[j]); every thread of the block must call it. Returns
    thread t's inclusive sum."""
    cuda.syncthreads()
    off = 1
    while off < SCAN_TPB:
        a = 0
        if t >= off:
            a = tmp[j - off]
        cuda.syncthreads()
        tmp[j] += a
        cuda.syncthreads()
        off *= 2
    return tmp[j]


@cuda.jit
def _k_scan_blocks(counts, incl, bsum, tmp, chunk):
    """Inclusive scan of counts into ``incl``, per block of SCAN_TPB x ``chunk`` counts: each
    thread scans ``chunk`` consecutive counts, the block's SCAN_TPB thread sums are scanned
    (Hillis-Steele in ``tmp``, global memory: __syncthreads orders a block's global memory
    accesses too, and Numba's simulator allocates shared arrays racily), each thread adds
    the offset of its chunk; the block's total goes to bsum[block]. Counts are zeroed for
    the next step once read."""
    t = cuda.threadIdx.x
    b = cuda.blockIdx.x
    n = counts.shape[0]
    j = b * SCAN_TPB + t
    lo = j * chunk
    hi = min(lo + chunk, n)
    s = 0
    for c in range(lo, hi):
        s += counts[c]
        counts[c] = 0
        incl[c] = s
    tmp[j] = s
    pre = _block_scan(tmp, j, t) - s
    for c in range(lo, hi):
        incl[c] += pre
    if t == SCAN_TPB - 1:
        bsum[b] = tmp[j]


@cuda.jit
def _k_scan_sums(bsum, nb, tmp, acc):
    """Exclusive scan of bsum[:nb] in place, by one block of SCAN_TPB threads: each thread
    sums a chunk, the chunk sums are scanned (in ``tmp``), each thread then writes its
    chunk. Also zeroes ``acc`` (the step's sums)."""
    t = cuda.threadIdx.x
    if t < acc.shape[0]:
        acc[t] = 0.0
    chunk = (nb + SCAN_TPB - 1) // SCAN_TPB
    lo = t * chunk
    hi = min(lo + chunk, nb)
    s = 0
    for b in range(lo, hi):
        s += bsum[b]
    tmp[t] = s
    run = _block_scan(tmp, t, t) - s
    for b in range(lo, hi):
        v = bsum[b]
        bsum[b] = run
        run += v


@cuda.jit
def _k_scan_finish(incl, bsum, cell_start, per_block):
    for c in range(cuda.grid(1), incl.shape[0], cuda.gridsize(1)):
        cell_start[c + 1] = incl[c] + bsum[c // per_block]
    if cuda.grid(1) == 0:
        cell_start[0] = 0


@cuda.jit
def _k_scatter(cell_of, rank, cell_start, cell_index):
    for i in range(cuda.grid(1), cell_of.shape[0], cuda.gridsize(1)):
        cell_index[cell_start[cell_of[i]] + rank[i]] = i


@cuda.jit
def _k_sort_cells(cell_start, cell_index):
    """Insertion sort of each cell's ids (ascending, as the CPU's stable counting sort)."""
    for c in range(cuda.grid(1), cell_start.shape[0] - 1, cuda.gridsize(1)):
        lo = cell_start[c]
        hi = cell_start[c + 1]
        if hi - lo > 1 and hi - lo <= MAX_CELL_SORT:
            for a in range(lo + 1, hi):
                v = cell_index[a]
                b = a - 1
                while b >= lo and cell_index[b] > v:
                    cell_index[b + 1] = cell_index[b]
                    b -= 1
                cell_index[b + 1] = v


class DeviceBins:
    """Device buffers and launches of the counting sort for a grid of ncx x ncz cells and n
    particles. :meth:`run` bins the points (S[0], S[1]) and zeroes ``acc``."""

    def __init__(self, n: int, ncx: int, ncz: int):
        nc = ncx * ncz
        self.n, self.nc = n, nc
        self.counts = cuda.to_device(np.zeros(nc, np.int32))  # zeroed again by each scan
        self.incl = cuda.device_array(nc, np.int32)
        self.per_block = SCAN_TPB * SCAN_CHUNK
        self.nblk = max((nc + self.per_block - 1) // self.per_block, 1)
        self.bsum = cuda.device_array(self.nblk, np.int32)
        self.tmp = cuda.device_array(self.nblk * SCAN_TPB, np.int32)
        self.cell_start = cuda.device_array(nc + 1, np.int32)
        self.cell_index = cuda.device_array(max(n, 1), np.int32)
        self.cell_of = cuda.device_array(max(n, 1), np.int32)
        self.rank = cuda.device_array(max(n, 1), np.int32)

    def run(self, S, xmin, zmin, inv_cell, ncx, ncz, acc):
        n, nc = self.n, self.nc
        if n:
            _k_count[_blocks(n), TPB](S, float(xmin), float(zmin), float(inv_cell), int(ncx),
                                      int(ncz), self.counts, self.cell_of, self.rank)
        _k_scan_blocks[self.nblk, SCAN_TPB](self.counts, self.incl, self.bsum, self.tmp,
                                            SCAN_CHUNK)
        _k_scan_sums[1, SCAN_TPB](self.bsum, self.nblk, self.tmp, acc)
        _k_scan_finish[_blocks(nc), TPB](self.incl, self.bsum, self.cell_start,
                                         self.per_block)
        if n:
            _k_scatter[_blocks(n), TPB](self.cell_of, self.rank, self.cell_start,
                                        self.cell_index)
        _k_sort_cells[_blocks(nc), TPB](self.cell_start, self.cell_index)


def bin_particles(x, z, xmin, zmin, inv_cell, ncx, ncz):
    """:func:`terradyn.sph.neighbours.bin_particles` on the device (for tests): returns host
    (cell_start, cell_index)."""
    n = len(x)
    S = cuda.to_device(np.ascontiguousarray(np.stack([x, z]), dtype=np.float64))
    b = DeviceBins(n, ncx, ncz)
    acc = cuda.device_array(4, np.float64)
    b.run(S, xmin, zmin, inv_cell, ncx, ncz, acc)
    return b.cell_start.copy_to_host(), b.cell_index.copy_to_host()[:n]


# ------------------------------------------------------------------------------- physics
@cuda.jit
def _k_place(S, lidx, body, c, s, hip_x, hip_z, hip_vx, hip_vz, hip_ax, hip_az, omega, alpha):
    for kk in range(cuda.grid(1), lidx.shape[0], cuda.gridsize(1)):
        _place_one(kk, c, s, S[X], S[Z], S[VX], S[VZ], S[AX], S[AZ], S[NOX], S[NOZ], lidx,
                   body[BODY_BX], body[BODY_BZ], body[BODY_BNX], body[BODY_BNZ], hip_x, hip_z,
                   hip_vx, hip_vz, hip_ax, hip_az, omega, alpha)


@cuda.jit
def _k_sides(S, kind, cl, hip_x, hip_z, c, s, box, reach2):
    for i in range(cuda.grid(1), kind.shape[0], cuda.gridsize(1)):
        _side_one(i, S[X], S[Z], kind, S[DCL], cl, hip_x, hip_z, c, s, box, reach2)


@cuda.jit
def _k_boundary(S, kind, bidx, grav, grid, cell_start, cell_index, noslip, bj, bn, build):
    for kk in range(cuda.grid(1), bidx.shape[0], cuda.gridsize(1)):
        _boundary_one(kk, S[X], S[Z], S[VX], S[VZ], S[RHO], kind, S[NOX], S[NOZ], S[DCL],
                      S[SXX], S[SZZ], S[SXZ], S[SYY], S[GVX], S[GVZ], bidx, S[AX], S[AZ], grav,
                      grid, cell_start, cell_index, noslip, bj, bn, build)


@cuda.jit
def _k_gather(cell_index, S, kind, srt, srtk):
    for k in range(cuda.grid(1), cell_index.shape[0], cuda.gridsize(1)):
        _gather_one(k, cell_index, S[X], S[Z], S[VX], S[VZ], S[GVX], S[GVZ], S[RHO], S[MASS],
                    kind, S[NOX], S[NOZ], S[DCL], S[GRD], S[SXX], S[SZZ], S[SXZ], srt, srtk)


@cuda.jit
def _k_regather(cell_index, S, kind, srt):
    for k in range(cuda.grid(1), cell_index.shape[0], cuda.gridsize(1)):
        _regather_one(k, cell_index, S[VX], S[VZ], S[GVX], S[GVZ], S[RHO], S[MASS], kind,
                      S[SXX], S[SZZ], S[SXZ], srt)


@cuda.jit
def _k_strain(srt, srtk, cell_index, cell_start, S, vj, vn, nbj, nbw, nbn, par):
    for k in range(cuda.grid(1), cell_index.shape[0], cuda.gridsize(1)):
        _strain_stress_one(k, srt[SRT_X], srt[SRT_Z], srt[SRT_VX], srt[SRT_VZ], srt[SRT_VOL],
                           srt[SRT_RHO], srt[SRT_NOX], srt[SRT_NOZ], srtk[SRTK_KIND],
                           srtk[SRTK_DCL], cell_index, cell_start, S[RHO], S[SXX], S[SZZ],
                           S[SXZ], S[SYY], vj, vn, nbj, nbw, nbn, par)


@cuda.jit
def _k_disp(S, xb, zb, dmax, acc):
    """dmax[0] = max over particles of the squared distance from the last list build (see
    :func:`terradyn.sph.neighbours.max_displacement2`); dmax[0] must be 0 before. Also zeroes
    ``acc`` (the step's sums; the binning, which did that, no longer runs every step)."""
    t = cuda.grid(1)
    if t < acc.shape[0]:
        acc[t] = 0.0
    for i in range(cuda.grid(1), xb.shape[0], cuda.gridsize(1)):
        dx = S[X, i] - xb[i]
        dz = S[Z, i] - zb[i]
        d2 = dx * dx + dz * dz
        if not d2 < 1e300:
            d2 = 1e300
        cuda.atomic.max(dmax, 0, d2)


@cuda.jit
def _k_mark(S, xb, zb):
    """Remember the positions of a list build."""
    for i in range(cuda.grid(1), xb.shape[0], cuda.gridsize(1)):
        xb[i] = S[X, i]
        zb[i] = S[Z, i]


@cuda.jit
def _k_accel(srt, srtk, cell_index, cell_start, S, fleg, bad, nbj, nbw, nbn, par, acc):
    """Pass 2 for one particle; acc[0:3] += its force on the leg, acc[3] += 1 if unstable."""
    for k in range(cuda.grid(1), cell_index.shape[0], cuda.gridsize(1)):
        nb = _accel_kick_one(k, srt[SRT_X], srt[SRT_Z], srt[SRT_VX], srt[SRT_VZ], srt[SRT_PXX],
                             srt[SRT_PZZ], srt[SRT_PXZ], srt[SRT_VOL], srt[SRT_RHO],
                             srt[SRT_NOX], srt[SRT_NOZ], srtk[SRTK_KIND], srtk[SRTK_DCL],
                             srtk[SRTK_GRD], cell_index,
                             cell_start, S[MASS], S[X], S[Z], S[VX], S[VZ], S[RHO], S[SXX],
                             S[SZZ], S[SYY], fleg, bad, (nbj, nbw, nbn), par)
        if nb != 0:
            cuda.atomic.add(acc, 3, 1.0)
        if srtk[SRTK_KIND, k] == SOIL:
            i = cell_index[k]
            fx = fleg[i, FLEG_X]
            fz = fleg[i, FLEG_Z]
            tq = fleg[i, FLEG_TQ]
            if fx != 0.0 or fz != 0.0 or tq != 0.0:
                cuda.atomic.add(acc, 0, fx)
                cuda.atomic.add(acc, 1, fz)
                cuda.atomic.add(acc, 2, tq)


@cuda.jit
def _k_drop(S, kind, fleg, x0, x1, z0, cnt):
    """Granular particles outside the container become LOST, parked at (1e3 + id, 1e3)."""
    for i in range(cuda.grid(1), kind.shape[0], cuda.gridsize(1)):
        if kind[i] != SOIL:
            continue
        x = S[X, i]
        z = S[Z, i]
        if x < x0 or x > x1 or z < z0:
            kind[i] = LOST
            S[X, i] = 1e3 + i
            S[Z, i] = 1e3
            for r in (VX, VZ, SXX, SZZ, SXZ, SYY):
                S[r, i] = 0.0
            fleg[i, FLEG_X] = 0.0
            fleg[i, FLEG_Z] = 0.0
            fleg[i, FLEG_TQ] = 0.0
            cuda.atomic.add(cnt, 0, 1)


# ------------------------------------------------------------------------------- backend
class GPUBackend:
    """Keeps a :class:`~terradyn.sph.solver.Solver`'s particles on the GPU and advances them.

    The solver's host arrays (:data:`terradyn.sph.solver.DEVICE_OWNED`) and the device state
    take turns holding the newer data: after :meth:`to_host` (which the solver's
    ``sync_to_host`` calls) the host's arrays are current and the next :meth:`steps` or
    :meth:`drop_lost` copies them, edits included, to the device first; after a step the
    device's are, until the next :meth:`to_host`. At construction the host's are current."""

    name = "gpu"

    def __init__(self, solver):
        self.s = s = solver
        n = s.n
        self.n = n
        self.S = cuda.device_array((len(ROWS), n), np.float64)
        self.kind = cuda.device_array(n, np.int8)
        self.fleg = cuda.device_array((n, 3), np.float64)
        self.bad = cuda.device_array(n, np.int8)
        self.srt = cuda.device_array((len(SRT), n), np.float64)
        self.srtk = cuda.device_array((len(SRTK), n), np.float64)
        self.nb = tuple(cuda.to_device(a) for a in neighbour_list(n, s.scene.config.hdx))
        self.xb = cuda.to_device(np.full(n, np.inf))  # positions at the last list build
        self.zb = cuda.to_device(np.full(n, np.inf))
        self.dmax = cuda.device_array(1, np.float64)
        self.builds = 0
        self.bins = DeviceBins(n, s.ncx, s.ncz)
        self.acc = cuda.device_array(4, np.float64)
        self.cnt = cuda.device_array(1, np.int32)
        bidx = np.concatenate([s.widx, s.lidx]).astype(np.int32)
        self.nbnd = len(bidx)
        self.bidx = cuda.to_device(bidx if len(bidx) else np.zeros(1, np.int32))
        self.bnb = tuple(cuda.to_device(a) for a in
                         neighbour_list(max(self.nbnd, 1), s.scene.config.hdx)[:2])
        self.nleg = len(s.lidx)
        leg = s.scene.leg
        if self.nleg:
            self.lidx = cuda.to_device(s.lidx.astype(np.int32))
            self.body = cuda.to_device(np.ascontiguousarray(
                np.stack([getattr(leg, r) for r in BODY]), dtype=np.float64))
        if s.sides:
            self.cl = cuda.to_device(np.ascontiguousarray(leg.centre, dtype=np.float64))
            self.clbox = cuda.to_device(leg.side_box(s.side_reach))
        self.host_current = True  # the solver's arrays hold the state: uploaded at first use

    # ---------------------------------------------------------------------- host <-> device
    def _upload(self) -> None:
        """Copy the solver's arrays to the device."""
        s = self.s
        self.S.copy_to_device(np.ascontiguousarray(np.stack([getattr(s, r) for r in ROWS]),
                                                   dtype=np.float64))
        self.kind.copy_to_device(np.ascontiguousarray(s.kind, dtype=np.int8))
        self.fleg.copy_to_device(np.ascontiguousarray(s.fleg, dtype=np.float64))
        self.bad.copy_to_device(np.ascontiguousarray(s.bad, dtype=np.int8))

    def to_host(self) -> None:
        """Bring the solver's arrays up to date: copy the device state into them (in place;
        ``sidx`` is replaced by the granular ids). A no-op while they are current."""
        if self.host_current:
            return
        s = self.s
        H = self.S.copy_to_host()
        for r, name in enumerate(CHANGING):
            getattr(s, name)[:] = H[r]
        s.kind[:] = self.kind.copy_to_host()
        s.fleg[:] = self.fleg.copy_to_host()
        s.bad[:] = self.bad.copy_to_host()
        s.cell_start[:] = self.bins.cell_start.copy_to_host()
        s.cell_index[:] = self.bins.cell_index.copy_to_host()[:self.n]
        s.sidx = np.flatnonzero(s.kind == SOIL).astype(np.int64)
        self.host_current = True

    def _to_device(self) -> None:
        """Before device work: if the solver's arrays are current (maybe edited), upload them;
        from then on the device holds the state."""
        if self.host_current:
            self._upload()
            self.host_current = False

    # ---------------------------------------------------------------------------- stepping
    def place(self, pose) -> None:
        """Put the leg at ``pose`` (a row of :data:`~.state.POSE`) and, with the resolved
        boundary, find the granular particles' sides of it."""
        self._to_device()
        if not self.nleg:
            return
        hip_x, hip_z = pose[POSE_HIP_X], pose[POSE_HIP_Z]
        hip_vx, hip_vz = pose[POSE_HIP_VX], pose[POSE_HIP_VZ]
        hip_ax, hip_az = pose[POSE_HIP_AX], pose[POSE_HIP_AZ]
        ang, omega, alpha = pose[POSE_ANGLE], pose[POSE_OMEGA], pose[POSE_ALPHA]
        _k_place[_blocks(self.nleg), TPB](self.S, self.lidx, self.body, math.cos(ang),
                                          math.sin(ang), hip_x, hip_z, hip_vx, hip_vz, hip_ax,
                                          hip_az, omega, alpha)
        if self.s.sides:
            _k_sides[_blocks(self.n), TPB](self.S, self.kind, self.cl, hip_x, hip_z,
                                           math.cos(ang), math.sin(ang), self.clbox,
                                           float(self.s.side_reach ** 2))

    def _boundaries(self, grav, grid, noslip, build):
        if self.nbnd:
            _k_boundary[_blocks(self.nbnd), TPB](self.S, self.kind, self.bidx, grav, grid,
                                                 self.bins.cell_start, self.bins.cell_index,
                                                 noslip, *self.bnb, build)

    def step(self, pose, damping):
        """Pass 1 and 2 of one step (the leg is placed already); returns (number of unstable
        particles, (Fx, Fz, torque) on the leg per unit depth)."""
        s = self.s
        self._to_device()
        mat = s.scene.material
        cfg = s.scene.config
        gx, gz = (float(g) for g in s.scene.gravity)
        h, dt = float(s.h), float(s.dt)
        xmin, zmin, inv_cell = float(s.xmin), float(s.zmin), float(s.inv_cell)
        ncx, ncz = int(s.ncx), int(s.ncz)
        n = self.n
        b = self.bins
        nb = _blocks(n)
        # Verlet list: rebuilt (and the cells re-binned) as on the CPU backend
        self.dmax.copy_to_device(np.zeros(1))
        _k_disp[nb, TPB](self.S, self.xb, self.zb, self.dmax, self.acc)
        build = bool(self.dmax.copy_to_host()[0] > (0.5 * SKIN * h) ** 2)
        if build:
            b.run(self.S, xmin, zmin, inv_cell, ncx, ncz, self.acc)
            _k_mark[nb, TPB](self.S, self.xb, self.zb)
            self.builds += 1
        grid = Grid(h=h, xmin=xmin, zmin=zmin, inv_cell=inv_cell, ncx=ncx, ncz=ncz)
        grav = Gravity(gx=gx, gz=gz)
        noslip = bool(cfg.noslip)
        self._boundaries(grav, grid, noslip, build)
        _k_gather[nb, TPB](b.cell_index, self.S, self.kind, self.srt, self.srtk)
        par = StrainPar(h=h, xmin=xmin, zmin=zmin, inv_cell=inv_cell, ncx=ncx, ncz=ncz, dt=dt,
                        shear_mod=float(mat.shear_modulus), bulk_mod=float(mat.bulk_modulus),
                        alpha_phi=float(mat.alpha_phi), k_c=float(mat.k_c),
                        rho_min=float(0.9 * mat.density), rho_max=float(1.1 * mat.density),
                        alpha_psi=float(mat.alpha_psi), rho_crit=float(mat.dilation_limit),
                        rlist=float((2.0 + SKIN) * h), build=build,
                        **mat.rate_constants)
        _k_strain[nb, TPB](self.srt, self.srtk, b.cell_index, b.cell_start, self.S, *self.nb,
                           par)
        self._boundaries(grav, grid, noslip, False)
        _k_regather[nb, TPB](b.cell_index, self.S, self.kind, self.srt)
        if pose is None:
            hip_x = hip_z = hip_vx = hip_vz = omega = 0.0
        else:
            hip_x, hip_z = pose[POSE_HIP_X], pose[POSE_HIP_Z]
            hip_vx, hip_vz = pose[POSE_HIP_VX], pose[POSE_HIP_VZ]
            omega = pose[POSE_OMEGA]
        par = SOURCES["_accel_par"](
            h, float(s.c0), float(cfg.av_alpha), float(cfg.av_beta), bool(cfg.av_boundary), gx,
            gz, hip_x, hip_z, hip_vx, hip_vz, omega, float(s.half_t), float(s.gap),
            float(0.1 * cfg.dx), xmin, zmin, inv_cell, ncx, ncz, dt, float(damping),
            float(s.vmax_allowed), float(s.wall_k), float(s.leg_mu))
        _k_accel[nb, TPB](self.srt, self.srtk, b.cell_index, b.cell_start, self.S, self.fleg,
                          self.bad, *self.nb[2:], par, self.acc)
        a = self.acc.copy_to_host()
        return int(a[3]), (float(a[0]), float(a[1]), float(a[2]))

    def steps(self, poses, dampings, forces):
        """Advance len(poses) steps, each launched from Python (see
        :meth:`terradyn.sph.cpu.CPUBackend.steps`); returns (steps done, unstable
        particles)."""
        leg = self.nleg > 0
        for i in range(len(poses)):
            pose = tuple(poses[i].tolist()) if leg else None
            if leg:
                self.place(pose)
            nbad, f = self.step(pose, float(dampings[i]))
            if nbad:
                return i, nbad
            if leg:
                forces[i] = f
        return len(poses), 0

    def drop_lost(self, box) -> int:
        """Granular particles outside the container box (x0, x1, z0) become LOST, on the
        device; returns how many."""
        self._to_device()
        x0, x1, z0 = (float(v) for v in box)
        self.cnt.copy_to_device(np.zeros(1, np.int32))
        _k_drop[_blocks(self.n), TPB](self.S, self.kind, self.fleg, x0, x1, z0, self.cnt)
        return int(self.cnt.copy_to_host()[0])


def available() -> bool:
    try:
        return bool(cuda.is_available())
    except Exception:  # noqa: BLE001 - a broken CUDA install counts as no GPU
        return False
