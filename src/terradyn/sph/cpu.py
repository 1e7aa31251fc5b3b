"""The CPU backend of the SPH solver: the multi-threaded (``prange``) loops around the one-source
physics of :mod:`terradyn.sph.physics`, a whole block of steps in one compiled call
(:func:`cpu_steps`), and :class:`CPUBackend`, which advances a solver's host arrays with it.
"""
from __future__ import annotations

from .._jitcache import bind_to_sources as _bind_cache

import math

import numba
import numpy as np
from numba import prange

from .neighbours import (MAX_CHUNKS, REACH, SKIN, SRT_NOX, SRT_NOZ, SRT_PXX, SRT_PXZ, SRT_PZZ,
                         SRT_RHO, SRT_VOL, SRT_VX, SRT_VZ, SRT_X, SRT_Z, SRTK_DCL, SRTK_GRD,
                         SRTK_KIND, _build_list, _cell_xz, _gather_one, _regather_one, _row_span,
                         _wanted, bin_particles, chunk_bounds, max_displacement2, neighbour_list)
from .physics import (FLEG_TQ, FLEG_X, FLEG_Z, Gravity, Grid, StrainPar, _accel_pair, _accel_par,
                      _accel_pp, _boundary_one, _kick_one, _pair_fdw, _place_one, _side_one,
                      _strain_terms, _stress_term, _support, dp_update)
from .source import FM as _FM
from .state import (BODY, BODY_BNX, BODY_BNZ, BODY_BX, BODY_BZ, LOST, POSE_ALPHA, POSE_ANGLE,
                    POSE_HIP_AX, POSE_HIP_AZ, POSE_HIP_VX, POSE_HIP_VZ, POSE_HIP_X, POSE_HIP_Z,
                    POSE_OMEGA, SOIL)

#: Columns of the pair passes' (N, 5) buffer ``buf`` (rows by column, cell order): pass 1's
#: sums (d rho/dt, the velocity gradient L), then pass 2's accelerations in the first two.
BUF_DRHO, BUF_LXX, BUF_LXZ, BUF_LZX, BUF_LZZ = range(5)
BUF_AX, BUF_AZ = 0, 1
#: Columns of pass 2's (N, 3) contact scratch ``cont``: distance to the nearest guarded leg
#: surface and its outward normal.
CONT_DMIN, CONT_NX, CONT_NZ, CONT_LNX, CONT_LNZ = range(5)


# ------------------------------------------------- CPU: each granular pair visited once
# The CPU's two passes visit each granular-granular pair once, from its lower column, and add
# the pair's terms to both particles (Newton's third law: half the pair work of visiting it
# from both sides, as the GPU does, where scattered writes would need atomics). A granular
# particle's pairs with wall and leg particles act on it alone and are visited from its side.
# The writes to the other particle go to a shared buffer ``buf`` (N, 5), rows by column:
# columns are split into chunks at least ``span`` long (the furthest any column's list
# reaches ahead in cell order), so a chunk writes only into itself and the next one; the even
# chunks run in parallel, then the odd ones. No atomics, no per-thread copies, and the sums
# do not depend on the number of threads.

@numba.njit(inline="always", fastmath=True)
def _strain_half_pair(k, j, fdw, X, Z, VX, VZ, VOL, RHO, KND, buf, acc):
    """Pass 1 terms of the pair (k, j) (fdw != 0): returns k's updated sums (d rho, Lxx, Lxz,
    Lzx, Lzz); a granular j's go to buf[j] (see :func:`_strain_terms`)."""
    dvg, txx, txz, tzx, tzz = _strain_terms(X[k] - X[j], Z[k] - Z[j], VX[k] - VX[j],
                                            VZ[k] - VZ[j], fdw)
    if KND[j] == SOIL:
        voli = VOL[k]
        buf[j, BUF_DRHO] += voli * RHO[k] * dvg
        buf[j, BUF_LXX] -= voli * txx
        buf[j, BUF_LXZ] -= voli * txz
        buf[j, BUF_LZX] -= voli * tzx
        buf[j, BUF_LZZ] -= voli * tzz
    dr, gxx, gxz, gzx, gzz = acc
    volj = VOL[j]
    return (dr + volj * RHO[j] * dvg, gxx - volj * txx, gxz - volj * txz, gzx - volj * tzx,
            gzz - volj * tzz)


@numba.njit(inline="always", fastmath=True)
def _strain_half_one(k, X, Z, VX, VZ, VOL, RHO, NOX, NOZ, KND, DCL, cell_start, vj, vn, nbj,
                     nbw, nbn, buf, par):
    """Pass 1 for granular column ``k``: builds its half Verlet list if ``build`` (columns
    :func:`_wanted` within ``rlist``: vj, vn; -1 on overflow), visits its pairs, hands the
    ones inside the support to pass 2 (nbj, nbw, nbn; -1 on overflow: pass 2 searches the
    cells) and adds its sums to buf[k]. par: a :class:`~.physics.StrainPar` (its grid, list
    radius and build flag are read here)."""
    if KND[k] != SOIL:
        return
    h, xmin, zmin, inv_cell = par.h, par.xmin, par.zmin, par.inv_cell
    ncx, ncz, rlist, build = par.ncx, par.ncz, par.rlist, par.build
    sup2, dwc, inv_h = _support(h)
    xi = X[k]
    zi = Z[k]
    cx, cz = _cell_xz(xi, zi, xmin, zmin, inv_cell, ncx, ncz)
    if build:
        _build_list(k, xi, zi, cx, cz, X, Z, KND, True, rlist, ncx, ncz, cell_start, vj, vn)
    acc = (0.0, 0.0, 0.0, 0.0, 0.0)
    cnt = vn[k]
    nbn[k] = -1
    if cnt >= 0:
        m = 0
        for n in range(cnt):
            j = vj[k, n]
            fdw = _pair_fdw(j, xi - X[j], zi - Z[j], KND, NOX, NOZ, DCL, sup2, inv_h, dwc, DCL[k])
            if fdw != 0.0:
                acc = _strain_half_pair(k, j, fdw, X, Z, VX, VZ, VOL, RHO, KND, buf, acc)
                nbj[k, m] = j
                nbw[k, m] = fdw
                m += 1
        nbn[k] = m
    else:
        for dz in range(-REACH, REACH + 1):
            lo, hi = _row_span(cx, cz, dz, ncx, ncz, cell_start)
            for j in range(lo, hi):
                if _wanted(k, j, KND):
                    fdw = _pair_fdw(j, xi - X[j], zi - Z[j], KND, NOX, NOZ, DCL, sup2, inv_h,
                                    dwc, DCL[k])
                    if fdw != 0.0:
                        acc = _strain_half_pair(k, j, fdw, X, Z, VX, VZ, VOL, RHO, KND, buf,
                                                acc)
    dr, gxx, gxz, gzx, gzz = acc
    buf[k, BUF_DRHO] += dr
    buf[k, BUF_LXX] += gxx
    buf[k, BUF_LXZ] += gxz
    buf[k, BUF_LZX] += gzx
    buf[k, BUF_LZZ] += gzz


@numba.njit(inline="always", fastmath=True)
def _accel_half_pair(k, j, fdw, X, Z, VX, VZ, PXX, PZZ, PXZ, VOL, RHO, NOX, NOZ, KND, DCL, GRD,
                     pp, buf, acc):
    """Pass 2 terms of the pair (k, j): a granular j gets its share in buf[j] (minus the
    term per unit mass of k), a wall or leg j goes through :func:`_accel_pair`."""
    if KND[j] != SOIL:
        return _accel_pair(j, fdw, X, Z, VX, VZ, PXX, PZZ, PXZ, VOL, RHO, NOX, NOZ, KND, DCL,
                           GRD, pp, acc)
    tx, tz = _stress_term(j, fdw, X[k] - X[j], Z[k] - Z[j], VX, VZ, PXX, PZZ, PXZ, RHO, KND,
                          pp)
    mi = pp.mi
    buf[j, BUF_AX] -= mi * tx
    buf[j, BUF_AZ] -= mi * tz
    mj = VOL[j] * RHO[j]
    a_x, a_z, fx, fz, tq, dmin, pnx, pnz, lnx, lnz = acc
    return (a_x + mj * tx, a_z + mj * tz, fx, fz, tq, dmin, pnx, pnz, lnx, lnz)


@numba.njit(inline="always", fastmath=True)
def _accel_half_one(k, X, Z, VX, VZ, PXX, PZZ, PXZ, VOL, RHO, NOX, NOZ, KND, DCL, GRD,
                    cell_index, cell_start, mass, nbj, nbw, nbn, buf, fleg, cont, par):
    """Pass 2's pair sums of granular column ``k`` over its half list (see
    :func:`_strain_half_one`): accelerations to buf[k, 0:2], its force on the leg to
    fleg[i], the contact guard's nearest leg surface (dmin, nx, nz) and the summed normals of
    the leg particles it sees (:func:`terradyn.sph.physics._accel_pair`) to cont[k]."""
    if KND[k] != SOIL:
        return
    h = par.h
    sup2, dwc, inv_h = _support(h)
    i = cell_index[k]
    pp = _accel_pp(k, X, Z, VX, VZ, PXX, PZZ, PXZ, RHO, mass[i], par)
    xi = X[k]
    zi = Z[k]
    acc = (0.0, 0.0, 0.0, 0.0, 0.0, par.gap, 0.0, 0.0, 0.0, 0.0)  # see _accel_pair
    cnt = nbn[k]
    if cnt >= 0:
        for n in range(cnt):
            acc = _accel_half_pair(k, nbj[k, n], nbw[k, n], X, Z, VX, VZ, PXX, PZZ, PXZ, VOL,
                                   RHO, NOX, NOZ, KND, DCL, GRD, pp, buf, acc)
    else:
        cx, cz = _cell_xz(xi, zi, par.xmin, par.zmin, par.inv_cell, par.ncx, par.ncz)
        for dz in range(-REACH, REACH + 1):
            lo, hi = _row_span(cx, cz, dz, par.ncx, par.ncz, cell_start)
            for j in range(lo, hi):
                if _wanted(k, j, KND):
                    fdw = _pair_fdw(j, xi - X[j], zi - Z[j], KND, NOX, NOZ, DCL, sup2, inv_h,
                                    dwc, DCL[k])
                    if fdw != 0.0:
                        acc = _accel_half_pair(k, j, fdw, X, Z, VX, VZ, PXX, PZZ, PXZ, VOL,
                                               RHO, NOX, NOZ, KND, DCL, GRD, pp, buf, acc)
    a_x, a_z, fx, fz, tq, dmin, pnx, pnz, lnx, lnz = acc
    buf[k, BUF_AX] += a_x
    buf[k, BUF_AZ] += a_z
    fleg[i, FLEG_X] = fx
    fleg[i, FLEG_Z] = fz
    fleg[i, FLEG_TQ] = tq
    cont[k, CONT_DMIN] = dmin
    cont[k, CONT_NX] = pnx
    cont[k, CONT_NZ] = pnz
    cont[k, CONT_LNX] = lnx
    cont[k, CONT_LNZ] = lnz


# ------------------------------------------------------------------ CPU kernels (prange)
@numba.njit(cache=True)
def column_sums3(a):
    """(sum a[:, 0], sum a[:, 1], sum a[:, 2]) of an (N, 3) array, as floats (the leg force
    of a step; NumPy's sum costs ~40 us of dispatch on a few thousand rows)."""
    s0 = 0.0
    s1 = 0.0
    s2 = 0.0
    for i in range(a.shape[0]):
        s0 += a[i, FLEG_X]
        s1 += a[i, FLEG_Z]
        s2 += a[i, FLEG_TQ]
    return s0, s1, s2


@numba.njit(parallel=True, fastmath=True, cache=True)
def boundary_state(x, z, vx, vz, rho, mass, kind, nox, noz, dcl, sxx, szz, sxz, syy,
                   gvx, gvz, bidx, acc_x, acc_z, gx, gz, h,
                   xmin, zmin, inv_cell, ncx, ncz, cell_start, cell_index, noslip, bj, bn,
                   build):
    """Stress and ghost velocity of every boundary particle (ids ``bidx``) from the granular
    particles around it (Shepard average + hydrostatic term). acc_x/acc_z: (N,) wall
    accelerations. ``noslip``: ghost velocity 2 v_w - <v>; else <v> (free slip). bj, bn:
    the boundary particles' Verlet lists (rows as ``bidx``), rebuilt if ``build``."""
    grav = Gravity(gx=gx, gz=gz)
    grid = Grid(h=h, xmin=xmin, zmin=zmin, inv_cell=inv_cell, ncx=ncx, ncz=ncz)
    for kk in prange(bidx.shape[0]):
        _boundary_one(kk, x, z, vx, vz, rho, kind, nox, noz, dcl, sxx, szz, sxz, syy, gvx, gvz,
                      bidx, acc_x, acc_z, grav, grid, cell_start, cell_index, noslip, bj, bn,
                      build)


@numba.njit(parallel=True, fastmath=True, cache=True)
def gather(cell_index, x, z, vx, vz, gvx, gvz, rho, mass, kind, nox, noz, dcl, guard, sxx, szz,
           sxz, out_f, out_k):
    """Copy what the pair loop reads into cell order (contiguous neighbour ranges).

    out_f: (11, N) rows x, z, v_x, v_z (ghost velocity for boundary particles), sigma/rho^2
    (xx, zz, xz), volume m/rho, rho, nox, noz; out_k: (3, N) float rows kind, dcl, guard."""
    for k in prange(cell_index.shape[0]):
        _gather_one(k, cell_index, x, z, vx, vz, gvx, gvz, rho, mass, kind, nox, noz, dcl,
                    guard, sxx, szz, sxz, out_f, out_k)


@numba.njit(parallel=True, fastmath=True, cache=True)
def regather(cell_index, vx, vz, gvx, gvz, rho, mass, kind, sxx, szz, sxz, out_f):
    """Refresh the rows of :func:`gather`'s copy that the stress update and the boundary
    extrapolation changed (velocities of boundary particles, sigma/rho^2, volume, density);
    positions, normals and kinds have not moved since."""
    for k in prange(cell_index.shape[0]):
        _regather_one(k, cell_index, vx, vz, gvx, gvz, rho, mass, kind, sxx, szz, sxz, out_f)


@numba.njit(parallel=True, fastmath=True, cache=True)
def strain_stress(srt, srtk, cell_index, h, xmin, zmin, inv_cell, ncx, ncz, cell_start,
                  rho, sxx, szz, sxz, syy, dt, shear_mod, bulk_mod, alpha_phi, k_c, rho_min,
                  rho_max, alpha_psi, rho_crit, vj, vn, nbj, nbw, nbn, rlist, build, buf, bounds,
                  nchunk, mu_s=0.0, mu_rise=0.0, mu_i0=1.0, mu_dscale=0.0):
    """First pass (velocities only): d rho/dt and the velocity gradient L of every granular
    particle (lxx = dvx/dx, lxz = dvx/dz, ...), then its new density and stress
    (:func:`dp_update`). Reads only the cell-ordered copies made by :func:`gather`, so it can
    write the new state by particle id. vj, vn: the half Verlet lists, rebuilt from the cells
    if ``build`` with radius ``rlist``; nbj, nbw, nbn: pass 2's lists
    (:func:`neighbour_list`); buf: (N, 5) zeros, left zero; bounds, nchunk: the chunks of
    :func:`chunk_bounds`."""
    X = srt[SRT_X]
    Z = srt[SRT_Z]
    VX = srt[SRT_VX]
    VZ = srt[SRT_VZ]
    VOL = srt[SRT_VOL]
    RHO = srt[SRT_RHO]
    NOX = srt[SRT_NOX]
    NOZ = srt[SRT_NOZ]
    KND = srtk[SRTK_KIND]
    DCL = srtk[SRTK_DCL]
    par = StrainPar(h=h, xmin=xmin, zmin=zmin, inv_cell=inv_cell, ncx=ncx, ncz=ncz, dt=dt,
                    shear_mod=shear_mod, bulk_mod=bulk_mod, alpha_phi=alpha_phi, k_c=k_c,
                    rho_min=rho_min, rho_max=rho_max, alpha_psi=alpha_psi, rho_crit=rho_crit,
                    rlist=rlist, build=build, mu_s=mu_s, mu_rise=mu_rise, mu_i0=mu_i0,
                    mu_dscale=mu_dscale)
    for phase in range(2):
        for c in prange((nchunk + 1 - phase) // 2):
            cc = 2 * c + phase
            for k in range(bounds[cc], bounds[cc + 1]):
                _strain_half_one(k, X, Z, VX, VZ, VOL, RHO, NOX, NOZ, KND, DCL, cell_start, vj,
                                 vn, nbj, nbw, nbn, buf, par)
    for k in prange(cell_index.shape[0]):
        if KND[k] != SOIL:
            continue
        i = cell_index[k]
        rho[i], sxx[i], szz[i], sxz[i], syy[i] = dp_update(
            rho[i], buf[k, BUF_DRHO], buf[k, BUF_LXX], buf[k, BUF_LXZ], buf[k, BUF_LZX],
            buf[k, BUF_LZZ], sxx[i], szz[i],
            sxz[i], syy[i], dt, shear_mod, bulk_mod, alpha_phi, k_c, rho_min, rho_max, alpha_psi,
            rho_crit, mu_s, mu_rise, mu_i0, mu_dscale)
        for f in range(5):
            buf[k, f] = 0.0


@numba.njit(parallel=True, fastmath=_FM, cache=True)  # _FM: the NaN checks must stay
def accelerations_kick(srt, srtk, cell_index, mass, h, c0, av_alpha, av_beta, av_boundary, gx,
                       gz, hip_x, hip_z, hip_vx, hip_vz, omega, half_t, gap, max_push, xmin, zmin,
                       inv_cell, ncx, ncz, cell_start, x, z, vx, vz, rho, sxx, szz, syy, dt,
                       damping, vmax_allowed, wall_k, leg_mu, fleg, bad, nbj, nbw, nbn, buf, cont,
                       bounds,
                       nchunk):
    """Second pass (stresses): acceleration of every granular particle, the force it exerts on
    the leg (fleg[i] = (Fx, Fz, torque about (hip_x, hip_z)), per unit depth), and its kick and
    drift: v += dt a (optionally damped), x += dt v (symplectic Euler). The pair sums read
    only the cell-ordered copies made by :func:`gather`; the particles move after them.
    Returns the number of particles that went non-finite or faster than ``vmax_allowed``
    (``bad[i]`` = 1 for those). buf: (N, 5) zeros, left zero; cont: (N, 5) scratch; bounds,
    nchunk: the chunks of :func:`chunk_bounds`. Artificial
    viscosity acts between granular particles, and on wall/leg pairs only if ``av_boundary``:
    its stress ~ alpha rho c v scales with the (numerical) sound speed and would add a drag
    proportional to the leg speed that the material does not have.

    Penetration guard: a granular particle closer than ``gap`` to the leg's surface (half
    thickness ``half_t`` from its centre line, seen from a guarded leg particle: not at the
    tip) is moved back towards that distance after the drift (at most ``max_push`` per step),
    and loses the part of its velocity that moves it into the leg, relative to the leg's rigid
    velocity at its position (an inelastic contact, as for a grain meeting a rigid plate; the
    leg turns clockwise at ``omega`` about the hip, which moves at (hip_vx, hip_vz)). The
    momentum it loses, m (v.n) n / dt, is added to the force it exerts on the leg, so the guard
    never takes momentum out of the balance unrecorded (before it did, the C leg's lift came
    out at a third of RFT's)."""
    nbad = 0
    X = srt[SRT_X]
    Z = srt[SRT_Z]
    VX = srt[SRT_VX]
    VZ = srt[SRT_VZ]
    PXX = srt[SRT_PXX]
    PZZ = srt[SRT_PZZ]
    PXZ = srt[SRT_PXZ]
    VOL = srt[SRT_VOL]
    RHO = srt[SRT_RHO]
    NOX = srt[SRT_NOX]
    NOZ = srt[SRT_NOZ]
    KND = srtk[SRTK_KIND]
    DCL = srtk[SRTK_DCL]
    GRD = srtk[SRTK_GRD]
    par = _accel_par(h, c0, av_alpha, av_beta, av_boundary, gx, gz, hip_x, hip_z, hip_vx, hip_vz,
                     omega, half_t, gap, max_push, xmin, zmin, inv_cell, ncx, ncz, dt, damping,
                     vmax_allowed, wall_k, leg_mu)
    for phase in range(2):
        for c in prange((nchunk + 1 - phase) // 2):
            cc = 2 * c + phase
            for k in range(bounds[cc], bounds[cc + 1]):
                _accel_half_one(k, X, Z, VX, VZ, PXX, PZZ, PXZ, VOL, RHO, NOX, NOZ, KND, DCL,
                                GRD, cell_index, cell_start, mass, nbj, nbw, nbn, buf, fleg,
                                cont, par)
    for k in prange(cell_index.shape[0]):
        if KND[k] != SOIL:
            continue
        i = cell_index[k]
        acc = (buf[k, BUF_AX], buf[k, BUF_AZ], fleg[i, FLEG_X], fleg[i, FLEG_Z], fleg[i, FLEG_TQ],
               cont[k, CONT_DMIN], cont[k, CONT_NX], cont[k, CONT_NZ], cont[k, CONT_LNX],
               cont[k, CONT_LNZ])
        buf[k, BUF_AX] = 0.0
        buf[k, BUF_AZ] = 0.0
        nbad += _kick_one(i, X[k], Z[k], VX[k], VZ[k], acc, mass, x, z, vx, vz, rho, sxx, szz,
                          syy, fleg, bad, par)
    return nbad


@numba.njit(parallel=True, fastmath=True, cache=True)
def update_stress(rho, sxx, szz, sxz, syy, sidx, drho, lxx, lxz, lzx, lzz, dt, shear_mod,
                  bulk_mod, alpha_phi, k_c, rho_min, rho_max, alpha_psi=0.0, rho_crit=0.0,
                  mu_s=0.0, mu_rise=0.0, mu_i0=1.0, mu_dscale=0.0):
    """:func:`dp_update` for the granular particles ``sidx`` (the solver fuses it into
    :func:`strain_stress`; this form serves tests)."""
    for kk in prange(sidx.shape[0]):
        i = sidx[kk]
        rho[i], sxx[i], szz[i], sxz[i], syy[i] = dp_update(
            rho[i], drho[i], lxx[i], lxz[i], lzx[i], lzz[i], sxx[i], szz[i], sxz[i], syy[i], dt,
            shear_mod, bulk_mod, alpha_phi, k_c, rho_min, rho_max, alpha_psi, rho_crit, mu_s,
            mu_rise, mu_i0, mu_dscale)


@numba.njit(parallel=True, fastmath=True, cache=True)
def place_rigid(x, z, vx, vz, acc_x, acc_z, nox, noz, lidx, bx, bz, bnx, bnz,
                hip_x, hip_z, hip_vx, hip_vz, hip_ax, hip_az, ang, omega, alpha):
    """Place the leg particles ``lidx`` (body coordinates bx, bz; body outward normals bnx, bnz)
    at hip + R(ang) s with R = [[cos, sin], [-sin, cos]] (clockwise), rigid velocity and
    acceleration. omega is the clockwise angular speed d(ang)/dt, alpha its derivative."""
    c = math.cos(ang)
    s = math.sin(ang)
    for kk in prange(lidx.shape[0]):
        _place_one(kk, c, s, x, z, vx, vz, acc_x, acc_z, nox, noz, lidx, bx, bz, bnx, bnz,
                   hip_x, hip_z, hip_vx, hip_vz, hip_ax, hip_az, omega, alpha)


@numba.njit(parallel=True, fastmath=True, cache=True)
def leg_sides(x, z, kind, dcl, cl, hip_x, hip_z, ang, box, reach2):
    """:func:`_side_one` for every particle (the leg at angle ``ang`` about the hip)."""
    c = math.cos(ang)
    s = math.sin(ang)
    for i in prange(x.shape[0]):
        _side_one(i, x, z, kind, dcl, cl, hip_x, hip_z, c, s, box, reach2)


# ------------------------------------------------------------------- CPU: a block of steps
#: Scalars of :func:`cpu_steps` (float array ``fp``), by index.
FP = ("h", "xmin", "zmin", "inv_cell", "gx", "gz", "dt", "shear_mod", "bulk_mod", "alpha_phi",
      "k_c", "rho_min", "rho_max", "c0", "av_alpha", "av_beta", "half_t", "gap", "max_push",
      "vmax_allowed", "side_reach2", "alpha_psi", "rho_crit", "wall_k", "mu_s", "mu_rise", "mu_i0",
      "mu_dscale", "leg_mu")
#: Integers of :func:`cpu_steps` (int64 array ``ip``): grid size, flags, and two counters it
#: updates: the pair chunks and the list builds so far.
IP = ("ncx", "ncz", "noslip", "av_boundary", "has_leg", "nchunk", "builds", "sides")
(FP_H, FP_XMIN, FP_ZMIN, FP_INV_CELL, FP_GX, FP_GZ, FP_DT, FP_SHEAR_MOD, FP_BULK_MOD,
 FP_ALPHA_PHI, FP_K_C, FP_RHO_MIN, FP_RHO_MAX, FP_C0, FP_AV_ALPHA, FP_AV_BETA, FP_HALF_T, FP_GAP,
 FP_MAX_PUSH, FP_VMAX_ALLOWED, FP_SIDE_REACH2, FP_ALPHA_PSI, FP_RHO_CRIT, FP_WALL_K, FP_MU_S,
 FP_MU_RISE, FP_MU_I0, FP_MU_DSCALE, FP_LEG_MU) = range(len(FP))
(IP_NCX, IP_NCZ, IP_NOSLIP, IP_AV_BOUNDARY, IP_HAS_LEG, IP_NCHUNK, IP_BUILDS,
 IP_SIDES) = range(len(IP))


@numba.njit(cache=True)
def cpu_steps(poses, dampings, forces, x, z, vx, vz, rho, sxx, szz, sxz, syy, gvx, gvz, acc_x,
              acc_z, nox, noz, dcl, guard, mass, kind, fleg, bad, srt, srtk, cell_start,
              cell_index, bidx, lidx, body, xb, zb, vj, vn, nbj, nbw, nbn, bj, bn, buf, cont,
              bounds, fp, ip, cl, clbox):
    """Advance ``len(poses)`` steps in one call (no Python between steps): per step, place
    the leg at poses[s] = (hip x, z, vx, vz, ax, az, angle, omega, alpha) (if ip has_leg;
    body = its body coordinates and normals (4, n_leg)), rebuild the Verlet lists if a
    particle moved half the skin, extrapolate the boundary state, pass 1, boundary state
    again, pass 2 with damping ``dampings[s]``; forces[s] = (Fx, Fz, torque) on the leg per
    unit depth. Stops after a step in which a particle went unstable. Returns (steps done
    without instability, unstable particles in the last step)."""
    h = fp[FP_H]
    xmin = fp[FP_XMIN]
    zmin = fp[FP_ZMIN]
    inv_cell = fp[FP_INV_CELL]
    gx = fp[FP_GX]
    gz = fp[FP_GZ]
    dt = fp[FP_DT]
    shear_mod = fp[FP_SHEAR_MOD]
    bulk_mod = fp[FP_BULK_MOD]
    alpha_phi = fp[FP_ALPHA_PHI]
    k_c = fp[FP_K_C]
    rho_min = fp[FP_RHO_MIN]
    rho_max = fp[FP_RHO_MAX]
    alpha_psi = fp[FP_ALPHA_PSI]
    rho_crit = fp[FP_RHO_CRIT]
    c0 = fp[FP_C0]
    av_alpha = fp[FP_AV_ALPHA]
    av_beta = fp[FP_AV_BETA]
    half_t = fp[FP_HALF_T]
    gap = fp[FP_GAP]
    max_push = fp[FP_MAX_PUSH]
    vmax_allowed = fp[FP_VMAX_ALLOWED]
    side_reach2 = fp[FP_SIDE_REACH2]
    wall_k = fp[FP_WALL_K]
    leg_mu = fp[FP_LEG_MU]
    mu_s = fp[FP_MU_S]
    mu_rise = fp[FP_MU_RISE]
    mu_i0 = fp[FP_MU_I0]
    mu_dscale = fp[FP_MU_DSCALE]
    sides = ip[IP_SIDES] != 0
    ncx = ip[IP_NCX]
    ncz = ip[IP_NCZ]
    noslip = ip[IP_NOSLIP] != 0
    av_boundary = ip[IP_AV_BOUNDARY] != 0
    has_leg = ip[IP_HAS_LEG] != 0
    rlist = (2.0 + SKIN) * h
    thr = (0.5 * SKIN * h) ** 2
    for s in range(poses.shape[0]):
        hip_x = poses[s, POSE_HIP_X]
        hip_z = poses[s, POSE_HIP_Z]
        hip_vx = poses[s, POSE_HIP_VX]
        hip_vz = poses[s, POSE_HIP_VZ]
        hip_ax = poses[s, POSE_HIP_AX]
        hip_az = poses[s, POSE_HIP_AZ]
        ang = poses[s, POSE_ANGLE]
        omega = poses[s, POSE_OMEGA]
        alpha = poses[s, POSE_ALPHA]
        if has_leg:
            place_rigid(x, z, vx, vz, acc_x, acc_z, nox, noz, lidx, body[BODY_BX], body[BODY_BZ],
                        body[BODY_BNX], body[BODY_BNZ], hip_x, hip_z, hip_vx, hip_vz, hip_ax,
                        hip_az, ang, omega, alpha)
            if sides:
                leg_sides(x, z, kind, dcl, cl, hip_x, hip_z, ang, clbox, side_reach2)
        build = max_displacement2(x, z, xb, zb) > thr
        if build:
            bin_particles(x, z, xmin, zmin, inv_cell, ncx, ncz, cell_start, cell_index)
            ip[IP_NCHUNK] = chunk_bounds(cell_start, cell_index, kind, ncx, ncz, bounds)
            xb[:] = x
            zb[:] = z
            ip[IP_BUILDS] += 1
        nchunk = ip[IP_NCHUNK]
        if bidx.shape[0]:
            boundary_state(x, z, vx, vz, rho, mass, kind, nox, noz, dcl, sxx, szz, sxz, syy,
                           gvx, gvz, bidx, acc_x, acc_z, gx, gz, h, xmin, zmin, inv_cell, ncx,
                           ncz, cell_start, cell_index, noslip, bj, bn, build)
        gather(cell_index, x, z, vx, vz, gvx, gvz, rho, mass, kind, nox, noz, dcl, guard, sxx,
               szz, sxz, srt, srtk)
        strain_stress(srt, srtk, cell_index, h, xmin, zmin, inv_cell, ncx, ncz, cell_start,
                      rho, sxx, szz, sxz, syy, dt, shear_mod, bulk_mod, alpha_phi, k_c, rho_min,
                      rho_max, alpha_psi, rho_crit, vj, vn, nbj, nbw, nbn, rlist, build, buf,
                      bounds, nchunk, mu_s, mu_rise, mu_i0, mu_dscale)
        if bidx.shape[0]:
            boundary_state(x, z, vx, vz, rho, mass, kind, nox, noz, dcl, sxx, szz, sxz, syy,
                           gvx, gvz, bidx, acc_x, acc_z, gx, gz, h, xmin, zmin, inv_cell, ncx,
                           ncz, cell_start, cell_index, noslip, bj, bn, False)
        regather(cell_index, vx, vz, gvx, gvz, rho, mass, kind, sxx, szz, sxz, srt)
        nbad = accelerations_kick(
            srt, srtk, cell_index, mass, h, c0, av_alpha, av_beta, av_boundary, gx, gz, hip_x,
            hip_z, hip_vx, hip_vz, omega, half_t, gap, max_push, xmin, zmin, inv_cell, ncx, ncz,
            cell_start, x, z, vx, vz, rho, sxx, szz, syy, dt, dampings[s], vmax_allowed, wall_k,
            leg_mu, fleg, bad, nbj, nbw, nbn, buf, cont, bounds, nchunk)
        if nbad:
            return s, nbad
        if has_leg:
            forces[s, FLEG_X], forces[s, FLEG_Z], forces[s, FLEG_TQ] = column_sums3(fleg)
    return poses.shape[0], 0


class CPUBackend:
    """The solver's arrays on the host, advanced by the multi-threaded CPU loops of this module
    (a block of steps per call: :func:`cpu_steps`). The interface of every backend:
    ``Backend(solver)``, :meth:`steps`, :meth:`drop_lost`, :meth:`to_host` (here a no-op: the
    solver's arrays are the state), plus :meth:`state_dict` / :meth:`load_state` for
    checkpoints."""

    name = "cpu"

    def __init__(self, solver):
        self.s = s = solver
        n = solver.n
        hdx = solver.scene.config.hdx
        self.nb = neighbour_list(n, hdx)
        # every boundary particle (walls, then leg) in one kernel call
        self.bidx = np.concatenate([s.widx, s.lidx]).astype(np.int64)
        nbl = neighbour_list(max(len(self.bidx), 1), hdx)
        self.bj, self.bn = nbl[0], nbl[1]  # the boundary particles' Verlet lists
        self.xb = np.full(n, np.inf)  # positions at the last list build: none yet
        self.zb = np.full(n, np.inf)
        # the pair passes' buffer for the other particle of a pair, and their chunks
        self.buf = np.zeros((n, 5))
        self.cont = np.zeros((n, 5))
        self.bounds = np.zeros(MAX_CHUNKS + 1, np.int64)
        leg = s.scene.leg
        self.body = (np.ascontiguousarray(np.stack([getattr(leg, r) for r in BODY]),
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
                   vmax_allowed=s.vmax_allowed, side_reach2=s.side_reach ** 2,
                   alpha_psi=mat.alpha_psi, rho_crit=mat.dilation_limit, wall_k=s.wall_k,
                   leg_mu=s.leg_mu)
        val.update(mat.rate_constants)
        self.fp = np.array([val[k] for k in FP], dtype=np.float64)
        ival = dict(ncx=s.ncx, ncz=s.ncz, noslip=int(bool(cfg.noslip)),
                    av_boundary=int(bool(cfg.av_boundary)), has_leg=int(leg is not None),
                    nchunk=1, builds=0, sides=int(s.sides))
        self.ip = np.array([ival[k] for k in IP], dtype=np.int64)
        if s.sides:
            self.cl = np.ascontiguousarray(leg.centre, dtype=np.float64)
            self.clbox = leg.side_box(s.side_reach)
        else:
            self.cl = np.zeros((2, 2))
            self.clbox = np.zeros(4)

    @property
    def builds(self) -> int:
        """Verlet-list builds so far."""
        return int(self.ip[IP_BUILDS])

    def steps(self, poses, dampings, forces):
        """Advance len(poses) steps (poses: (n, 9) rows of :data:`~.state.POSE`; dampings (n,);
        forces (n, 3), written: the force on the leg per step; see :func:`cpu_steps`); returns
        (steps done, unstable particles in the last step)."""
        s = self.s
        done, nbad = cpu_steps(
            poses, dampings, forces, s.x, s.z, s.vx, s.vz, s.rho, s.sxx, s.szz, s.sxz, s.syy,
            s.gvx, s.gvz, s.acc_x, s.acc_z, s.nox, s.noz, s.dcl, s.guard, s.mass, s.kind, s.fleg,
            s.bad, s.srt, s.srtk, s.cell_start, s.cell_index, self.bidx, s.lidx, self.body,
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
        for i in (IP_NCHUNK, IP_BUILDS):
            self.ip[i] = d["ip"][i]
        vj = np.asarray(d["vj"])
        self.nb[0][:, :vj.shape[1]] = vj
        self.nb[1][:] = d["vn"]
        bj = np.asarray(d["bj"])
        self.bj[:, :bj.shape[1]] = bj
        self.bn[:] = d["bn"]

    def drop_lost(self, box) -> int:
        """Granular particles outside the container box (x0, x1, z0) become LOST, parked far
        away; returns how many."""
        s = self.s
        x0, x1, z0 = box
        sidx = s.sidx
        out = (s.x[sidx] < x0) | (s.x[sidx] > x1) | (s.z[sidx] < z0)
        if not out.any():
            return 0
        ids = sidx[out]
        s.kind[ids] = LOST
        s.x[ids] = 1e3 + np.arange(len(ids))  # beyond every kernel support
        s.z[ids] = 1e3
        for a in (s.vx, s.vz, s.sxx, s.szz, s.sxz, s.syy):
            a[ids] = 0.0
        s.fleg[ids] = 0.0
        s.sidx = np.flatnonzero(s.kind == SOIL).astype(np.int64)
        return len(ids)

    def to_host(self) -> None:
        """The solver's arrays are the state: nothing to copy."""

# Cached kernels above use jitted code and constants of other modules: make their on-disk
# cache stale when those change too (terradyn._jitcache; Numba checks only this file).
_bind_cache(globals(), 'terradyn.sph.physics', 'terradyn.sph.neighbours', 'terradyn.sph.source', 'terradyn.sph.state')
