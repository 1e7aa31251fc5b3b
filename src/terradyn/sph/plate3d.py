"""A minimal 3D SPH of the plate test (issue 17): is the 2D plate too weak because it is 2D?

The 2D model (:mod:`terradyn.sph.physics`) is plane strain: its plate is a strip, infinitely
long out of plane. Li 2013's plate is 3.81 x 2.54 cm, and a finite footing bears more than a
strip (bearing-capacity shape factors > 1). This module runs the *same physics* in 3D so that
geometry is the only change:

* Wendland C2 kernel in 3D, W = 21 / (16 pi h^3) (1 - q/2)^4 (2 q + 1), support 2h, h = hdx dx
  (:class:`~terradyn.sph.state.SPHConfig` defaults: 1.3 dx); Verlet pair lists from a cell
  grid, rebuilt when a particle has moved half the skin (:data:`~terradyn.sph.neighbours.SKIN`).
* The 2D integrator: per step the boundary particles' state is extrapolated, pass 1 takes the
  velocity gradient from v^n and updates density and stress (:func:`dp_update3`), the boundary
  state is extrapolated again, pass 2 takes the accelerations from sigma^{n+1}, kicks and
  drifts (symplectic Euler); dt = cfl h / (c + v_plate); damped settling (15 bed-depth /
  sound-speed transits, damping 2 c / depth), the plate waiting at its start.
* The 2D momentum equation and Monaghan viscosity (between granular particles only), the same
  material (:func:`terradyn.sph.materials.from_medium`: density, E, nu, alpha_phi, k_c, K0),
  and :func:`dp_update3`: the Drucker-Prager update of :func:`terradyn.sph.physics.dp_update`
  with the full 3D stress (six components, Jaumann rate with the 3D spin), the same tension
  cut-off, return and density clamp [0.9, 1.1] rho0 (the 2D code's).
* Boundaries as in 2D: dummy particles whose stress and velocity are extrapolated from the
  granular particles around them (Adami, Hu & Adams 2012; no-slip ghost velocity), a rough
  floor and far walls; the plate is rigid, each face with its own ``wall_layers`` layers of
  markers from dx/2 inside it, a marker sees material on its own side only and material on
  the two sides of the plate does not interact through it (the 2D side test), the 2D contact
  guard at dx/4 (not within 1.5 dx of the edges). Force on the plate: the sum of the
  granular -> marker pair forces plus the guard's momentum, as in 2D.
* Symmetry planes x = 0 and y = 0 (and y = Ly for the plane-strain slab) are frictionless
  mirrors: every particle within the list radius of a plane has a mirror ghost (position,
  velocity and stress reflected: sigma_xy, sigma_xz change sign across x = 0), rebuilt with the
  lists and refreshed from its source before each use; a particle that crosses a plane is
  reflected back. Only a quarter of the bed and plate is simulated, and the vertical force on
  the whole plate is 4 x the quarter's (the quarter's particles act on all markers, ghosts
  included, which by symmetry is the whole plate's force / 4).

Parallel without atomics (Numba ``prange``): particles are binned into cells ordered x
slowest, the cell order is cut into chunks at least as long as any cell's neighbour reach, and
each pair pass runs the chunks in three phases (chunks three apart at once), so two threads
never write the same particle. Each granular pair is listed once (partner later in cell order)
and acts on both particles; sums run in a fixed order, so the forces are bitwise the same on
any number of threads (tested). Entry points: :func:`plate_scene` (the bed and plate), :func:`plate_push3d`
(the plate test of :data:`terradyn.sph.calibration.PLATE_TEST`, its alpha_z as the 2D
``plate_slope`` fits it), :func:`plate_drag3d` (the rig's vertical plate pushed sideways) and
:func:`leg3d` (the rotating-leg test: flat, C or reverse-C leg; curved legs carry per-marker
face normals). ``benchmarks/sph_plate3d.py``, ``sph_plate_drag3d.py`` and ``sph_leg3d.py`` run
the studies (docs/sph.md).
"""
from __future__ import annotations

from .._jitcache import bind_to_sources as _bind_cache

import math
import time
from dataclasses import dataclass, field

import numpy as np
from numba import njit, prange

from ..errors import InputError, check_memory, in_range, integer, positive
from ..units import CM, G
from ..geometry import ArcLeg
from .calibration import PLATE_TEST
from .materials import GranularMaterial, material as _material
from .neighbours import SKIN
from .state import LEG, LOST, SOIL, WALL, SPHConfig

_W3D = 21.0 / (16.0 * math.pi)
#: Columns of the stress array (N, 6), tension positive.
S_XX, S_YY, S_ZZ, S_XY, S_XZ, S_YZ = range(6)
#: Memory per particle (state, ghosts, pair lists, work arrays), bytes: an upper estimate.
PARTICLE_BYTES_3D = 2048
#: Most particles a plate run may have (about 40 min per 2D-equivalent plate test per 10^5
#: on one core): a guard against typos such as dx = 0.4 mm.
MAX_PARTICLES = 2_000_000
#: Li 2013's plate (m): length (along x), width (along y), thickness.
PLATE_LENGTH, PLATE_WIDTH, PLATE_THICKNESS = 3.81 * CM, 2.54 * CM, 0.64 * CM

# float parameters of the step kernel, by index
FP = ("h", "dt", "shear_mod", "bulk_mod", "alpha_phi", "k_c", "rho_min", "rho_max", "alpha_psi",
      "rho_crit", "c0", "av_alpha", "av_beta", "gz", "half_t", "gap", "max_push", "vmax",
      "plate_a", "plate_b", "ly", "x_lo", "y_lo", "z_lo", "inv_cell", "rlist", "x_hi_box",
      "y_hi_box", "z_lo_box", "side_reach", "x_lo_box", "p_cx", "p_cz", "p_ux", "p_uz", "p_vx",
      "p_vz", "p_om", "arc_r", "arc_qc", "arc_sg", "arc_cos")
(F_H, F_DT, F_G, F_K, F_APHI, F_KC, F_RMIN, F_RMAX, F_APSI, F_RCRIT, F_C0, F_AVA, F_AVB, F_GZ,
 F_HALFT, F_GAP, F_MAXPUSH, F_VMAX, F_PA, F_PB, F_LY, F_XLO, F_YLO, F_ZLO, F_INVC, F_RLIST,
 F_XHIB, F_YHIB, F_ZLOB, F_SREACH, F_XLOB, F_CX, F_CZ, F_UX, F_UZ, F_VX, F_VZ, F_OM, F_ARCR,
 F_ARCQC, F_ARCSG, F_ARCCOS) = range(len(FP))
#: Columns of a plate pose row (per step): centre x, z (m), angle phi of the chord from +x
#: towards +z (rad), centre velocity x, z (m/s), angular velocity d phi / dt (rad/s). The
#: chord is u = (cos phi, sin phi), the normal n = (-sin phi, cos phi) (phi = 0: the
#: horizontal plate of the plate test, normal up); a point r moves at v_c + om (-(r_z - c_z),
#: r_x - c_x).
POSE = ("cx", "cz", "phi", "vx", "vz", "om")
IP = ("nr", "ng", "nss", "nsb", "ncx", "ncy", "ncz", "mirror_x", "mirror_y0", "mirror_y1",
      "slab", "builds", "has_plate", "bad", "lost", "arc", "nchunk")
(I_NR, I_NG, I_NSS, I_NSB, I_NCX, I_NCY, I_NCZ, I_MX, I_MY0, I_MY1, I_SLAB, I_BUILDS, I_PLATE,
 I_BAD, I_LOST, I_ARC, I_NCHUNK) = range(len(IP))
#: Most chunks of the parallel pair passes (:func:`_chunk_bounds`), and the fixed blocks of
#: the per-particle reductions (the kick's force): neither depends on the number of threads.
MAX_CHUNKS_3D, N_BLOCKS_3D = 384, 64
#: Kernel return codes.
OK, UNSTABLE, PAIRS_FULL, GHOSTS_FULL = 0, 1, 2, 3


# ------------------------------------------------------------------------ constitutive law
@njit(cache=True, fastmath=True)
def dp_update3(rho, drho, lxx, lxy, lxz, lyx, lyy, lyz, lzx, lzy, lzz, sxx, syy, szz, sxy, sxz,
               syz, dt, shear_mod, bulk_mod, alpha_phi, k_c, rho_min, rho_max, alpha_psi,
               rho_crit):
    """:func:`terradyn.sph.physics.dp_update` with the full 3D stress: density (clamped to
    [rho_min, rho_max]), Jaumann rate + Hooke's law, the Bui et al. (2008) tension cut-off and
    stress scaling onto sqrt(J2) + alpha_phi I1 - k_c = 0 (non-dilatant; or the
    non-associated closed-form return while denser than rho_crit when alpha_psi > 0). l_ab =
    dv_a / dx_b. Returns (rho, sxx, syy, szz, sxy, sxz, syz). For a plane-strain history (l_y*
    = l_*y = 0, sxy = syz = 0) it gives the numbers of the 2D update."""
    rho = min(max(rho + dt * drho, rho_min), rho_max)
    exy = 0.5 * (lxy + lyx)
    exz = 0.5 * (lxz + lzx)
    eyz = 0.5 * (lyz + lzy)
    wxy = 0.5 * (lxy - lyx)
    wxz = 0.5 * (lxz - lzx)
    wyz = 0.5 * (lyz - lzy)
    ev = lxx + lyy + lzz
    third = ev / 3.0
    # Jaumann terms sigma_ac w_bc + sigma_cb w_ac (w antisymmetric)
    d_xx = 2.0 * (sxy * wxy + sxz * wxz) + 2.0 * shear_mod * (lxx - third) + bulk_mod * ev
    d_yy = 2.0 * (syz * wyz - sxy * wxy) + 2.0 * shear_mod * (lyy - third) + bulk_mod * ev
    d_zz = -2.0 * (sxz * wxz + syz * wyz) + 2.0 * shear_mod * (lzz - third) + bulk_mod * ev
    d_xy = wxy * (syy - sxx) + (syz * wxz - sxz * wyz) + 2.0 * shear_mod * exy
    d_xz = wxz * (szz - sxx) + (syz * wxy - sxy * wyz) + 2.0 * shear_mod * exz
    d_yz = wyz * (szz - syy) - (sxy * wxz + sxz * wxy) + 2.0 * shear_mod * eyz
    s_xx = sxx + dt * d_xx
    s_yy = syy + dt * d_yy
    s_zz = szz + dt * d_zz
    s_xy = sxy + dt * d_xy
    s_xz = sxz + dt * d_xz
    s_yz = syz + dt * d_yz
    i1 = s_xx + s_zz + s_yy
    if -alpha_phi * i1 + k_c < 0.0:  # tension cut-off
        shift = (i1 - k_c / alpha_phi) / 3.0
        s_xx -= shift
        s_zz -= shift
        s_yy -= shift
        i1 = k_c / alpha_phi
    m = i1 / 3.0
    dxx = s_xx - m
    dyy = s_yy - m
    dzz = s_zz - m
    j2 = 0.5 * (dxx * dxx + dzz * dzz + dyy * dyy) + s_xz * s_xz + s_xy * s_xy + s_yz * s_yz
    lim = -alpha_phi * i1 + k_c
    if alpha_psi > 0.0 and rho > rho_crit and j2 > lim * lim and j2 > 0.0:
        sj = math.sqrt(j2)
        dlam = (sj - lim) / (shear_mod + 9.0 * bulk_mod * alpha_phi * alpha_psi)
        if sj > shear_mod * dlam:
            rr = 1.0 - shear_mod * dlam / sj
            m = (i1 - 9.0 * bulk_mod * alpha_psi * dlam) / 3.0
        else:
            rr = 0.0
            m = k_c / (3.0 * alpha_phi) if alpha_phi > 0.0 else m
        return (rho, dxx * rr + m, dyy * rr + m, dzz * rr + m, s_xy * rr, s_xz * rr,
                s_yz * rr)
    if j2 > lim * lim and j2 > 0.0:
        rr = lim / math.sqrt(j2)
        dxx *= rr
        dyy *= rr
        dzz *= rr
        s_xy *= rr
        s_xz *= rr
        s_yz *= rr
    return rho, dxx + m, dyy + m, dzz + m, s_xy, s_xz, s_yz


# ----------------------------------------------------------------------- neighbour search
@njit(cache=True)
def _cell3(px, py, pz, fp, ip):
    inv = fp[F_INVC]
    cx = min(max(int((px - fp[F_XLO]) * inv), 0), ip[I_NCX] - 1)
    cy = min(max(int((py - fp[F_YLO]) * inv), 0), ip[I_NCY] - 1)
    cz = min(max(int((pz - fp[F_ZLO]) * inv), 0), ip[I_NCZ] - 1)
    return cx, cy, cz


@njit(cache=True)
def _add_ghost(g, s, sx, sy, oy, src, gs, go):
    src[g] = s
    gs[g, 0] = sx
    gs[g, 1] = sy
    gs[g, 2] = 1.0
    go[g, 0] = 0.0
    go[g, 1] = oy
    go[g, 2] = 0.0


@njit(cache=True)
def _make_ghosts(pos, kind, src, gs, go, fp, ip):
    """Mirror ghosts of every real particle within the list radius of a symmetry plane
    (x = 0; y = 0; y = Ly for the slab), and of the x = 0 ghosts across the y planes (the
    corners). Returns the ghost count, or -1 when they do not fit."""
    nr = ip[I_NR]
    cap = pos.shape[0] - nr
    rl = fp[F_RLIST]
    ly = fp[F_LY]
    mx = ip[I_MX] != 0
    my0 = ip[I_MY0] != 0
    my1 = ip[I_MY1] != 0
    g = 0
    for s in range(nr):
        if kind[s] == LOST:
            continue
        nx = mx and pos[s, 0] < rl
        n0 = my0 and pos[s, 1] < rl
        n1 = my1 and pos[s, 1] > ly - rl
        need = (1 if nx else 0) * (1 + (1 if n0 else 0) + (1 if n1 else 0)) + (1 if n0 else 0) \
            + (1 if n1 else 0)
        if g + need > cap:
            return -1
        if nx:
            _add_ghost(nr + g, s, -1.0, 1.0, 0.0, src, gs, go)
            g += 1
        if n0:
            _add_ghost(nr + g, s, 1.0, -1.0, 0.0, src, gs, go)
            g += 1
            if nx:
                _add_ghost(nr + g, s, -1.0, -1.0, 0.0, src, gs, go)
                g += 1
        if n1:
            _add_ghost(nr + g, s, 1.0, -1.0, 2.0 * ly, src, gs, go)
            g += 1
            if nx:
                _add_ghost(nr + g, s, -1.0, -1.0, 2.0 * ly, src, gs, go)
                g += 1
    return g


@njit(inline="always")
def _ghost_one(g, pos, vel, gv, rho, mass, sig, kind, nz, wn, dcl, grd, side, src, gs, go):
    """Refresh ghost g from its source (reflected position, velocities, marker normal and
    stress)."""
    s = src[g]
    sx = gs[g, 0]
    sy = gs[g, 1]
    pos[g, 0] = sx * pos[s, 0] + go[g, 0]
    pos[g, 1] = sy * pos[s, 1] + go[g, 1]
    pos[g, 2] = pos[s, 2]
    vel[g, 0] = sx * vel[s, 0]
    vel[g, 1] = sy * vel[s, 1]
    vel[g, 2] = vel[s, 2]
    gv[g, 0] = sx * gv[s, 0]
    gv[g, 1] = sy * gv[s, 1]
    gv[g, 2] = gv[s, 2]
    rho[g] = rho[s]
    mass[g] = mass[s]
    kind[g] = kind[s]
    nz[g] = nz[s]
    wn[g, 0] = sx * wn[s, 0]
    wn[g, 1] = wn[s, 1]
    dcl[g] = dcl[s]
    grd[g] = grd[s]
    side[g] = side[s]
    sig[g, S_XX] = sig[s, S_XX]
    sig[g, S_YY] = sig[s, S_YY]
    sig[g, S_ZZ] = sig[s, S_ZZ]
    sig[g, S_XY] = sx * sy * sig[s, S_XY]
    sig[g, S_XZ] = sx * sig[s, S_XZ]
    sig[g, S_YZ] = sy * sig[s, S_YZ]


@njit(cache=True, parallel=True)
def _update_ghosts(pos, vel, gv, rho, mass, sig, kind, nz, wn, dcl, grd, side, src, gs, go, ip):
    """Refresh every ghost from its source (:func:`_ghost_one`)."""
    nr = ip[I_NR]
    for g in prange(nr, nr + ip[I_NG]):
        _ghost_one(g, pos, vel, gv, rho, mass, sig, kind, nz, wn, dcl, grd, side, src, gs, go)


@njit(cache=True)
def _bin_cells(pos, kind, cell_start, cell_idx, rank, fp, ip):
    """Sort the particles (real and ghost, not lost) into the cells by counting: cell (cx, cy,
    cz) is number (cx ncy + cy) ncz + cz (x, the bed's longest axis, slowest), cell_idx the
    particles in cell order, rank[p] p's place in it (-1: lost)."""
    n = ip[I_NR] + ip[I_NG]
    ncy, ncz = ip[I_NCY], ip[I_NCZ]
    ncell = ip[I_NCX] * ncy * ncz
    cell_start[:] = 0
    for p in range(n):
        if kind[p] == LOST:
            rank[p] = -1
            continue
        cx, cy, cz = _cell3(pos[p, 0], pos[p, 1], pos[p, 2], fp, ip)
        c = (cx * ncy + cy) * ncz + cz
        rank[p] = c  # the cell for now
        cell_start[c + 1] += 1
    for c in range(ncell):
        cell_start[c + 1] += cell_start[c]
    fill = cell_start[:ncell].copy()
    for p in range(n):
        c = rank[p]
        if c >= 0:
            cell_idx[fill[c]] = p
            rank[p] = fill[c]
            fill[c] += 1


@njit(cache=True)
def _chunk_bounds(cell_start, bounds, ip):
    """Split the particles in cell order into chunks for the parallel pair passes. Two
    particles of a pair lie less than ``span`` places apart in cell order (span: the furthest
    any occupied cell's neighbour cells reach before or after it), so chunks at least span
    long make every pass over a chunk's particles write only into that chunk and its two
    neighbours: chunks three apart run at once (three phases), with no atomics and sums whose
    order does not depend on the number of threads. bounds[0..q], ip[I_NCHUNK] = q."""
    ncx, ncy, ncz = ip[I_NCX], ip[I_NCY], ip[I_NCZ]
    span = 1
    for cx in range(ncx):
        for cy in range(ncy):
            for cz in range(ncz):
                c = (cx * ncy + cy) * ncz + cz
                if cell_start[c + 1] == cell_start[c]:
                    continue
                hi = (min(cx + 1, ncx - 1) * ncy + min(cy + 1, ncy - 1)) * ncz + min(cz + 1, ncz - 1)
                lo = (max(cx - 1, 0) * ncy + max(cy - 1, 0)) * ncz + max(cz - 1, 0)
                span = max(span, cell_start[hi + 1] - cell_start[c],
                           cell_start[c + 1] - cell_start[lo])
    m = cell_start[ncx * ncy * ncz]
    q = max(1, min(m // span, bounds.shape[0] - 1))
    for k in range(q + 1):
        bounds[k] = m * k // q
    ip[I_NCHUNK] = q


@njit(inline="always")
def _pairs_of(p, pos, kind, rank, cell_start, cell_idx, ss, sb, o_ss, o_sb, write, rl2, fp, ip):
    """The list entries of particle p (see :func:`_build_pairs`): counts (granular, boundary)
    and, with ``write``, the partners at ss[o_ss:], sb[o_sb:]."""
    nss = 0
    nsb = 0
    if kind[p] != SOIL:
        return nss, nsb
    nr = ip[I_NR]
    ncx, ncy, ncz = ip[I_NCX], ip[I_NCY], ip[I_NCZ]
    real = p < nr
    rp = rank[p]
    cx, cy, cz = _cell3(pos[p, 0], pos[p, 1], pos[p, 2], fp, ip)
    for ddx in range(-1, 2):
        ix = cx + ddx
        if ix < 0 or ix >= ncx:
            continue
        for ddy in range(-1, 2):
            iy = cy + ddy
            if iy < 0 or iy >= ncy:
                continue
            for ddz in range(-1, 2):
                iz = cz + ddz
                if iz < 0 or iz >= ncz:
                    continue
                cc = (ix * ncy + iy) * ncz + iz
                for t in range(cell_start[cc], cell_start[cc + 1]):
                    q = cell_idx[t]
                    kq = kind[q]
                    if kq == SOIL:
                        if not real or (q < nr and rank[q] <= rp):
                            continue
                    elif not real and q >= nr:
                        continue
                    rx = pos[p, 0] - pos[q, 0]
                    ry = pos[p, 1] - pos[q, 1]
                    rz = pos[p, 2] - pos[q, 2]
                    if rx * rx + ry * ry + rz * rz >= rl2:
                        continue
                    if kq == SOIL:
                        if write:
                            ss[o_ss + nss] = q
                        nss += 1
                    else:
                        if write:
                            sb[o_sb + nsb] = q
                        nsb += 1
    return nss, nsb


@njit(cache=True, parallel=True)
def _build_pairs(pos, kind, rank, cell_start, cell_idx, ss, sso, sb, sbo, fp, ip):
    """List, per granular particle p (compressed rows: partners ss[sso[p]:sso[p + 1]]), the
    pairs within the list radius that the passes need: granular partners later in cell order
    and granular ghosts (a real p: each granular pair once, acting on both), and boundary
    partners (sb, sbo) of real granular particles and of granular ghosts next to real
    boundary particles (their extrapolation). The cells come from :func:`_bin_cells`. Counts
    first, then the rows, both in parallel. Returns False when a list is full."""
    n = ip[I_NR] + ip[I_NG]
    rl2 = fp[F_RLIST] ** 2
    for p in prange(n):
        a, b = _pairs_of(p, pos, kind, rank, cell_start, cell_idx, ss, sb, 0, 0, False, rl2,
                         fp, ip)
        sso[p + 1] = a
        sbo[p + 1] = b
    sso[0] = 0
    sbo[0] = 0
    for p in range(n):
        sso[p + 1] += sso[p]
        sbo[p + 1] += sbo[p]
    if sso[n] > ss.shape[0] or sbo[n] > sb.shape[0]:
        return False
    for p in prange(n):
        _pairs_of(p, pos, kind, rank, cell_start, cell_idx, ss, sb, sso[p], sbo[p], True, rl2,
                  fp, ip)
    ip[I_NSS] = sso[n]
    ip[I_NSB] = sbo[n]
    return True


# ------------------------------------------------------------------------- the pair terms
@njit(inline="always", fastmath=True)
def _boundary_one(f, pos, vel, rho, sig, kind, wn, dcl, sb, sbo, wsb, reuse, bacc, h, gz, nr,
                  sup2, c_w):
    """:func:`_boundary_pass`'s sums over the boundary partners of the granular particle f."""
    if kind[f] != SOIL:
        return
    xf = pos[f, 0]
    yf = pos[f, 1]
    zf = pos[f, 2]
    rf = rho[f]
    for k in range(sbo[f], sbo[f + 1]):
        w = sb[k]
        rz = pos[w, 2] - zf
        if reuse:
            wgt = wsb[k]
            if wgt == 0.0:
                continue
        else:
            wsb[k] = 0.0
            if w >= nr:
                continue
            rx = pos[w, 0] - xf
            ry = pos[w, 1] - yf
            r2 = rx * rx + ry * ry + rz * rz
            if r2 >= sup2:
                continue
            if kind[w] == LEG and (xf - pos[w, 0]) * wn[w, 0] + (zf - pos[w, 2]) * wn[w, 1] \
                    + dcl[w] <= 0.0:
                continue
            q = math.sqrt(r2) / h
            t = 1.0 - 0.5 * q
            wgt = c_w * t * t * t * t * (2.0 * q + 1.0)
            wsb[k] = wgt
        bacc[w, 0] += wgt
        for c in range(6):
            bacc[w, 1 + c] += sig[f, c] * wgt
        bacc[w, 7] += vel[f, 0] * wgt
        bacc[w, 8] += vel[f, 1] * wgt
        bacc[w, 9] += vel[f, 2] * wgt
        bacc[w, 10] += rf * (gz * rz) * wgt


@njit(inline="always", fastmath=True)
def _boundary_fin(w, vel, gv, sig, kind, bacc):
    """:func:`_boundary_pass`'s Shepard average for the real wall or plate particle w from
    its sums bacc[w]."""
    kw = kind[w]
    if kw != WALL and kw != LEG:
        return
    ssum = bacc[w, 0]
    if ssum > 0.0:
        inv = 1.0 / ssum
        p_add = -bacc[w, 10] * inv
        for c in range(6):
            sig[w, c] = bacc[w, 1 + c] * inv
        sig[w, S_XX] += p_add
        sig[w, S_YY] += p_add
        sig[w, S_ZZ] += p_add
        for c in range(3):
            gv[w, c] = 2.0 * vel[w, c] - bacc[w, 7 + c] * inv
    else:
        for c in range(6):
            sig[w, c] = 0.0
        for c in range(3):
            gv[w, c] = vel[w, c]


@njit(cache=True, fastmath=True, parallel=True)
def _boundary_pass(pos, vel, gv, rho, sig, kind, wn, dcl, sb, sbo, wsb, reuse, bacc, cell_idx,
                   bounds, fp, ip):
    """Adami extrapolation: stress and (no-slip) ghost velocity of every real wall and
    plate particle from the granular particles around it (Shepard average + rho (g - a_w) .
    (x_w - x_f); a_w = 0: walls fixed, the plate moves at constant speed). A plate marker
    uses only material on its own side. The kernel values go to wsb (per pair) or, with
    ``reuse`` (positions unchanged since), come from it. The granular particles in the
    chunks of :func:`_chunk_bounds`, three phases."""
    h = fp[F_H]
    gz = fp[F_GZ]
    nr = ip[I_NR]
    sup2 = 4.0 * h * h
    c_w = _W3D / (h * h * h)
    nch = ip[I_NCHUNK]
    for w in prange(nr):
        for c in range(11):
            bacc[w, c] = 0.0
    for phase in range(3):
        for j in prange((nch + 2 - phase) // 3):
            jc = 3 * j + phase
            for rk in range(bounds[jc], bounds[jc + 1]):
                _boundary_one(cell_idx[rk], pos, vel, rho, sig, kind, wn, dcl, sb, sbo, wsb,
                              reuse, bacc, h, gz, nr, sup2, c_w)
    for w in prange(nr):
        _boundary_fin(w, vel, gv, sig, kind, bacc)


@njit(inline="always", fastmath=True)
def _add_grad(lg, row, m, vol, dvx, dvy, dvz, gx, gy, gz):
    """One pair's pass-1 terms for particle ``row`` (partner mass m, volume vol; dv = v_row -
    v_partner, grad W = (gx, gy, gz) seen from row): d rho += m dv . grad W, l -= vol dv (x)
    grad W."""
    lg[row, 0] += m * (dvx * gx + dvy * gy + dvz * gz)
    lg[row, 1] -= vol * dvx * gx
    lg[row, 2] -= vol * dvx * gy
    lg[row, 3] -= vol * dvx * gz
    lg[row, 4] -= vol * dvy * gx
    lg[row, 5] -= vol * dvy * gy
    lg[row, 6] -= vol * dvy * gz
    lg[row, 7] -= vol * dvz * gx
    lg[row, 8] -= vol * dvz * gy
    lg[row, 9] -= vol * dvz * gz


@njit(inline="always", fastmath=True)
def _strain_one(a, pos, vel, gv, rho, mass, kind, wn, dcl, side, ss, sso, sb, sbo, fss, fsb, lg,
                nr, sup2, dwc, inv_h):
    """:func:`_strain_pass`'s pair sums of the real granular particle a (its granular pairs
    also act on the real partner)."""
    if a >= nr or kind[a] != SOIL:
        return
    xa = pos[a, 0]
    ya = pos[a, 1]
    za = pos[a, 2]
    sa = side[a]
    ma = mass[a]
    va = ma / rho[a]
    for k in range(sso[a], sso[a + 1]):
        b = ss[k]
        fss[k] = 0.0
        if kind[b] != SOIL or sa * side[b] < 0.0:
            continue
        rx = xa - pos[b, 0]
        ry = ya - pos[b, 1]
        rz = za - pos[b, 2]
        r2 = rx * rx + ry * ry + rz * rz
        if r2 >= sup2:
            continue
        t = 1.0 - 0.5 * math.sqrt(r2) * inv_h
        fdw = dwc * t * t * t
        fss[k] = fdw
        dvx = vel[a, 0] - vel[b, 0]
        dvy = vel[a, 1] - vel[b, 1]
        dvz = vel[a, 2] - vel[b, 2]
        mb = mass[b]
        _add_grad(lg, a, mb, mb / rho[b], dvx, dvy, dvz, fdw * rx, fdw * ry, fdw * rz)
        if b < nr:  # grad_b W = -grad_a W, v_b - v_a = -dv: the same products
            _add_grad(lg, b, ma, va, dvx, dvy, dvz, fdw * rx, fdw * ry, fdw * rz)
    for k in range(sbo[a], sbo[a + 1]):
        w = sb[k]
        fsb[k] = 0.0
        rx = xa - pos[w, 0]
        ry = ya - pos[w, 1]
        rz = za - pos[w, 2]
        r2 = rx * rx + ry * ry + rz * rz
        if r2 >= sup2:
            continue
        if kind[w] == LEG and rx * wn[w, 0] + rz * wn[w, 1] + dcl[w] <= 0.0:
            continue
        t = 1.0 - 0.5 * math.sqrt(r2) * inv_h
        fdw = dwc * t * t * t
        fsb[k] = fdw
        mw = mass[w]
        _add_grad(lg, a, mw, mw / rho[w], vel[a, 0] - gv[w, 0], vel[a, 1] - gv[w, 1],
                  vel[a, 2] - gv[w, 2], fdw * rx, fdw * ry, fdw * rz)


@njit(inline="always", fastmath=True)
def _dp_one(i, rho, sig, kind, lg, fp):
    """:func:`dp_update3` of the real particle i from its pass-1 sums lg[i] (granular only)."""
    if kind[i] != SOIL:
        return
    (rho[i], sig[i, S_XX], sig[i, S_YY], sig[i, S_ZZ], sig[i, S_XY], sig[i, S_XZ],
     sig[i, S_YZ]) = dp_update3(
        rho[i], lg[i, 0], lg[i, 1], lg[i, 2], lg[i, 3], lg[i, 4], lg[i, 5], lg[i, 6],
        lg[i, 7], lg[i, 8], lg[i, 9], sig[i, S_XX], sig[i, S_YY], sig[i, S_ZZ],
        sig[i, S_XY], sig[i, S_XZ], sig[i, S_YZ], fp[F_DT], fp[F_G], fp[F_K], fp[F_APHI],
        fp[F_KC], fp[F_RMIN], fp[F_RMAX], fp[F_APSI], fp[F_RCRIT])


@njit(cache=True, fastmath=True, parallel=True)
def _strain_pass(pos, vel, gv, rho, mass, sig, kind, wn, dcl, side, ss, sso, sb, sbo, fss, fsb,
                 lg, cell_idx, bounds, fp, ip):
    """Pass 1: d rho/dt and the velocity gradient of every real granular particle (l_ab =
    dv_a/dx_b, lg[i] = (d rho/dt, lxx, lxy, lxz, lyx, lyy, lyz, lzx, lzy, lzz)), then
    :func:`dp_update3`. The kernel-gradient factors (grad W = fdw r) go to fss, fsb (0: no
    interaction) for pass 2. The granular particles in the chunks of :func:`_chunk_bounds`,
    three phases."""
    h = fp[F_H]
    nr = ip[I_NR]
    sup2 = 4.0 * h * h
    dwc = -5.0 * _W3D / (h * h * h * h * h)
    inv_h = 1.0 / h
    nch = ip[I_NCHUNK]
    for i in prange(nr):
        for c in range(10):
            lg[i, c] = 0.0
    for phase in range(3):
        for j in prange((nch + 2 - phase) // 3):
            jc = 3 * j + phase
            for rk in range(bounds[jc], bounds[jc + 1]):
                _strain_one(cell_idx[rk], pos, vel, gv, rho, mass, kind, wn, dcl, side, ss, sso,
                            sb, sbo, fss, fsb, lg, nr, sup2, dwc, inv_h)
    for i in prange(nr):
        _dp_one(i, rho, sig, kind, lg, fp)


@njit(inline="always", fastmath=True)
def _stress_term3(psig, a, b, pi_ij, gx, gy, gz):
    """The momentum equation's pair term per unit mass of b: (sigma_a / rho_a^2 + sigma_b /
    rho_b^2 - Pi_ab I) . grad_a W (psig: sigma / rho^2 rows), as (tx, ty, tz)."""
    txx = psig[a, S_XX] + psig[b, S_XX] - pi_ij
    tyy = psig[a, S_YY] + psig[b, S_YY] - pi_ij
    tzz = psig[a, S_ZZ] + psig[b, S_ZZ] - pi_ij
    txy = psig[a, S_XY] + psig[b, S_XY]
    txz = psig[a, S_XZ] + psig[b, S_XZ]
    tyz = psig[a, S_YZ] + psig[b, S_YZ]
    return (txx * gx + txy * gy + txz * gz, txy * gx + tyy * gy + tyz * gz,
            txz * gx + tyz * gy + tzz * gz)


@njit(inline="always", fastmath=True)
def _accel_one(a, pos, vel, rho, mass, psig, kind, nz, wn, dcl, grd, ss, sso, sb, sbo, fss, fsb,
               acc, cont, h, h2, c0, ava, avb, half_t, arc, nr, fp):
    """:func:`_accel_pass`'s pair sums of the real granular particle a (its granular pairs
    also act on the real partner)."""
    if a >= nr or kind[a] != SOIL:
        return
    xa = pos[a, 0]
    ya = pos[a, 1]
    za = pos[a, 2]
    vxa = vel[a, 0]
    vya = vel[a, 1]
    vza = vel[a, 2]
    ra = rho[a]
    ma = mass[a]
    ax = 0.0
    ay = 0.0
    az = 0.0
    for k in range(sso[a], sso[a + 1]):
        fdw = fss[k]
        if fdw == 0.0:
            continue
        b = ss[k]
        rx = xa - pos[b, 0]
        ry = ya - pos[b, 1]
        rz = za - pos[b, 2]
        vdotr = (vxa - vel[b, 0]) * rx + (vya - vel[b, 1]) * ry + (vza - vel[b, 2]) * rz
        pi_ij = 0.0
        if vdotr < 0.0:
            mu = h * vdotr / (rx * rx + ry * ry + rz * rz + 0.01 * h2)
            pi_ij = (-ava * c0 * mu + avb * mu * mu) / (0.5 * (ra + rho[b]))
        fx, fy, fz = _stress_term3(psig, a, b, pi_ij, fdw * rx, fdw * ry, fdw * rz)
        mb = mass[b]
        ax += mb * fx
        ay += mb * fy
        az += mb * fz
        if b < nr:
            acc[b, 0] -= ma * fx
            acc[b, 1] -= ma * fy
            acc[b, 2] -= ma * fz
    f3x = 0.0
    f3y = 0.0
    f3z = 0.0
    dmin = fp[F_GAP]
    pn = 0.0
    gnx = 0.0
    gnz = 0.0
    r2min = np.inf
    wnear = -1
    for k in range(sbo[a], sbo[a + 1]):
        fdw = fsb[k]
        if fdw == 0.0:
            continue
        w = sb[k]
        rx = xa - pos[w, 0]
        ry = ya - pos[w, 1]
        rz = za - pos[w, 2]
        tx, ty, tz = _stress_term3(psig, a, w, 0.0, fdw * rx, fdw * ry, fdw * rz)
        mw = mass[w]
        pax = mw * tx
        pay = mw * ty
        paz = mw * tz
        ax += pax
        ay += pay
        az += paz
        if kind[w] == LEG:
            f3x -= ma * pax
            f3y -= ma * pay
            f3z -= ma * paz
            if grd[w] > 0.0:
                if arc:  # a curved face: the tangent plane of the nearest marker
                    r2 = rx * rx + ry * ry + rz * rz
                    if r2 < r2min:
                        r2min = r2
                        wnear = w
                else:
                    dn = rx * wn[w, 0] + rz * wn[w, 1] + dcl[w] - half_t
                    if dn < dmin:
                        dmin = dn
                        pn = nz[w]
                        gnx = wn[w, 0]
                        gnz = wn[w, 1]
    acc[a, 0] += ax
    acc[a, 1] += ay
    acc[a, 2] += az
    acc[a, 3] = f3x
    acc[a, 4] = f3y
    acc[a, 5] = f3z
    if wnear >= 0:
        w = wnear
        dn = ((xa - pos[w, 0]) * wn[w, 0] + (za - pos[w, 2]) * wn[w, 1] + dcl[w]
              - half_t)
        if dn < dmin:
            dmin = dn
            pn = nz[w]
            gnx = wn[w, 0]
            gnz = wn[w, 1]
    cont[a, 0] = dmin
    cont[a, 1] = pn
    cont[a, 2] = gnx
    cont[a, 3] = gnz


@njit(inline="always", fastmath=True)
def _psig_one(i, rho, sig, psig):
    """sigma / rho^2 of particle i into psig[i]."""
    r = rho[i]
    inv2 = 1.0 / (r * r)
    for c in range(6):
        psig[i, c] = sig[i, c] * inv2


@njit(cache=True, fastmath=True, parallel=True)
def _accel_pass(pos, vel, rho, mass, sig, psig, kind, nz, wn, dcl, grd, ss, sso, sb, sbo, fss, fsb,
                acc, cont, cell_idx, bounds, fp, ip):
    """Pass 2's pair sums (the pairs and kernel-gradient factors of pass 1, positions
    unchanged since): acceleration of every real granular particle (acc[i, 0:3]), its force
    on the plate (acc[i, 3:6]) and the nearest guarded plate surface (cont[i] = (distance,
    face, outward normal x, z); a flat plate: the least distance over the guarded markers, a
    curved leg: the distance to the tangent plane of the nearest guarded marker). psig:
    scratch (N, 6) for sigma / rho^2. The granular particles in the chunks of
    :func:`_chunk_bounds`, three phases."""
    h = fp[F_H]
    nr = ip[I_NR]
    h2 = h * h
    c0 = fp[F_C0]
    ava = fp[F_AVA]
    avb = fp[F_AVB]
    half_t = fp[F_HALFT]
    arc = ip[I_ARC] != 0
    for i in prange(nr + ip[I_NG]):
        _psig_one(i, rho, sig, psig)
    nch = ip[I_NCHUNK]
    for i in prange(nr):
        for c in range(6):
            acc[i, c] = 0.0
    for phase in range(3):
        for j in prange((nch + 2 - phase) // 3):
            jc = 3 * j + phase
            for rk in range(bounds[jc], bounds[jc + 1]):
                _accel_one(cell_idx[rk], pos, vel, rho, mass, psig, kind, nz, wn, dcl, grd, ss,
                           sso, sb, sbo, fss, fsb, acc, cont, h, h2, c0, ava, avb, half_t, arc,
                           nr, fp)


@njit(inline="always", fastmath=True)
def _kick_one(i, pos, vel, mass, rho, sig, kind, acc, cont, fdamp, fp, ip):
    """Kick, contact guard and drift of the real particle i (granular only; see
    :func:`_kick`). Returns (its force on the plate x, y, z; 1 if it left the box and became
    LOST, else 0; whether it went non-finite or faster than sound)."""
    if kind[i] != SOIL:
        return 0.0, 0.0, 0.0, 0, False
    dt = fp[F_DT]
    ly = fp[F_LY]
    nvx = (vel[i, 0] + dt * acc[i, 0]) * fdamp
    nvy = (vel[i, 1] + dt * acc[i, 1]) * fdamp
    nvz = (vel[i, 2] + dt * (acc[i, 2] + fp[F_GZ])) * fdamp
    fx = acc[i, 3]
    fy = acc[i, 4]
    fz = acc[i, 5]
    pn = cont[i, 1]
    dp = 0.0
    gnx = cont[i, 2]  # the guarded face's outward normal
    gnz = cont[i, 3]
    if pn != 0.0:  # the guard: no approach faster than the plate's rigid motion there
        om = fp[F_OM]
        vn = ((nvx - fp[F_VX] + om * (pos[i, 2] - fp[F_CZ])) * gnx
              + (nvz - fp[F_VZ] - om * (pos[i, 0] - fp[F_CX])) * gnz)
        if vn < 0.0:
            nvx -= vn * gnx
            nvz -= vn * gnz
            fx += mass[i] * vn * gnx / dt
            fz += mass[i] * vn * gnz / dt
        dp = min(fp[F_GAP] - cont[i, 0], fp[F_MAXPUSH])
    vel[i, 0] = nvx
    vel[i, 1] = nvy
    vel[i, 2] = nvz
    x = pos[i, 0] + dt * nvx + dp * gnx
    y = pos[i, 1] + dt * nvy
    z = pos[i, 2] + dt * nvz + dp * gnz
    flip_x = ip[I_MX] != 0 and x < 0.0
    flip_y = (ip[I_MY0] != 0 and y < 0.0) or (ip[I_MY1] != 0 and y > ly)
    if flip_x:
        x = -x
        vel[i, 0] = -vel[i, 0]
        sig[i, S_XY] = -sig[i, S_XY]
        sig[i, S_XZ] = -sig[i, S_XZ]
    if flip_y:
        y = -y if y < 0.0 else 2.0 * ly - y
        vel[i, 1] = -vel[i, 1]
        sig[i, S_XY] = -sig[i, S_XY]
        sig[i, S_YZ] = -sig[i, S_YZ]
    pos[i, 0] = x
    pos[i, 1] = y
    pos[i, 2] = z
    if x > fp[F_XHIB] or x < fp[F_XLOB] or y > fp[F_YHIB] or z < fp[F_ZLOB]:
        kind[i] = LOST
        pos[i, 0] = 1e3 + i
        pos[i, 1] = 1e3
        pos[i, 2] = 1e3
        return fx, fy, fz, 1, False
    v2 = nvx * nvx + nvy * nvy + nvz * nvz
    vmax = fp[F_VMAX]
    return fx, fy, fz, 0, not (v2 < vmax * vmax and math.isfinite(x + y + z + rho[i] + sig[i, S_ZZ]))


@njit(cache=True, fastmath=True, parallel=True)
def _kick(pos, vel, mass, rho, sig, kind, acc, cont, damp, force, part, fp, ip):
    """Kick, contact guard and drift of the real granular particles (:func:`_kick_one`);
    mirror reflection at the symmetry planes; granular particles that left the box become
    LOST. Adds the force on the plate (pair forces + the guard's momentum) to force (3,).
    Returns the index of a particle that went non-finite or faster than sound, or -1. In
    parallel over fixed blocks of particles (part: their (force x, y, z, lost, bad) rows),
    summed in block order, so the force does not depend on the number of threads."""
    nr = ip[I_NR]
    fdamp = 1.0 / (1.0 + damp * fp[F_DT])
    nblk = part.shape[0]
    for blk in prange(nblk):
        bfx = 0.0
        bfy = 0.0
        bfz = 0.0
        blost = 0
        bbad = -1
        for i in range(nr * blk // nblk, nr * (blk + 1) // nblk):
            fx, fy, fz, lost, bad = _kick_one(i, pos, vel, mass, rho, sig, kind, acc, cont,
                                              fdamp, fp, ip)
            bfx += fx
            bfy += fy
            bfz += fz
            blost += lost
            if bad:
                bbad = i
        part[blk, 0] = bfx
        part[blk, 1] = bfy
        part[blk, 2] = bfz
        part[blk, 3] = blost
        part[blk, 4] = bbad
    bad = -1
    for blk in range(nblk):
        force[0] += part[blk, 0]
        force[1] += part[blk, 1]
        force[2] += part[blk, 2]
        ip[I_LOST] += int(part[blk, 3])
        if part[blk, 4] >= 0.0:
            bad = int(part[blk, 4])
    return bad


@njit(inline="always", fastmath=True)
def _side_one(i, pos, kind, side, fp, ip):
    """Side of the plate of every real granular particle: +1 / -1 on the side its normal
    points to / the other, where it lies over the plate (|(r - c) . u| <= a along the chord,
    |y| <= b, or any y in the slab) within the side reach (2h + t/2) of the mid-plane, 0
    elsewhere (the 2D side test). A curved leg (an arc of radius R about the body point (0,
    q_c), bulging towards sg n): +1 outside the arc's circle, -1 inside, where the particle
    lies within the arc's angular span and within the reach of the mid-arc. This: particle
    i (granular only)."""
    if kind[i] != SOIL:
        return
    a = fp[F_PA]
    b = fp[F_PB]
    reach = fp[F_SREACH]
    slab = ip[I_SLAB] != 0
    arc = ip[I_ARC] != 0
    rad, qc, sg, cphi = fp[F_ARCR], fp[F_ARCQC], fp[F_ARCSG], fp[F_ARCCOS]
    cx, cz, ux, uz = fp[F_CX], fp[F_CZ], fp[F_UX], fp[F_UZ]
    rx = pos[i, 0] - cx
    rz = pos[i, 2] - cz
    dn = -rx * uz + rz * ux
    s = 0.0
    if arc:
        su = rx * ux + rz * uz
        dq = sg * (dn - qc)
        rr = math.sqrt(su * su + dq * dq)
        if dq >= rr * cphi and (slab or abs(pos[i, 1]) <= b) and abs(rr - rad) < reach:
            s = 1.0 if rr > rad else -1.0
    elif abs(rx * ux + rz * uz) <= a and (slab or abs(pos[i, 1]) <= b) and abs(dn) < reach:
        s = 1.0 if dn > 0.0 else -1.0
    side[i] = s


@njit(cache=True, fastmath=True, parallel=True)
def _sides(pos, kind, side, fp, ip):
    """Side of the plate of every real granular particle (:func:`_side_one`)."""
    for i in prange(ip[I_NR]):
        _side_one(i, pos, kind, side, fp, ip)


@njit(inline="always", fastmath=True)
def _disp2_one(i, pos, pb, kind):
    """Squared displacement of particle i since the lists were built (0 when lost)."""
    if kind[i] == LOST:
        return 0.0
    return ((pos[i, 0] - pb[i, 0]) ** 2 + (pos[i, 1] - pb[i, 1]) ** 2
            + (pos[i, 2] - pb[i, 2]) ** 2)


@njit(cache=True, fastmath=True, parallel=True)
def _max_disp2(pos, pb, kind, nr, part):
    """The largest squared displacement of a particle since the lists were built (part:
    scratch rows, one per block)."""
    nblk = part.shape[0]
    for blk in prange(nblk):
        m = 0.0
        for i in range(nr * blk // nblk, nr * (blk + 1) // nblk):
            d = _disp2_one(i, pos, pb, kind)
            if d > m:
                m = d
        part[blk, 0] = m
    mall = 0.0
    for blk in range(nblk):
        mall = max(mall, part[blk, 0])
    return mall


@njit(inline="always", fastmath=True)
def _place_marker(kk, pos, vel, wn, bo, bn, lidx, fp):
    """Plate marker kk (particle lidx[kk]) at the step's pose (fp's F_CX..F_OM): position,
    rigid-body velocity and its face's outward normal."""
    cx = fp[F_CX]
    cz = fp[F_CZ]
    ux = fp[F_UX]
    uz = fp[F_UZ]
    om = fp[F_OM]
    w = lidx[kk]
    x = cx + bo[kk, 0] * ux - bo[kk, 2] * uz
    z = cz + bo[kk, 0] * uz + bo[kk, 2] * ux
    pos[w, 0] = x
    pos[w, 1] = bo[kk, 1]
    pos[w, 2] = z
    vel[w, 0] = fp[F_VX] - om * (z - cz)
    vel[w, 1] = 0.0
    vel[w, 2] = fp[F_VZ] + om * (x - cx)
    wn[w, 0] = bn[kk, 0] * ux - bn[kk, 1] * uz
    wn[w, 1] = bn[kk, 0] * uz + bn[kk, 1] * ux


@njit(cache=True)
def steps3d(pose, damp, forces, pos, vel, gv, rho, mass, sig, kind, nz, wn, dcl, grd, side,
            src, gs, go, bo, bn, lidx, pb, cell_start, cell_idx, rank, bounds, ss, sso, sb, sbo, fss,
            fsb, wsb, lg, acc, cont, bacc, psig, part, fp, ip):
    """Advance len(pose) steps: per step the plate (its frame from ``pose[s]``, a
    :data:`POSE` row; markers ``lidx`` at c + bo[:, 0] u + bo[:, 2] n, y = bo[:, 1], moving
    rigidly, their faces' outward normals wn = bn[:, 0] u + bn[:, 1] n), its sides, the lists (rebuilt with the ghosts when a particle moved half the
    skin), the boundary state, pass 1, the boundary state again, pass 2 with damping
    damp[s]; forces[s] = force of the real granular particles on the whole (real + ghost)
    plate. Returns (steps done, code): OK; UNSTABLE (ip bad: the particle); PAIRS_FULL or
    GHOSTS_FULL (the lists did not fit: the step was not done, enlarge and call again)."""
    nr = ip[I_NR]
    thr = (0.5 * SKIN * fp[F_H]) ** 2
    f3 = np.zeros(3)
    for s in range(pose.shape[0]):
        cx = pose[s, 0]
        cz = pose[s, 1]
        ux = math.cos(pose[s, 2])
        uz = math.sin(pose[s, 2])
        pvx = pose[s, 3]
        pvz = pose[s, 4]
        om = pose[s, 5]
        fp[F_CX] = cx
        fp[F_CZ] = cz
        fp[F_UX] = ux
        fp[F_UZ] = uz
        fp[F_VX] = pvx
        fp[F_VZ] = pvz
        fp[F_OM] = om
        if ip[I_PLATE]:
            for kk in range(lidx.shape[0]):
                _place_marker(kk, pos, vel, wn, bo, bn, lidx, fp)
            _sides(pos, kind, side, fp, ip)
        if ip[I_BUILDS] == 0 or _max_disp2(pos, pb, kind, nr, part) > thr:
            ng = _make_ghosts(pos, kind, src, gs, go, fp, ip)
            if ng < 0:
                return s, GHOSTS_FULL
            ip[I_NG] = ng
            _update_ghosts(pos, vel, gv, rho, mass, sig, kind, nz, wn, dcl, grd, side, src, gs, go,
                           ip)
            _bin_cells(pos, kind, cell_start, cell_idx, rank, fp, ip)
            _chunk_bounds(cell_start, bounds, ip)
            if not _build_pairs(pos, kind, rank, cell_start, cell_idx, ss, sso, sb, sbo, fp, ip):
                ip[I_BUILDS] = 0
                return s, PAIRS_FULL
            pb[:nr] = pos[:nr]
            ip[I_BUILDS] += 1
        _update_ghosts(pos, vel, gv, rho, mass, sig, kind, nz, wn, dcl, grd, side, src, gs, go, ip)
        _boundary_pass(pos, vel, gv, rho, sig, kind, wn, dcl, sb, sbo, wsb, False, bacc, cell_idx,
                       bounds, fp, ip)
        _update_ghosts(pos, vel, gv, rho, mass, sig, kind, nz, wn, dcl, grd, side, src, gs, go, ip)
        _strain_pass(pos, vel, gv, rho, mass, sig, kind, wn, dcl, side, ss, sso, sb, sbo, fss,
                     fsb, lg, cell_idx, bounds, fp, ip)
        _update_ghosts(pos, vel, gv, rho, mass, sig, kind, nz, wn, dcl, grd, side, src, gs, go, ip)
        _boundary_pass(pos, vel, gv, rho, sig, kind, wn, dcl, sb, sbo, wsb, True, bacc, cell_idx,
                       bounds, fp, ip)
        _update_ghosts(pos, vel, gv, rho, mass, sig, kind, nz, wn, dcl, grd, side, src, gs, go, ip)
        _accel_pass(pos, vel, rho, mass, sig, psig, kind, nz, wn, dcl, grd, ss, sso, sb, sbo, fss,
                    fsb, acc, cont, cell_idx, bounds, fp, ip)
        f3[:] = 0.0
        bad = _kick(pos, vel, mass, rho, sig, kind, acc, cont, damp[s], f3, part, fp, ip)
        forces[s, 0] = f3[0]
        forces[s, 1] = f3[1]
        forces[s, 2] = f3[2]
        if bad >= 0:
            ip[I_BAD] = bad
            return s + 1, UNSTABLE
    return pose.shape[0], OK


# ------------------------------------------------------------------------------ the scene
@dataclass
class Scene3D:
    """Real particles of a 3D run (SI): positions (n, 3), kinds, masses, densities, stress
    (n, 6), velocities (n, 3); plate markers (kind LEG): the face they belong to (``nz``: +1
    the face the plate's normal points out of, -1 the other), their offset from the
    mid-plane along it (dcl), guard flag, body coordinates (``bo``: along the chord, y, along
    the normal from the plate's centre; markers in the order of ``lidx``), their faces'
    outward normals in the body frame (``bn``: along the chord, along the normal; None: the
    flat plate's (0, nz)). ``mirror``: (x = 0, y = 0, y = ly)
    symmetry planes; ``box``: (x_lo, x_hi, y_hi, z_lo) outside which grains are lost;
    ``plate``: half length a, half width b, thickness t, slab (the plate spans all y)."""

    pos: np.ndarray
    kind: np.ndarray
    mass: np.ndarray
    rho: np.ndarray
    sig: np.ndarray
    vel: np.ndarray
    material: GranularMaterial
    config: SPHConfig
    nz: np.ndarray
    dcl: np.ndarray
    grd: np.ndarray
    bo: np.ndarray
    mirror: tuple = (True, True, False)
    ly: float = 0.0
    box: tuple = (-1e3, 1e3, 1e3, -1e3)
    plate: dict | None = None
    depth: float = 0.1
    gravity: float = G
    meta: dict = field(default_factory=dict)
    bn: np.ndarray | None = None

    @property
    def lidx(self) -> np.ndarray:
        return np.flatnonzero(self.kind == LEG).astype(np.int64)

    def __len__(self):
        return len(self.kind)


def _grid3(x0, x1, y0, y1, z0, z1, dx):
    """Cubic lattice of spacing dx filling [x0, x1] x [y0, y1] x [z0, z1] (cell centres;
    each extent a whole number of spacings): (M, 3)."""
    def ax(a, b):
        n = max(int(round((b - a) / dx)), 0)
        return a + (np.arange(n) + 0.5) * dx
    X, Y, Z = np.meshgrid(ax(x0, x1), ax(y0, y1), ax(z0, z1), indexing="ij")
    return np.stack([X.ravel(), Y.ravel(), Z.ravel()], -1)


def estimate_particles(half_x: float, half_y: float, depth: float, dx: float, layers: int = 3,
                       mirror_x: bool = True, slab: bool = False) -> int:
    """Real + ghost particles of a :func:`plate_scene` (an estimate for the memory check)."""
    nx = half_x / dx * (1 if mirror_x else 2) + layers * (1 if mirror_x else 2)
    ny = half_y / dx + (0 if slab else layers)
    nzz = (depth + 0.03) / dx + layers
    real = nx * ny * nzz
    ghosts = 3.0 * (2.2 * 1.3 + 1) * (nx + ny) * nzz
    return int(real + ghosts)


def plate_scene(medium: str | GranularMaterial = "3 mm glass CP", *, dx: float = 4e-3,
                config: SPHConfig | None = None, length: float = PLATE_LENGTH,
                width: float = PLATE_WIDTH, thickness: float = PLATE_THICKNESS,
                slab: int | None = None, half_x: float | None = None,
                half_y: float | None = None, depth: float | None = None,
                mirror_x: bool = True, z0: float | None = None,
                with_plate: bool = True, pose: tuple | None = None,
                curvature: float = 0.0) -> Scene3D:
    """The bed and plate of the 3D plate test, a quarter of it (symmetry planes x = 0, y = 0).

    The plate (``length`` along x, ``width`` along y, ``thickness``) is centred at x = y = 0
    with its centre ``z0`` above the surface z = 0 (default t/2 + dx/2: its bottom face
    dx/2 above the top grains, as in 2D). Bed: x in [0, half_x] (default 3 plate lengths),
    y in [0, half_y] (default 3 plate widths), depth (default the plate test's 4 cm + 2
    plate lengths, the 2D bed's), geostatic stress, a rough floor and far walls (up to 3 cm
    above the surface, ``config.wall_layers`` layers). ``slab`` = n: the plane-strain
    configuration instead, a slab n particles thick in y between two symmetry planes with
    the plate spanning it (the 2D test in 3D). ``mirror_x`` False: both halves in x, with a
    wall at -half_x (a check of the x mirror). ``with_plate`` False: the bed alone.

    ``pose`` (cx, cz, phi): the plate's start in any other placement (centre, m; chord angle
    from +x towards +z, rad; see :data:`POSE`), e.g. the vertical plate of
    :func:`plate_drag3d` or the leg of :func:`leg3d`; it must lie above the floor, and a
    plate not centred on x = 0 horizontally needs both halves of the bed (``mirror_x``
    False).

    ``curvature`` k (as :class:`terradyn.geometry.ArcLeg`'s: chord / (2 radius), in [-1, 1]):
    a curved leg instead of the flat plate, a circular arc of that chord (``length``),
    ``thickness`` and ``width`` bulging towards -n for k > 0 (the C leg hanging down with n
    = +x: its convex side towards -x) and +n for k < 0 (the reverse C). Its markers lie on
    arcs concentric with the mid-arc, ``wall_layers`` per face from dx/2 inside it, spaced
    about dx along each arc; each carries its face's outward normal (radial), the guard keeps
    grains off the tangent plane of their nearest guarded marker, and the side test is
    inside / outside the arc's circle."""
    mat = _material(medium)
    cfg = config or SPHConfig(dx=dx)
    dx = cfg.dx
    positive("length", length, "m")
    positive("width", width, "m")
    positive("thickness", thickness, "m")
    in_range("curvature", curvature, -1.0, 1.0, "(chord / (2 radius))")
    layers = cfg.wall_layers
    hx = half_x if half_x is not None else 3.0 * length
    if slab is not None:
        integer("slab", slab, 2)
        hy = slab * dx
    else:
        hy = half_y if half_y is not None else 3.0 * width
    D = depth if depth is not None else PLATE_TEST["depth_m"] + 2.0 * length
    for name, v in (("half_x", hx), ("half_y", hy), ("depth", D)):
        positive(name, v, "m")
    nx = max(int(round(hx / dx)), 1)
    ny = max(int(round(hy / dx)), 1)
    nzs = max(int(round(D / dx)), 1)
    hx, hy, D = nx * dx, ny * dx, nzs * dx
    if slab is not None and hy < 2.2 * cfg.h + SKIN * cfg.h:
        raise InputError("slab", f"the slab must be at least {math.ceil((2.2 + SKIN) * cfg.hdx)} "
                                 f"particles thick (its mirror ghosts cover one list radius), "
                                 f"got {slab}")
    n_est = estimate_particles(hx, hy, D, dx, layers, mirror_x, slab is not None)
    if n_est > MAX_PARTICLES:
        raise InputError("dx", f"a 3D bed of about {n_est:,} particles (dx = {dx * 1e3:g} mm) is "
                               f"more than the {MAX_PARTICLES:,} this CPU code allows")
    check_memory("dx", n_est * PARTICLE_BYTES_3D,
                 f"a 3D bed of about {n_est:,} particles (dx = {dx * 1e3:g} mm)")
    x_lo = 0.0 if mirror_x else -hx
    soil = _grid3(x_lo, hx, 0.0, hy, -D, 0.0, dx)
    top = max(int(round(0.03 / dx)), 1) * dx  # walls 3 cm above the surface (as in 2D)
    wx_lo = x_lo if mirror_x else x_lo - layers * dx
    wy_hi = hy if slab is not None else hy + layers * dx
    walls = [_grid3(wx_lo, hx + layers * dx, 0.0, wy_hi, -D - layers * dx, -D, dx),
             _grid3(hx, hx + layers * dx, 0.0, hy, -D, top, dx)]
    if not mirror_x:
        walls.append(_grid3(x_lo - layers * dx, x_lo, 0.0, hy, -D, top, dx))
    if slab is None:
        walls.append(_grid3(wx_lo, hx + layers * dx, hy, hy + layers * dx, -D, top, dx))
    walls = np.concatenate(walls)
    # plate markers (body frame: x, y on the plate, z from its centre)
    a = 0.5 * length
    b = hy if slab is not None else 0.5 * width
    t = thickness
    nxm = max(int(round(a / dx)), 1)
    xm = (np.arange(nxm) + 0.5) * (a / nxm)
    if not mirror_x:
        xm = np.concatenate([-xm[::-1], xm])
    if slab is not None:
        ym = (np.arange(ny) + 0.5) * dx
    else:
        nym = max(int(round(b / dx)), 1)
        ym = (np.arange(nym) + 0.5) * (b / nym)
    arc = None
    mk = []
    if curvature == 0.0:
        MX, MY = np.meshgrid(xm, ym, indexing="ij")
        MX, MY = MX.ravel(), MY.ravel()
        guard_xy = (np.abs(MX) < a - 1.5 * dx) & ((slab is not None) | (np.abs(MY) < b - 1.5 * dx))
        for sd in (1.0, -1.0):
            for k in range(layers):
                d = 0.5 * t - (k + 0.5) * dx
                mk.append(np.stack([MX, MY, np.full_like(MX, sd * d), np.full_like(MX, sd),
                                    np.full_like(MX, d), guard_xy.astype(float),
                                    np.zeros_like(MX), np.full_like(MX, sd)], -1))
    else:
        if mirror_x:
            raise InputError("mirror_x", "a curved leg needs both halves of the bed "
                                         "(mirror_x=False)")
        rad = a / abs(curvature)
        half = math.asin(abs(curvature))
        sg = -math.copysign(1.0, curvature)  # the bulge is towards sg n
        qc = -sg * rad * math.cos(half)
        arc = {"r": rad, "qc": qc, "sg": sg, "half_angle": half}
        for sd in (1.0, -1.0):  # +1 the convex (outer) face
            for k in range(layers):
                d = 0.5 * t - (k + 0.5) * dx
                rr = rad + sd * d
                na = max(int(round(rr * 2.0 * half / dx)), 1)
                psi = -half + (np.arange(na) + 0.5) * (2.0 * half / na)
                PS, MY = np.meshgrid(psi, ym, indexing="ij")
                PS, MY = PS.ravel(), MY.ravel()
                er_s, er_q = np.sin(PS), sg * np.cos(PS)
                guard = ((rad * (half - np.abs(PS)) > 1.5 * dx)
                         & ((slab is not None) | (np.abs(MY) < b - 1.5 * dx)))
                mk.append(np.stack([rr * er_s, MY, qc + rr * er_q, np.full_like(PS, sd),
                                    np.full_like(PS, d), guard.astype(float), sd * er_s,
                                    sd * er_q], -1))
    mk = np.concatenate(mk) if with_plate else np.zeros((0, 8))
    if pose is None:  # the plate test: horizontal, over x = 0, dx/2 above the grains
        pose = (0.0, z0 if z0 is not None else 0.5 * t + 0.5 * dx, 0.0)
    cx0, cz0, phi0 = (float(v) for v in pose)
    zc0 = cz0
    if mirror_x and (cx0 != 0.0 or math.sin(phi0) != 0.0):
        raise InputError("mirror_x", "a plate not centred horizontally on x = 0 needs both "
                                     "halves of the bed (mirror_x=False)")
    lowest = cz0 - a * abs(math.sin(phi0)) - 0.5 * t * abs(math.cos(phi0))
    if arc is not None and len(mk):
        lowest = float(np.min(cz0 + mk[:, 0] * math.sin(phi0) + mk[:, 2] * math.cos(phi0))) \
            - 0.5 * dx
    if lowest <= -D:
        raise InputError("pose", f"the plate's lowest point ({-lowest * 100:g} cm deep) must lie "
                                 f"inside the bed ({D * 100:g} cm deep)")
    ux, uz = math.cos(phi0), math.sin(phi0)
    rxs, rzs = soil[:, 0] - cx0, soil[:, 2] - cz0
    # granular particles inside the plate's body at the start (none when it starts above)
    su, sq = rxs * ux + rzs * uz, -rxs * uz + rzs * ux
    if arc is None:
        inside = ((np.abs(su) <= a + 0.5 * dx) & (np.abs(sq) <= 0.5 * t + 0.5 * dx))
    else:
        dq = arc["sg"] * (sq - arc["qc"])
        rr = np.hypot(su, dq)
        inside = ((dq >= rr * math.cos(arc["half_angle"]) - 0.5 * dx)
                  & (np.abs(rr - arc["r"]) <= 0.5 * t + 0.5 * dx))
    inside &= (slab is not None) | (soil[:, 1] <= b + 0.5 * dx)
    mpos = np.stack([cx0 + mk[:, 0] * ux - mk[:, 2] * uz, mk[:, 1],
                     cz0 + mk[:, 0] * uz + mk[:, 2] * ux], -1)
    if with_plate:
        soil = soil[~inside]
    ns, nw, nm = len(soil), len(walls), len(mk)
    pos = np.concatenate([soil, walls, mpos])
    kind = np.concatenate([np.full(ns, SOIL), np.full(nw, WALL), np.full(nm, LEG)]).astype(np.int8)
    n = len(kind)
    rho = np.full(n, mat.density)
    mass = rho * dx ** 3
    sig = np.zeros((n, 6))
    szz = -mat.density * G * np.clip(-soil[:, 2], 0.0, None)
    sig[:ns, S_ZZ] = szz
    sig[:ns, S_XX] = mat.lateral_ratio * szz
    sig[:ns, S_YY] = mat.lateral_ratio * szz
    nzv = np.zeros(n)
    dcl = np.zeros(n)
    grd = np.zeros(n)
    nzv[ns + nw:] = mk[:, 3]
    dcl[ns + nw:] = mk[:, 4]
    grd[ns + nw:] = mk[:, 5]
    box = (x_lo - (0.0 if mirror_x else layers * dx), hx + layers * dx,
           hy + (0.0 if slab is not None else layers * dx), -D - layers * dx)
    meta = {"scene": "plate3d", "dx_m": dx, "half_x_m": hx, "half_y_m": hy, "depth_m": D,
            "slab_layers": slab, "mirror_x": mirror_x, "plate_m": [length, width, thickness],
            "z0_m": zc0, "granular": ns, "wall": nw, "markers": nm, "wall_top_m": top,
            "pose0": [cx0, cz0, phi0], "curvature": float(curvature)}
    return Scene3D(pos, kind, mass, rho, sig, np.zeros((n, 3)), mat, cfg, nzv, dcl, grd,
                   np.ascontiguousarray(mk[:, :3]), mirror=(mirror_x, True, slab is not None), ly=hy, box=box,
                   plate={"a": a, "b": b, "t": t, "slab": slab is not None, "z0": zc0,
                          "pose0": (cx0, cz0, phi0), "arc": arc},
                   depth=D, meta=meta, bn=np.ascontiguousarray(mk[:, 6:8]))


# ----------------------------------------------------------------------------- the solver
class Solver3D:
    """Advances a :class:`Scene3D`: parallel Numba kernels (:func:`steps3d`), or with
    ``SPHConfig(backend="gpu")`` (or ``"auto"`` where Numba sees a GPU) the same physics on an
    NVIDIA GPU (:mod:`terradyn.sph.gpu3d`)."""

    def __init__(self, scene: Scene3D, *, plate_speed: float = 0.0):
        self.scene = sc = scene
        self.plate_speed = plate_speed
        self.resumed_from = None
        cfg = sc.config
        mat = sc.material
        if cfg.channel_width is not None or cfg.wall_friction is not None:
            raise InputError("channel-width", "is a setting of the 2D model (its side walls "
                             "are modelled as friction); a 3D scene has none, got "
                             f"{cfg.channel_width!r} m")
        if cfg.leg_friction is not None:
            raise InputError("leg-friction", "grain-leg slip is in the 2D solver only; the 3D "
                             "solver's plate and legs are rough (no-slip): leave it unset")
        if mat.mu_rise > 0.0:  # dp_update3 has no rate dependence: refuse, never ignore
            raise InputError("rheology", "mu(I) ('mu-i') is in the 2D solver only; the 3D solver's "
                             "friction is rate-independent: use rheology 'constant'")
        from .solver import resolve_backend

        self.backend = resolve_backend(cfg.backend)
        nr = len(sc)
        self.nr = nr
        self.h = cfg.h
        self.rlist = (2.0 + SKIN) * self.h
        self.c0 = mat.sound_speed
        self.dt = cfg.cfl * self.h / (self.c0 + abs(plate_speed))
        self.settle_time = (cfg.settle_time if cfg.settle_time is not None
                            else 15.0 * sc.depth / self.c0)
        self.settle_damping = 2.0 * self.c0 / max(sc.depth, 1e-6)
        near = self._near_planes(sc)
        ng_cap = int(3 * near + 64)
        n = nr + ng_cap
        self.pos = np.zeros((n, 3))
        self.vel = np.zeros((n, 3))
        self.gv = np.zeros((n, 3))
        self.rho = np.zeros(n)
        self.mass = np.zeros(n)
        self.sig = np.zeros((n, 6))
        self.kind = np.full(n, LOST, np.int8)
        self.nz = np.zeros(n)
        self.wn = np.zeros((n, 2))
        self.dcl = np.zeros(n)
        self.grd = np.zeros(n)
        self.side = np.zeros(n)
        self.pos[:nr] = sc.pos
        self.vel[:nr] = sc.vel
        self.rho[:nr] = sc.rho
        self.mass[:nr] = sc.mass
        self.sig[:nr] = sc.sig
        self.kind[:nr] = sc.kind
        self.nz[:nr] = sc.nz
        self.dcl[:nr] = sc.dcl
        self.grd[:nr] = sc.grd
        self.src = np.zeros(n, np.int64)
        self.gs = np.ones((n, 3))
        self.go = np.zeros((n, 3))
        self.lidx = sc.lidx
        self.bo = np.ascontiguousarray(sc.bo, dtype=np.float64)
        bn = sc.bn if sc.bn is not None else np.stack(
            [np.zeros(len(self.lidx)), sc.nz[self.lidx]], -1)
        self.bn = np.ascontiguousarray(bn, dtype=np.float64)
        self.pb = np.full((nr, 3), np.inf)
        n_soil = int(np.sum(sc.kind == SOIL))
        n_bnd = nr - n_soil
        self.ss = np.zeros(int(55 * (n_soil + 0.5 * ng_cap)) + 64, np.int32)
        self.sb = np.zeros(int(60 * min(n_bnd + ng_cap, n_soil + ng_cap)) + 64, np.int32)
        self.sso = np.zeros(n + 1, np.int64)
        self.sbo = np.zeros(n + 1, np.int64)
        self._pair_scratch()
        self.lg = np.zeros((n, 10))
        self.psig = np.zeros((n, 6))
        self.acc = np.zeros((n, 6))
        self.cont = np.zeros((n, 4))
        self.bacc = np.zeros((n, 11))
        # the cell grid: cells >= the list radius over everything that may move
        p = sc.pos
        pad = self.rlist + 2 * cfg.dx
        lo = p.min(axis=0) - pad
        hi = p.max(axis=0) + pad
        lo[2] -= 0.0
        hi[2] += 0.02
        if sc.plate is not None:
            lo[2] = min(lo[2], -PLATE_TEST["depth_m"] - sc.plate["t"] - pad)
        cell = self.rlist
        ncell = np.maximum(np.ceil((hi - lo) / cell).astype(int), 1)
        self.cell_start = np.zeros(int(np.prod(ncell)) + 1, np.int64)
        self.cell_idx = np.zeros(n, np.int64)
        self.rank = np.zeros(n, np.int64)
        self.bounds = np.zeros(MAX_CHUNKS_3D + 1, np.int64)
        self.part = np.zeros((N_BLOCKS_3D, 5))
        plate = sc.plate or {"a": 0.0, "b": 0.0, "t": 0.0, "slab": False}
        pose0 = plate.get("pose0", (0.0, 0.0, 0.0))  # overwritten by every step's pose
        arc = plate.get("arc") or {"r": 0.0, "qc": 0.0, "sg": 0.0, "half_angle": 0.0}
        ux0, uz0 = math.cos(pose0[2]), math.sin(pose0[2])
        self.wn[self.lidx, 0] = self.bn[:, 0] * ux0 - self.bn[:, 1] * uz0
        self.wn[self.lidx, 1] = self.bn[:, 0] * uz0 + self.bn[:, 1] * ux0
        gap = (0.25 if cfg.contact_gap is None else cfg.contact_gap) * cfg.dx
        val = dict(h=self.h, dt=self.dt, shear_mod=mat.shear_modulus, bulk_mod=mat.bulk_modulus,
                   alpha_phi=mat.alpha_phi, k_c=mat.k_c, rho_min=0.9 * mat.density,
                   rho_max=1.1 * mat.density, alpha_psi=mat.alpha_psi,
                   rho_crit=mat.dilation_limit, c0=self.c0, av_alpha=cfg.av_alpha,
                   av_beta=cfg.av_beta, gz=-sc.gravity, half_t=0.5 * plate["t"], gap=gap,
                   max_push=0.1 * cfg.dx, vmax=self.c0, plate_a=plate["a"], plate_b=plate["b"],
                   ly=sc.ly, x_lo=lo[0], y_lo=lo[1], z_lo=lo[2], inv_cell=1.0 / cell,
                   rlist=self.rlist, x_hi_box=sc.box[1], y_hi_box=sc.box[2], z_lo_box=sc.box[3],
                   side_reach=2.0 * self.h + 0.5 * plate["t"], x_lo_box=sc.box[0],
                   p_cx=pose0[0], p_cz=pose0[1], p_ux=math.cos(pose0[2]),
                   p_uz=math.sin(pose0[2]), p_vx=0.0, p_vz=0.0, p_om=0.0, arc_r=arc["r"],
                   arc_qc=arc["qc"], arc_sg=arc["sg"], arc_cos=math.cos(arc["half_angle"]))
        self.fp = np.array([val[k] for k in FP], dtype=np.float64)
        ival = dict(nr=nr, ng=0, nss=0, nsb=0, ncx=ncell[0], ncy=ncell[1], ncz=ncell[2],
                    mirror_x=int(sc.mirror[0]), mirror_y0=int(sc.mirror[1]),
                    mirror_y1=int(sc.mirror[2]), slab=int(bool(plate["slab"])), builds=0,
                    has_plate=int(len(self.lidx) > 0), bad=-1, lost=0,
                    arc=int(plate.get("arc") is not None), nchunk=1)
        self.ip = np.array([ival[k] for k in IP], dtype=np.int64)
        self.t = 0.0
        self.step_count = 0

    def _near_planes(self, sc) -> int:
        r = self.rlist + sc.config.dx
        p = sc.pos
        cnt = 0
        if sc.mirror[0]:
            cnt += int(np.sum(p[:, 0] < r))
        if sc.mirror[1]:
            cnt += int(np.sum(p[:, 1] < r))
        if sc.mirror[2]:
            cnt += int(np.sum(p[:, 1] > sc.ly - r))
        return cnt

    def _pair_scratch(self):
        self.fss = np.zeros(len(self.ss))
        self.fsb = np.zeros(len(self.sb))
        self.wsb = np.zeros(len(self.sb))

    def _grow(self, code):
        """Enlarge the array that did not fit (and force a rebuild)."""
        if code == PAIRS_FULL:
            self.ss = np.zeros(int(1.5 * len(self.ss)), np.int32)
            self.sb = np.zeros(int(1.5 * len(self.sb)), np.int32)
            self._pair_scratch()
        else:
            extra = max(len(self.pos) - self.nr, 64)
            n = len(self.pos) + extra
            for name in ("pos", "vel", "gv", "gs", "go", "sig", "lg", "acc", "cont", "bacc",
                         "psig", "wn"):
                a = getattr(self, name)
                b = np.zeros((n,) + a.shape[1:])
                b[:len(a)] = a
                setattr(self, name, b)
            for name in ("rho", "mass", "nz", "dcl", "grd", "side"):
                a = getattr(self, name)
                b = np.zeros(n)
                b[:len(a)] = a
                setattr(self, name, b)
            k = np.full(n, LOST, np.int8)
            k[:len(self.kind)] = self.kind
            self.kind = k
            s = np.zeros(n, np.int64)
            s[:len(self.src)] = self.src
            self.src = s
            self.cell_idx = np.zeros(n, np.int64)
            self.rank = np.zeros(n, np.int64)
            self.sso = np.zeros(n + 1, np.int64)
            self.sbo = np.zeros(n + 1, np.int64)
        self.ip[I_BUILDS] = 0

    def advance(self, pose, damp) -> np.ndarray:
        """len(pose) steps with the plate at pose[s] (a :data:`POSE` row: centre, chord angle,
        centre velocity, angular velocity), damping damp[s]; returns the force (N, 3) of the
        real granular particles on the plate per step."""
        pose = np.ascontiguousarray(np.atleast_2d(pose), dtype=np.float64)
        damp = np.ascontiguousarray(damp, dtype=np.float64)
        if pose.shape != (len(damp), len(POSE)):
            raise ValueError(f"pose must be ({len(damp)}, {len(POSE)}), got {pose.shape}")
        out = np.zeros((len(pose), 3))
        done = 0
        while done < len(pose):
            if self.backend == "gpu":
                from .gpu3d import steps_gpu

                d, code = steps_gpu(self, pose[done:], damp[done:], out[done:])
            else:
                d, code = steps3d(pose[done:], damp[done:], out[done:], self.pos,
                                  self.vel, self.gv, self.rho, self.mass, self.sig, self.kind,
                                  self.nz, self.wn, self.dcl, self.grd, self.side, self.src,
                                  self.gs, self.go, self.bo, self.bn, self.lidx, self.pb,
                                  self.cell_start, self.cell_idx, self.rank, self.bounds,
                                  self.ss, self.sso, self.sb, self.sbo, self.fss, self.fsb,
                                  self.wsb, self.lg, self.acc, self.cont, self.bacc,
                                  self.psig, self.part, self.fp, self.ip)
            done += int(d)
            self.step_count += int(d)
            self.t += int(d) * self.dt
            if code == UNSTABLE:
                i = int(self.ip[I_BAD])
                raise InputError("plate3d", f"the 3D run went unstable at step {self.step_count}: "
                                            f"particle {i} at {self.pos[i].round(4).tolist()} m "
                                            "(non-finite or faster than sound)")
            if code in (PAIRS_FULL, GHOSTS_FULL):
                self._grow(code)
        return out

    # ---------------------------------------------------------------------------- checkpoints
    def state_dict(self) -> dict:
        """Every array a later step reads (the particles, ghosts, cell order, pair lists and
        their per-pair scratch, the parameter vectors) and the counters, so that a run resumed
        from it is bit-identical to one never stopped. Keys ``s_<name>``."""
        d = {f"s_{k}": v for k, v in vars(self).items() if isinstance(v, np.ndarray)}
        d.update(s_t=np.array(self.t), s_step_count=np.array(self.step_count))
        return d

    def load_state(self, d) -> None:
        """Restore :meth:`state_dict` (a dict or an opened .npz); arrays keep their saved
        sizes (those that grew during the run)."""
        keys = [k for k in d.keys() if k.startswith("s_")]
        names = {k[2:] for k in keys} - {"t", "step_count"}
        missing = {k for k, v in vars(self).items() if isinstance(v, np.ndarray)} - names
        if missing:
            raise KeyError(f"checkpoint lacks {sorted(missing)}")
        for k in names:
            setattr(self, k, np.ascontiguousarray(d[f"s_{k}"]))
        self.t = float(d["s_t"])
        self.step_count = int(d["s_step_count"])

    @property
    def soil(self) -> np.ndarray:
        return np.flatnonzero(self.kind[:self.nr] == SOIL)

    @property
    def lost(self) -> int:
        return int(self.ip[I_LOST])


def force_factor(scene: Scene3D) -> float:
    """Whole plate / sum over the real grains: 2 per mirror plane that halves the plate."""
    f = 2.0 if scene.mirror[0] else 1.0
    if scene.mirror[1] and not scene.plate["slab"]:
        f *= 2.0
    return f


def plate_area(scene: Scene3D) -> float:
    """Area of the whole plate (m^2); for the slab, its length x the slab's thickness, the
    strip the real grains press on (times the x mirror)."""
    pl = scene.plate
    return (2.0 * pl["a"]) * (scene.ly if pl["slab"] else 2.0 * pl["b"])


def fit_alpha(depth: np.ndarray, stress: np.ndarray, fit_from: float) -> dict:
    """The 2D plate test's two fits over depths > fit_from: sigma = alpha |z| through the
    origin (RFT-consistent, :func:`terradyn.sph.calibration.plate_slope`) and the free
    slope and intercept."""
    m = depth > fit_from
    if m.sum() < 2:
        return {"alpha_z": float("nan"), "slope": float("nan"), "intercept_Pa": float("nan")}
    slope, icpt = np.polyfit(depth[m], stress[m], 1)
    return {"alpha_z": float(np.sum(stress[m] * depth[m]) / np.sum(depth[m] ** 2)),
            "slope": float(slope), "intercept_Pa": float(icpt)}


def _schedule(s: Solver3D, duration: float):
    """The steps of a run: damped settling (``s.settle_time``) then ``duration`` s of motion.
    Returns (times, settling mask, time since the motion began, damping per step)."""
    nsteps = int(math.ceil((s.settle_time + duration) / s.dt))
    ts = np.arange(nsteps) * s.dt
    settling = ts < s.settle_time
    return ts, settling, np.maximum(ts - s.settle_time, 0.0), np.where(settling, s.settle_damping, 0.0)


def run_key(scene: Scene3D, pose, damp) -> str:
    """A hash of everything that defines a 3D run (scene, material, settings and the per-step
    motion): a checkpoint resumes only the run that wrote it."""
    import hashlib
    import json

    h = hashlib.sha256()
    cfg = scene.config.run_items()
    h.update(json.dumps({"scene": "3d", "config": cfg, "material": scene.material.describe(),
                         "meta": scene.meta}, sort_keys=True, default=str).encode())
    for a in (scene.pos, scene.kind, scene.mass, scene.sig, scene.nz, scene.dcl, scene.grd,
              scene.bo, scene.bn, pose, damp):
        if a is not None:
            h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()[:16]


def _run_blocks(s: Solver3D, pose, damp, progress=None, after=None, block: int = 2000,
                checkpoint=None, checkpoint_every: float = 60.0):
    """Advance ``s`` through the per-step ``pose`` and ``damp`` in blocks of steps; returns
    the force per step (N, 3). ``progress(done_s, total_s)`` and ``after(steps_done,
    forces)`` after every block. ``checkpoint``: a file where the state is written (atomically)
    every ``checkpoint_every`` wall-clock seconds at a block's end; a rerun of the same run
    resumes from it, bit-identical to a run never stopped, and it is removed at the end. A
    file there that is not a checkpoint of this run is never overwritten or removed (an
    :class:`InputError` on ``checkpoint`` before any step). Where the run resumed is
    ``s.resumed_from`` (None when it did not)."""
    import warnings
    import zipfile
    from pathlib import Path

    from .solver import _checkpoint_key, atomic_savez, check_checkpoint

    n = len(damp)
    forces = np.zeros((n, 3))
    ck = Path(checkpoint) if checkpoint else None
    key = run_key(s.scene, pose, damp) if ck is not None else None
    start = 0
    s.resumed_from = None
    if check_checkpoint(ck, key):
        try:
            with np.load(ck, allow_pickle=False) as d:
                done = int(d["done"])
                if not 0 <= done <= n:
                    raise ValueError("done")
                f = d["forces"]
                s.load_state(d)
            forces[:done] = f[:done]
            start = done
            s.resumed_from = {"checkpoint": str(ck), "step": done, "time_s": done * s.dt,
                              "total_s": n * s.dt}
        except (OSError, KeyError, ValueError, EOFError, zipfile.BadZipFile):
            # this run's checkpoint, damaged: start afresh from the scene (it is overwritten
            # at the next checkpoint); load_state may have replaced some arrays already
            s.__init__(s.scene, plate_speed=s.plate_speed)
    if progress is not None:
        progress(start * s.dt, n * s.dt)
    last = time.perf_counter()
    for k in range(start, n, block):
        forces[k:k + block] = s.advance(pose[k:k + block], damp[k:k + block])
        upto = min(k + block, n)
        if ck is not None and upto < n and time.perf_counter() - last > checkpoint_every:
            if not ck.exists() or _checkpoint_key(ck) == key:
                atomic_savez(ck, key=np.array(key), done=np.array(upto),
                             forces=forces[:upto], **s.state_dict())
            else:
                warnings.warn(f"checkpoint: {ck} was replaced by a file this run did not "
                              "write; it is left alone and the run no longer checkpoints",
                              RuntimeWarning, stacklevel=2)
                ck = None
            last = time.perf_counter()
        if progress is not None:
            progress(upto * s.dt, n * s.dt)
        if after is not None:
            after(upto, forces)
    if ck is not None and _checkpoint_key(ck) == key:
        ck.unlink(missing_ok=True)
    return forces


def plate_push3d(medium: str | GranularMaterial = "3 mm glass CP", *, dx: float = 4e-3,
                 config: SPHConfig | None = None, slab: int | None = None,
                 half_x: float | None = None, half_y: float | None = None,
                 depth: float | None = None, speed: float = PLATE_TEST["speed_m_s"],
                 push_depth: float = PLATE_TEST["depth_m"], n_samples: int = PLATE_TEST["n_samples"],
                 fit_from: float = PLATE_TEST["fit_from_m"], realization: int = 0,
                 mirror_x: bool = True, progress=None, partial=None, checkpoint=None) -> dict:
    """The plate test of :data:`~terradyn.sph.calibration.PLATE_TEST` in 3D: the plate
    pushed straight down at ``speed`` from dx/2 above the surface to ``push_depth`` (centre
    depth), sampled at ``n_samples`` times; stress = whole-plate vertical force / area.
    Returns depth (m), stress (Pa), alpha_z (N/m^3, through the origin over depths >
    fit_from, as the 2D calibration fits it), the free slope and intercept, the lateral
    forces, counts and timings. ``slab``: the plane-strain configuration (see
    :func:`plate_scene`). ``progress(done_s, total_s)`` every block of steps; ``partial(depth,
    stress)``: the samples reached so far (m, Pa), after every block (a long run that is
    stopped still leaves its curve)."""
    positive("speed", speed, "m/s")
    positive("push_depth", push_depth, "m")
    integer("n_samples", n_samples, 3)
    cfg = config or SPHConfig(dx=dx)
    z0 = 0.5 * PLATE_THICKNESS + 0.5 * cfg.dx + 1e-8 * int(realization)
    sc = plate_scene(medium, config=cfg, slab=slab, half_x=half_x, half_y=half_y, depth=depth,
                     mirror_x=mirror_x, z0=z0)
    t_wall = time.perf_counter()
    s = Solver3D(sc, plate_speed=speed)
    T = (push_depth + z0) / speed
    ts, settling, tm, damp = _schedule(s, T)
    nsteps = len(ts)
    pose = np.zeros((nsteps, len(POSE)))
    pose[:, 1] = z0 - speed * tm
    pose[:, 4] = np.where(settling, 0.0, -speed)
    fac = force_factor(sc)
    area = plate_area(sc)
    t = np.linspace(0.0, T, n_samples)

    def after(upto, forces):
        keep = ~settling[:upto]
        if keep.sum() > 1:
            t_now = ts[upto - 1] - s.settle_time
            tt = t[t <= t_now]
            partial(-(z0 - speed * tt), np.interp(tt, ts[:upto][keep] - s.settle_time,
                                                  forces[:upto][keep, 2]) * fac / area)

    forces = _run_blocks(s, pose, damp, progress, after if partial is not None else None,
                         checkpoint=checkpoint)
    keep = ~settling
    t_rec = ts[keep] - s.settle_time
    fz = np.interp(t, t_rec, forces[keep, 2]) * fac
    d = -(z0 - speed * t)
    stress = fz / area
    fits = fit_alpha(d, stress, fit_from)
    wall = time.perf_counter() - t_wall
    return {"depth": d, "stress": stress, **fits, "time": t,
            "fx_quarter_N": np.interp(t, t_rec, forces[keep, 0]),
            "fy_quarter_N": np.interp(t, t_rec, forces[keep, 1]),
            "fz_quarter_N": np.interp(t, t_rec, forces[keep, 2]),
            "force_factor": fac, "area_m2": area, "steps": nsteps, "dt_s": s.dt,
            "particles": s.nr, "ghosts": int(s.ip[I_NG]), "pairs": int(s.ip[I_NSS] + s.ip[I_NSB]),
            "lost": s.lost, "wall_s": wall, "scene": sc.meta, "solver": s,
            "resumed_from": s.resumed_from}


def plate_drag3d(medium: str | GranularMaterial = "3 mm glass CP", *, dx: float = 4e-3,
                 config: SPHConfig | None = None, slab: int | None = None,
                 half_x: float = 0.08, half_y: float | None = None, depth: float | None = None,
                 centre_depth: float = 0.03, travel: float = 0.02, speed: float = 0.02,
                 n_samples: int = 41, realization: int = 0, progress=None,
                 checkpoint=None) -> dict:
    """Li 2013's plate held vertical (attack angle beta = pi/2) and pushed horizontally
    (gamma = 0) in 3D: the virtual rig's point (:func:`terradyn.sph.suite.rig_point`) with
    the plate's real 2.54 cm width instead of plane strain. The plate's centre is
    ``centre_depth`` deep; it starts ``travel``/2 behind x = 0 in the settled bed (the bed
    settles around it) and moves ``travel`` at ``speed``. As in the 2D rig, alpha = force /
    (area x centre depth) averaged over the second half of the travel: alpha_x (against
    the motion) and alpha_z (up), N/m^3. ``slab``: the plane-strain configuration (the
    plate spans a slab between two symmetry planes; the 2D rig's geometry in this code).
    Bed: x in [-half_x, half_x] (the 2D rig's 16 cm), y in [0, half_y] (default 3 plate
    widths), ``depth`` (default the 2D rig's centre depth + travel/2 + 5 cm). ``checkpoint``:
    a file to resume from (see :func:`_run_blocks`)."""
    positive("speed", speed, "m/s")
    positive("travel", travel, "m")
    integer("n_samples", n_samples, 3)
    cfg = config or SPHConfig(dx=dx)
    D = depth if depth is not None else centre_depth + 0.5 * travel + 0.05
    x0 = -0.5 * travel + 1e-8 * int(realization)
    positive("centre_depth", centre_depth, "m")
    # vertical (chord angle -pi/2: the normal along +x), its mid-plane at x0
    sc = plate_scene(medium, config=cfg, slab=slab, half_x=half_x, half_y=half_y, depth=D,
                     mirror_x=False, pose=(x0, -centre_depth, -0.5 * math.pi))
    t_wall = time.perf_counter()
    s = Solver3D(sc, plate_speed=speed)
    T = travel / speed
    ts, settling, tm, damp = _schedule(s, T)
    nsteps = len(ts)
    pose = np.zeros((nsteps, len(POSE)))
    pose[:, 0] = x0 + speed * tm
    pose[:, 1] = -centre_depth
    pose[:, 2] = -0.5 * math.pi
    pose[:, 3] = np.where(settling, 0.0, speed)
    forces = _run_blocks(s, pose, damp, progress, checkpoint=checkpoint)
    fac = force_factor(sc)
    area = plate_area(sc)
    keep = ~settling
    t_rec = ts[keep] - s.settle_time
    t = np.linspace(0.0, T, n_samples)
    fx = np.interp(t, t_rec, forces[keep, 0]) * fac
    fz = np.interp(t, t_rec, forces[keep, 2]) * fac
    late = t >= 0.5 * T
    return {"alpha_x": float(np.mean(-fx[late] / (area * centre_depth))),
            "alpha_z": float(np.mean(fz[late] / (area * centre_depth))),
            "time": t, "fx_N": fx, "fz_N": fz, "force_factor": fac, "area_m2": area,
            "steps": nsteps, "dt_s": s.dt, "particles": s.nr, "ghosts": int(s.ip[I_NG]),
            "lost": s.lost, "wall_s": time.perf_counter() - t_wall, "scene": sc.meta,
            "resumed_from": s.resumed_from}


#: The rotating-leg test's leg shapes in 3D: curvature (chord / (2 radius)) as
#: :mod:`terradyn.geometry`'s presets.
LEG3D_SHAPES = {"flat": 0.0, "c": 1.0, "reverse-c": -1.0}


def leg_curvature(shape: str) -> float:
    """The curvature of a :data:`LEG3D_SHAPES` name (else a one-line :class:`InputError`)."""
    if shape not in LEG3D_SHAPES:
        raise InputError("leg", f"must be one of {', '.join(LEG3D_SHAPES)}, got {shape!r}")
    return LEG3D_SHAPES[shape]


def leg3d(medium: str | GranularMaterial = "poppy LP", *, shape: str = "flat",
          dx: float = 4e-3, config: SPHConfig | None = None, slab: int | None = None,
          half_y: float | None = None, omega: float = 1.1, hip_height: float = 2.0 * CM,
          length: float = 7.62 * CM, width: float = PLATE_WIDTH,
          thickness: float = PLATE_THICKNESS, pad: float = 0.06, n_theta: int = 271,
          realization: int = 0, curvature: float | None = None, progress=None,
          checkpoint=None, so_far: bool = False) -> dict:
    """A leg of the rotating-leg test (:func:`terradyn.sph.suite.leg_vs_measured`: hip
    ``hip_height`` above the surface, omega rad/s, -135..135 deg sampled at ``n_theta``
    angles) in 3D: a rigid leg of chord ``length``, ``width`` and ``thickness`` hanging from
    the hip, ``shape`` one of :data:`LEG3D_SHAPES` (flat: a plate; c / reverse-c: the half
    circle bulging towards / away from the tip's motion, as
    :func:`terradyn.geometry.c_leg`), turning clockwise (theta = 0: straight down; the tip
    sweeps backwards and the bed pushes the leg forwards). Half domain (symmetry plane y =
    0); ``slab``: the plane-strain configuration (the leg spans a slab between two symmetry
    planes: the 2D test in this code). Only the part of the stroke where the leg is within
    2h + dx of the bed is run (as in 2D), after the bed has settled with the leg above it.
    Bed as the 2D test's (:func:`terradyn.sph.api.bed_extent`: the leg's path below the
    surface plus ``pad``). ``curvature``: any other arc (chord / (2 radius), in [-1, 1];
    overrides ``shape``). ``checkpoint``: a file where the run's state is kept (every minute)
    and a rerun resumes from (:func:`_run_blocks`). ``so_far``: run nothing; the curve so far
    of the run (the same arguments) whose ``checkpoint`` is there, stopped or still going:
    angles past the one it reached are NaN, ``reached_deg`` says which, the peaks are those so
    far. Returns theta (rad), Fx (thrust, + forward), Fz (lift, + up) in N, peaks, counts,
    timings and ``resumed_from``."""
    k = leg_curvature(shape) if curvature is None else float(curvature)
    in_range("curvature", k, -1.0, 1.0, "(chord / (2 radius))")
    positive("omega", omega, "rad/s")
    positive("length", length, "m")
    integer("n_theta", n_theta, 3)
    in_range("hip_height", hip_height, -length, length, "m")
    if so_far:  # the checkpoint must be there before the scene is built
        _checkpoint_file(checkpoint)
    cfg = config or SPHConfig(dx=dx)
    margin = 2.0 * cfg.h + cfg.dx
    reach = math.sqrt(max(length ** 2 - max(hip_height, 0.0) ** 2, 0.0))
    half_x = reach + pad
    D = length - hip_height + pad
    theta = np.linspace(-135 * math.pi / 180, 135 * math.pi / 180, n_theta)
    if k == 0.0:  # lowest point of the plate (its tip corner) against the surface
        low = hip_height - length * np.cos(theta) - 0.5 * thickness * np.abs(np.sin(theta))
    else:  # lowest point of the arc's outline, hip frame (x forward, z up, hanging down)
        g = ArcLeg(width, 2, length, k).outline(400)
        c, s_ = np.cos(theta)[:, None], np.sin(theta)[:, None]
        low = hip_height + np.min(-g[None, :, 0] * s_ + g[None, :, 1] * c, axis=1) \
            - 0.5 * thickness
    touch = np.flatnonzero(low < margin)
    if len(touch) == 0:
        raise InputError("hip_height", "the leg never reaches the bed")
    i0, i1 = max(int(touch[0]) - 1, 0), min(int(touch[-1]) + 1, n_theta - 1)
    th0 = float(theta[i0]) + 1e-8 * int(realization)

    def pose_at(th):
        ux, uz = -np.sin(th), -np.cos(th)  # hip -> tip
        cx, cz = 0.5 * length * ux, hip_height + 0.5 * length * uz
        om = -omega  # d phi / dt: clockwise
        return np.stack([cx, cz, np.arctan2(uz, ux), -om * (cz - hip_height), om * cx,
                         np.full_like(cx, om)], -1)

    p0 = pose_at(np.array([th0]))[0]
    sc = plate_scene(medium, config=cfg, length=length, width=width, thickness=thickness,
                     slab=slab, half_x=half_x, half_y=half_y, depth=D, mirror_x=False,
                     pose=(p0[0], p0[1], p0[2]), curvature=k)
    t_wall = time.perf_counter()
    s = Solver3D(sc, plate_speed=omega * length)
    T = (float(theta[i1]) - th0) / omega
    ts, settling, tm, damp = _schedule(s, T)
    nsteps = len(ts)
    th = th0 + omega * tm
    pose = pose_at(th)
    pose[settling, 3:] = 0.0  # the leg waits above the bed while it settles
    keep = ~settling
    reached = None
    if so_far:
        forces, done = _checkpoint_forces(s, pose, damp, checkpoint)
        keep &= np.arange(nsteps) < done
        if not keep.any():
            raise InputError("checkpoint", f"{checkpoint}: the run is still settling the bed "
                                           "(no stroke yet)")
        reached = float(th[keep][-1])
    else:
        forces = _run_blocks(s, pose, damp, progress, checkpoint=checkpoint)
    fac = force_factor(sc)
    Fx = np.zeros(n_theta)
    Fz = np.zeros(n_theta)
    win = slice(i0, i1 + 1)
    Fx[win] = np.interp(theta[win], th[keep], forces[keep, 0]) * fac
    Fz[win] = np.interp(theta[win], th[keep], forces[keep, 2]) * fac
    if reached is not None:
        Fx[theta > reached] = np.nan
        Fz[theta > reached] = np.nan
    return {"theta": theta, "Fx": Fx, "Fz": Fz, "peak_lift": float(np.nanmax(Fz)),
            "peak_thrust": float(np.nanmax(Fx)), "force_factor": fac, "steps": nsteps,
            "reached_deg": None if reached is None else reached * 180 / math.pi,
            "dt_s": s.dt, "particles": s.nr, "ghosts": int(s.ip[I_NG]), "lost": s.lost,
            "wall_s": time.perf_counter() - t_wall, "scene": sc.meta,
            "shape": shape if curvature is None else None, "curvature": k,
            "window_deg": [float(theta[i0] * 180 / math.pi), float(theta[i1] * 180 / math.pi)],
            "resumed_from": s.resumed_from}


def _checkpoint_file(checkpoint) -> str:
    """The run key in the terradyn checkpoint ``checkpoint`` (one-line error if there is none)."""
    from pathlib import Path

    from .solver import _checkpoint_key

    if checkpoint is None:
        raise InputError("checkpoint", "so_far needs the checkpoint file of the run")
    got = _checkpoint_key(Path(checkpoint))
    if got is None:
        raise InputError("checkpoint", f"{checkpoint} is not a terradyn checkpoint (missing or unreadable)")
    return got


def _checkpoint_forces(s: Solver3D, pose, damp, checkpoint) -> tuple[np.ndarray, int]:
    """(forces per step, steps done) held in the checkpoint of this run (``run_key``)."""
    if _checkpoint_file(checkpoint) != run_key(s.scene, pose, damp):
        raise InputError("checkpoint", f"{checkpoint} is not a checkpoint of this run (another scene, "
                                       "resolution or motion): give the run's own arguments")
    with np.load(checkpoint, allow_pickle=False) as d:
        done = int(d["done"])
        f = np.zeros((len(damp), 3))
        f[:done] = d["forces"][:done]
    return f, done


def flat_leg3d(medium: str | GranularMaterial = "poppy LP", **kw) -> dict:
    """:func:`leg3d` with the flat leg."""
    return leg3d(medium, shape="flat", **kw)


def shape_factor(length: float, width: float, friction: float) -> float:
    """Bearing-capacity shape factor of the surcharge term, s_q = 1 + (B/L) tan(phi), B <= L
    the plate's sides (De Beer 1970, as tabulated by Vesic 1973); phi in rad."""
    in_range("friction", friction, 0.0, math.pi / 2, "rad")
    b, l_ = sorted((length, width))
    return 1.0 + (b / l_) * math.tan(friction)

# Cached kernels above use jitted code and constants of other modules: make their on-disk
# cache stale when those change too (terradyn._jitcache; Numba checks only this file).
_bind_cache(globals(), 'terradyn.sph.neighbours', 'terradyn.sph.state')
