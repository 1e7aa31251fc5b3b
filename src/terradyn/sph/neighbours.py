"""Neighbour search of the SPH model: the cell grid, the Verlet lists, the counting sort of
the particles into cells, the cell-ordered copy the pair loops read, and the pair chunks of
the CPU's pair passes.

The per-particle pieces (:func:`_cell_xz`, :func:`_row_span`, :func:`_build_list`,
:func:`_gather_one`, ...) are one-source functions (:mod:`terradyn.sph.source`), compiled for
the CPU here and for the GPU by :mod:`terradyn.sph.gpu`; :func:`bin_particles`,
:func:`chunk_bounds` and :func:`max_displacement2` are the CPU's whole-array forms.
"""
from __future__ import annotations

from .._jitcache import bind_to_sources as _bind_cache

import math

import numba
import numpy as np
from numba import prange

from .source import FM as _FM
from .source import source as _source
from .state import SOIL

#: Cells per list radius: cell side = (2 + SKIN) h / REACH, a particle's list candidates
#: lie in the (2 REACH + 1)^2 cells around its own. With REACH = 2 the cells scanned cover
#: about 2 x the disc's area instead of 2.9 x with REACH = 1 (measured faster:
#: benchmarks/bench_sph.py).
REACH = 2
#: Verlet-list skin as a fraction of h: lists hold the particles within 2h + SKIN h and are
#: rebuilt when a particle has moved SKIN h / 2 (cells grow to (2 + SKIN) h / REACH).
SKIN = 0.2
#: Most chunks of the pair passes (a multiple of 4: balanced on 1, 2 and 4 threads).
MAX_CHUNKS = 64

#: Rows of the cell-ordered float copy ``srt`` (11, N) made by :func:`_gather_one`: position,
#: velocity (the ghost velocity for boundary particles), sigma / rho^2, volume m / rho,
#: density, outward normal.
SRT = ("x", "z", "vx", "vz", "pxx", "pzz", "pxz", "vol", "rho", "nox", "noz")
(SRT_X, SRT_Z, SRT_VX, SRT_VZ, SRT_PXX, SRT_PZZ, SRT_PXZ, SRT_VOL, SRT_RHO, SRT_NOX,
 SRT_NOZ) = range(len(SRT))
#: Rows of the cell-ordered copy ``srtk`` (3, N), stored as floats: kind, offset from the leg's
#: centre line (a granular particle's side of the leg, see physics._side_one), guard flag.
SRTK = ("kind", "dcl", "guard")
SRTK_KIND, SRTK_DCL, SRTK_GRD = range(len(SRTK))


@_source
def _cell_xz(xi, zi, xmin, zmin, inv_cell, ncx, ncz):
    """Column and row of the cell of a point; points outside the grid are clamped into the
    edge cells."""
    return (min(max(int((xi - xmin) * inv_cell), 0), ncx - 1),
            min(max(int((zi - zmin) * inv_cell), 0), ncz - 1))


@_source
def _cell_of(xi, zi, xmin, zmin, inv_cell, ncx, ncz):
    """Cell id of a point (see :func:`_cell_xz`)."""
    cx, cz = _cell_xz(xi, zi, xmin, zmin, inv_cell, ncx, ncz)
    return cz * ncx + cx


@_source
def _row_span(cx, cz, dz, ncx, ncz, cell_start):
    """Cell-ordered positions [lo, hi) of the particles in row cz + dz of the cells, columns
    cx - REACH .. cx + REACH (the cells of a row are contiguous in cell order); empty past
    the grid's edge."""
    iz = cz + dz
    if iz < 0 or iz >= ncz:
        return 0, 0
    c0x = max(cx - REACH, 0)
    c1x = min(cx + REACH, ncx - 1)
    return cell_start[iz * ncx + c0x], cell_start[iz * ncx + c1x + 1]


@_source
def _wanted(k, j, KND):
    """Whether column ``j`` belongs in granular column ``k``'s half list (the CPU's: each
    granular pair once): a granular ``j`` after ``k``, or any wall or leg particle."""
    return KND[j] != SOIL or j > k


@_source
def _build_list(k, xi, zi, cx, cz, X, Z, KND, half, rlist, ncx, ncz, cell_start, vj, vn):
    """Column ``k``'s Verlet list from the cells around (cx, cz): the columns within
    ``rlist`` of (xi, zi) (only those :func:`_wanted` if ``half``) to vj[k], their count to
    vn[k] (-1 if more than vj's width)."""
    rl2 = rlist * rlist
    maxn = vj.shape[1]
    cnt = 0
    for dz in range(-REACH, REACH + 1):
        lo, hi = _row_span(cx, cz, dz, ncx, ncz, cell_start)
        for j in range(lo, hi):
            if half and not _wanted(k, j, KND):
                continue
            rx = xi - X[j]
            rz = zi - Z[j]
            if rx * rx + rz * rz < rl2:
                if cnt < maxn:
                    vj[k, cnt] = j
                cnt += 1
    vn[k] = cnt if cnt <= maxn else -1


@_source
def _gather_one(k, cell_index, x, z, vx, vz, gvx, gvz, rho, mass, kind, nox, noz, dcl, guard,
                sxx, szz, sxz, out_f, out_k):
    """Column ``k`` (cell order) of the cell-ordered copy the pair loops read (rows
    :data:`SRT`, :data:`SRTK`; :func:`terradyn.sph.cpu.gather`)."""
    i = cell_index[k]
    r = rho[i]
    inv2 = 1.0 / (r * r)
    out_f[SRT_X, k] = x[i]
    out_f[SRT_Z, k] = z[i]
    if kind[i] == SOIL:
        out_f[SRT_VX, k] = vx[i]
        out_f[SRT_VZ, k] = vz[i]
    else:
        out_f[SRT_VX, k] = gvx[i]
        out_f[SRT_VZ, k] = gvz[i]
    out_f[SRT_PXX, k] = sxx[i] * inv2
    out_f[SRT_PZZ, k] = szz[i] * inv2
    out_f[SRT_PXZ, k] = sxz[i] * inv2
    out_f[SRT_VOL, k] = mass[i] / r
    out_f[SRT_RHO, k] = r
    out_f[SRT_NOX, k] = nox[i]
    out_f[SRT_NOZ, k] = noz[i]
    out_k[SRTK_KIND, k] = kind[i]
    out_k[SRTK_DCL, k] = dcl[i]
    out_k[SRTK_GRD, k] = guard[i]


@_source
def _regather_one(k, cell_index, vx, vz, gvx, gvz, rho, mass, kind, sxx, szz, sxz, out_f):
    """Column ``k`` of :func:`terradyn.sph.cpu.regather`: the rows that the stress update and
    the boundary extrapolation changed."""
    i = cell_index[k]
    r = rho[i]
    inv2 = 1.0 / (r * r)
    if kind[i] != SOIL:
        out_f[SRT_VX, k] = gvx[i]
        out_f[SRT_VZ, k] = gvz[i]
    out_f[SRT_PXX, k] = sxx[i] * inv2
    out_f[SRT_PZZ, k] = szz[i] * inv2
    out_f[SRT_PXZ, k] = sxz[i] * inv2
    out_f[SRT_VOL, k] = mass[i] / r
    out_f[SRT_RHO, k] = r


def neighbour_list(n: int, hdx: float):
    """Arrays of the neighbour lists: the Verlet list that pass 1 builds and uses (columns
    (n, maxn) int32, counts (n,) int32, -1: more than maxn candidates, both passes search the
    cells) and pass 2's list of the neighbours pass 1 found (columns, kernel-gradient factors
    (n, maxn), counts). maxn: 1.5 x the particles of a square lattice within the list radius
    (pi ((2 + SKIN) hdx)^2), room for strong compression."""
    maxn = int(math.ceil(1.5 * math.pi * ((2.0 + SKIN) * hdx) ** 2)) + 8
    return (np.zeros((n, maxn), np.int32), np.zeros(n, np.int32),
            np.zeros((n, maxn), np.int32), np.zeros((n, maxn), np.float64),
            np.zeros(n, np.int32))


@numba.njit(cache=True)
def chunk_bounds(cell_start, cell_index, kind, ncx, ncz, bounds):
    """Split the columns (cell order) for the pair passes into chunks of about equal numbers of
    granular particles (the work), each but the first at least as long as the furthest any
    column's candidates reach ahead in cell order (to the last particle of the cell REACH
    rows and columns on). Writes bounds[0..q] and returns q, the number of chunks: at most
    MAX_CHUNKS, a multiple of 4 when there are at least 4 (balanced on 1, 2 or 4 threads)."""
    n = cell_index.shape[0]
    span = 1
    for cz in range(ncz):
        z1 = min(cz + REACH, ncz - 1)
        for cx in range(ncx):
            c = cz * ncx + cx
            if cell_start[c + 1] == cell_start[c]:
                continue
            end = cell_start[z1 * ncx + min(cx + REACH, ncx - 1) + 1]
            span = max(span, end - cell_start[c])
    soil = np.empty(n + 1, np.int64)  # granular particles before column k
    soil[0] = 0
    for k in range(n):
        soil[k + 1] = soil[k] + (1 if kind[cell_index[k]] == SOIL else 0)
    q = min(max(n // span, 1), MAX_CHUNKS)
    if q >= 4:
        q -= q % 4
    while q > 1:
        bounds[0] = 0
        k = 0
        for c in range(1, q):  # cut where the granular count reaches c / q of the total
            goal = soil[n] * c // q
            k = max(k, bounds[c - 1] + (span if c > 1 else 1))
            while k < n and soil[k] < goal:
                k += 1
            bounds[c] = k
        bounds[q] = n
        if n - bounds[q - 1] >= span:
            return q
        q = q - 4 if q > 4 else q - 1
    bounds[0] = 0
    bounds[1] = n
    return 1


@numba.njit(parallel=True, fastmath=_FM, cache=True)
def max_displacement2(x, z, xb, zb):
    """Largest squared distance of a particle from where it was at the last list build
    (non-finite positions count as infinitely far)."""
    m = 0.0
    for i in prange(x.shape[0]):
        dx = x[i] - xb[i]
        dz = z[i] - zb[i]
        d2 = dx * dx + dz * dz
        if not d2 < 1e300:
            d2 = 1e300
        m = max(m, d2)
    return m


@numba.njit(cache=True)
def bin_particles(x, z, xmin, zmin, inv_cell, ncx, ncz, cell_start, cell_index):
    """Counting sort of particles into square cells (side = kernel support).

    cell_start: (ncx*ncz + 1,) int64 offsets; cell_index: (N,) particle ids sorted by cell
    (ascending ids within a cell). Particles outside the grid are clamped into the edge cells
    (still correct: every pair is tested by distance)."""
    n = x.shape[0]
    nc = ncx * ncz
    cell_of = np.empty(n, np.int64)
    for k in range(nc + 1):
        cell_start[k] = 0
    for i in range(n):
        c = _cell_of(x[i], z[i], xmin, zmin, inv_cell, ncx, ncz)
        cell_of[i] = c
        cell_start[c + 1] += 1
    for k in range(nc):
        cell_start[k + 1] += cell_start[k]
    fill = cell_start[:-1].copy()
    for i in range(n):
        c = cell_of[i]
        cell_index[fill[c]] = i
        fill[c] += 1

# Cached kernels above use jitted code and constants of other modules: make their on-disk
# cache stale when those change too (terradyn._jitcache; Numba checks only this file).
_bind_cache(globals(), 'terradyn.sph.source', 'terradyn.sph.state')
