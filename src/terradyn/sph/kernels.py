"""Compiled SPH kernels (Numba, multi-threaded on the CPU).

Physics (2D plane strain, per unit depth; tension-positive stress, z up):

* Kernel: Wendland C2 in 2D, W(r, h) = 7 / (4 pi h^2) (1 - q/2)^4 (2 q + 1), q = r/h, support
  2h (Wendland 1995; free of the pairing instability: Dehnen & Aly 2012, MNRAS 425:1068).
* Continuity: d rho_i/dt = sum_j m_j (v_i - v_j) . grad_i W_ij.
* Momentum (Bui et al. 2008, eq. 38):
  dv_i/dt = sum_j m_j (sigma_i / rho_i^2 + sigma_j / rho_j^2 - Pi_ij I) . grad_i W_ij + g,
  Monaghan artificial viscosity Pi_ij = (-a c mu + b mu^2) / rho_ij, mu = h v_ij.x_ij /
  (r^2 + 0.01 h^2) when v_ij.x_ij < 0 (Monaghan 1992).
* Time stepping (two passes per step, symplectic): the velocity gradient from v^n updates
  the stress to sigma^{n+1}; the accelerations from sigma^{n+1} update v and then x.
* Velocity gradient: L_i = sum_j (m_j / rho_j) (v_j - v_i) (x) grad_i W_ij; strain rate and
  spin are its symmetric and antisymmetric parts.
* Constitutive law: elastic-perfectly plastic Drucker-Prager, Jaumann stress rate, elastic
  predictor then Bui et al. (2008) sec. 3.3 return: tension cut-off (shift of the mean stress
  back to the apex) and stress scaling of the deviator onto the yield surface. The flow is
  non-dilatant (psi = 0), the choice Bui et al. found to match their experiment.
* Boundaries: dummy particles (walls, rigid leg) whose stress and velocity are extrapolated
  from the granular particles around them (Adami, Hu & Adams 2012, J. Comput. Phys. 231:7057,
  generalised from pressure to the stress tensor), with the gravity / wall-acceleration term.
  Leg particles belong to one side of the (thin) leg and only see material on that side.

Particle kinds: 0 granular, 1 fixed wall, 2 leg (moving rigid body), 3 lost (left the
container; parked far away and ignored).

One source for CPU and GPU: the physics of one particle or one pair is a plain Python
function of (index, arrays..., scalars) that allocates nothing (``_boundary_one``,
``_gather_one``, ``_pair_fdw``, ``_strain_pair``, ``_stress_term``, ``_accel_pair``,
``dp_update``, ``_kick_one``, ...; registered in :data:`SOURCES`). Here each is compiled as an
inlined ``numba.njit`` function and called from the ``prange`` loops of the CPU kernels;
:mod:`terradyn.sph.gpu` compiles the very same functions as CUDA device functions called from
one-thread-per-particle kernels. The loops around them differ where the hardware does: a GPU
thread visits every neighbour of its particle (no write conflicts); the CPU visits each
granular pair once and adds its terms to both particles (half the pair work; see the
"each granular pair visited once" section below).
"""
from __future__ import annotations

import math

import numba
import numpy as np
from numba import prange

SOIL, WALL, LEG, LOST = 0, 1, 2, 3
_W2D = 7.0 / (4.0 * math.pi)
#: Cells per list radius: cell side = (2 + SKIN) h / REACH, a particle's list candidates
#: lie in the (2 REACH + 1)^2 cells around its own. With REACH = 2 the cells scanned cover
#: about 2 x the disc's area instead of 2.9 x with REACH = 1 (measured faster:
#: benchmarks/bench_sph.py).
REACH = 2
_FM = {"nsz", "arcp", "contract", "afn", "reassoc"}  # fastmath that keeps NaN/inf checks


#: The one source of the per-particle work: plain Python functions of (index, arrays...,
#: scalars) that allocate nothing. Each is compiled here as an inlined ``numba.njit``
#: function that the multi-threaded CPU kernels below call from their ``prange`` loops, and
#: again by :mod:`terradyn.sph.gpu` as a CUDA device function that its one-thread-per-particle
#: kernels call (same code, names re-bound to the device versions). name -> plain function.
SOURCES: dict = {}


def _source(fn):
    """Register ``fn`` as one-source kernel code; returns its CPU (inlined njit) form. The
    fastmath flags are those of the calling kernel (Numba inlines at the IR level)."""
    SOURCES[fn.__name__] = fn
    return numba.njit(inline="always", fastmath=True)(fn)


@_source
def wendland_dw(r, h):
    """(1/r) dW/dr of the 2D Wendland C2 kernel: -35 / (4 pi h^4) (1 - q/2)^3 (0 outside)."""
    q = r / h
    if q >= 2.0:
        return 0.0
    t = 1.0 - 0.5 * q
    return -5.0 * _W2D / (h * h * h * h) * t * t * t


@_source
def wendland_w(r, h):
    q = r / h
    if q >= 2.0:
        return 0.0
    t = 1.0 - 0.5 * q
    return _W2D / (h * h) * t * t * t * t * (2.0 * q + 1.0)


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
def dp_update(rho, drho, lxx, lxz, lzx, lzz, sxx, szz, sxz, syy, dt, shear_mod, bulk_mod,
              alpha_phi, k_c, rho_min, rho_max):
    """One particle's density and Drucker-Prager stress over one step: Jaumann rate + Hooke's
    law (plane strain), then the Bui et al. (2008) return: tension cut-off and stress scaling
    onto the yield surface (non-dilatant flow). The density is kept in [rho_min, rho_max]: a
    dry packing neither compacts nor dilutes much, and grains splashed off the free surface
    must not get tiny densities (their sigma/rho^2 would explode). Returns (rho, sxx, szz,
    sxz, syy)."""
    rho = min(max(rho + dt * drho, rho_min), rho_max)
    exx = lxx
    ezz = lzz
    exz = 0.5 * (lxz + lzx)
    wxz = 0.5 * (lxz - lzx)
    ev = exx + ezz
    third = ev / 3.0
    d_xx = 2.0 * sxz * wxz + 2.0 * shear_mod * (exx - third) + bulk_mod * ev
    d_zz = -2.0 * sxz * wxz + 2.0 * shear_mod * (ezz - third) + bulk_mod * ev
    d_yy = 2.0 * shear_mod * (-third) + bulk_mod * ev
    d_xz = wxz * (szz - sxx) + 2.0 * shear_mod * exz
    s_xx = sxx + dt * d_xx
    s_zz = szz + dt * d_zz
    s_yy = syy + dt * d_yy
    s_xz = sxz + dt * d_xz
    # tension cut-off: -alpha_phi I1 + k_c >= 0
    i1 = s_xx + s_zz + s_yy
    if -alpha_phi * i1 + k_c < 0.0:
        shift = (i1 - k_c / alpha_phi) / 3.0
        s_xx -= shift
        s_zz -= shift
        s_yy -= shift
        i1 = k_c / alpha_phi
    # stress scaling onto the yield surface f = sqrt(J2) + alpha_phi I1 - k_c = 0
    m = i1 / 3.0
    dxx = s_xx - m
    dzz = s_zz - m
    dyy = s_yy - m
    j2 = 0.5 * (dxx * dxx + dzz * dzz + dyy * dyy) + s_xz * s_xz
    lim = -alpha_phi * i1 + k_c
    if j2 > lim * lim and j2 > 0.0:
        rr = lim / math.sqrt(j2)
        dxx *= rr
        dzz *= rr
        dyy *= rr
        s_xz *= rr
    return rho, dxx + m, dzz + m, s_xz, dyy + m


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
def _bnd_pair(xw, zw, f, isleg, nxw, nzw, dclw, ex, ez, x, z, vx, vz, rho, sxx, szz, sxz, syy,
              h, acc):
    """Granular particle ``f`` as a neighbour of a boundary particle at (xw, zw) (see
    :func:`_boundary_one`): its Shepard-weighted sums acc = (sum W, sigma_xx W, sigma_zz W,
    sigma_xz W, sigma_yy W, v_x W, v_z W, hydrostatic term), updated; unchanged outside the
    support or, for a leg particle (isleg; outward normal (nxw, nzw), offset dclw), on the
    leg's other side. (ex, ez) = g - a_w."""
    rx = xw - x[f]
    rz = zw - z[f]
    if isleg and (-rx * nxw - rz * nzw + dclw) <= 0.0:
        return acc
    wgt = wendland_w(math.sqrt(rx * rx + rz * rz), h)
    if wgt == 0.0:
        return acc
    ssum, axx, azz, axz, ayy, avx, avz, hyd = acc
    return (ssum + wgt, axx + sxx[f] * wgt, azz + szz[f] * wgt, axz + sxz[f] * wgt,
            ayy + syy[f] * wgt, avx + vx[f] * wgt, avz + vz[f] * wgt,
            hyd + rho[f] * (ex * rx + ez * rz) * wgt)


@_source
def _boundary_one(kk, x, z, vx, vz, rho, kind, nox, noz, dcl, sxx, szz, sxz, syy, gvx, gvz,
                  bidx, acc_x, acc_z, grav, grid, cell_start, cell_index, noslip, bj, bn,
                  build):
    """Boundary particle ``bidx[kk]``: stress and ghost velocity (see :func:`boundary_state`).
    Reads granular particles only and writes the boundary particle only. grav = (gx, gz);
    grid = (h, xmin, zmin, inv_cell, ncx, ncz). Candidates come from its Verlet list (bj[kk,
    :bn[kk]]: the granular particles within 2h + skin at the last build, -1: more than fit, or
    no list: search the cells), made here from the cells if ``build``. (Calls with more than
    30 arguments become *args calls in CPython's bytecode, which Numba cannot inline: hence
    the tuples.)"""
    gx, gz = grav
    h, xmin, zmin, inv_cell, ncx, ncz = grid
    w = bidx[kk]
    xw = x[w]
    zw = z[w]
    cx, cz = _cell_xz(xw, zw, xmin, zmin, inv_cell, ncx, ncz)
    acc = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    isleg = kind[w] == LEG
    nxw = nox[w]
    nzw = noz[w]
    dclw = dcl[w]
    ex = gx - acc_x[w]
    ez = gz - acc_z[w]
    maxn = bj.shape[1]
    if build:
        rl2 = ((2.0 + SKIN) * h) ** 2
        cnt = 0
        for dz in range(-REACH, REACH + 1):
            lo, hi = _row_span(cx, cz, dz, ncx, ncz, cell_start)
            for p in range(lo, hi):
                f = cell_index[p]
                if kind[f] == SOIL:
                    rx = xw - x[f]
                    rz = zw - z[f]
                    if rx * rx + rz * rz < rl2:
                        if cnt < maxn:
                            bj[kk, cnt] = f
                        cnt += 1
        bn[kk] = cnt if cnt <= maxn else -1
    cnt = bn[kk]
    if cnt >= 0:
        for n in range(cnt):
            f = bj[kk, n]
            if kind[f] == SOIL:
                acc = _bnd_pair(xw, zw, f, isleg, nxw, nzw, dclw, ex, ez, x, z, vx, vz, rho,
                                sxx, szz, sxz, syy, h, acc)
    else:
        for dz in range(-REACH, REACH + 1):
            lo, hi = _row_span(cx, cz, dz, ncx, ncz, cell_start)
            for p in range(lo, hi):
                f = cell_index[p]
                if kind[f] == SOIL:
                    acc = _bnd_pair(xw, zw, f, isleg, nxw, nzw, dclw, ex, ez, x, z, vx, vz,
                                    rho, sxx, szz, sxz, syy, h, acc)
    ssum, axx, azz, axz, ayy, avx, avz, hyd = acc
    if ssum > 0.0:
        inv = 1.0 / ssum
        # p_w = <p> + rho (g - a_w).(x_w - x_f) (Adami 2012); sigma = -p I, tension
        # positive: a wall below the material carries more compression.
        p_add = -hyd * inv
        sxx[w] = axx * inv + p_add
        szz[w] = azz * inv + p_add
        syy[w] = ayy * inv + p_add
        sxz[w] = axz * inv
        if noslip:
            gvx[w] = 2.0 * vx[w] - avx * inv
            gvz[w] = 2.0 * vz[w] - avz * inv
        else:
            gvx[w] = avx * inv
            gvz[w] = avz * inv
    else:
        sxx[w] = 0.0
        szz[w] = 0.0
        syy[w] = 0.0
        sxz[w] = 0.0
        gvx[w] = vx[w]
        gvz[w] = vz[w]


@_source
def _gather_one(k, cell_index, x, z, vx, vz, gvx, gvz, rho, mass, kind, nox, noz, dcl, guard,
                sxx, szz, sxz, out_f, out_k):
    """Column ``k`` (cell order) of :func:`gather`'s copy."""
    i = cell_index[k]
    r = rho[i]
    inv2 = 1.0 / (r * r)
    out_f[0, k] = x[i]
    out_f[1, k] = z[i]
    if kind[i] == SOIL:
        out_f[2, k] = vx[i]
        out_f[3, k] = vz[i]
    else:
        out_f[2, k] = gvx[i]
        out_f[3, k] = gvz[i]
    out_f[4, k] = sxx[i] * inv2
    out_f[5, k] = szz[i] * inv2
    out_f[6, k] = sxz[i] * inv2
    out_f[7, k] = mass[i] / r
    out_f[8, k] = r
    out_f[9, k] = nox[i]
    out_f[10, k] = noz[i]
    out_k[0, k] = kind[i]
    out_k[1, k] = dcl[i]
    out_k[2, k] = guard[i]


@_source
def _regather_one(k, cell_index, vx, vz, gvx, gvz, rho, mass, kind, sxx, szz, sxz, out_f):
    """Column ``k`` of :func:`regather`."""
    i = cell_index[k]
    r = rho[i]
    inv2 = 1.0 / (r * r)
    if kind[i] != SOIL:
        out_f[2, k] = gvx[i]
        out_f[3, k] = gvz[i]
    out_f[4, k] = sxx[i] * inv2
    out_f[5, k] = szz[i] * inv2
    out_f[6, k] = sxz[i] * inv2
    out_f[7, k] = mass[i] / r
    out_f[8, k] = r


@_source
def _support(h):
    """(squared support radius (2h)^2, the factor of :func:`wendland_dw`'s -35 / (4 pi h^4),
    1 / h): the constants of the pair loops' kernel-gradient factor (:func:`_pair_fdw`)."""
    return 4.0 * h * h, -5.0 * _W2D / (h * h * h * h), 1.0 / h


@_source
def _pair_fdw(j, rx, rz, KND, NOX, NOZ, DCL, sup2, inv_h, dwc, si):
    """Kernel-gradient factor of granular particle i and column j (grad_i W = fdw r_ij, r_ij
    = (rx, rz) = x_i - x_j): 0 outside the support, when j is a leg particle on the other
    side of the (thin) leg, or when j is granular and the two lie on opposite sides of the
    leg (``si``, DCL[j]: the sides of i and j, +1 / -1 near the leg, 0 elsewhere; see
    :func:`_side_one`: the body is not transparent to the material's own stress), else
    negative. Written without branches: the compiler turns the branching form into code an
    order of magnitude slower (benchmarks/bench_sph.py)."""
    r2 = rx * rx + rz * rz
    t = 1.0 - 0.5 * math.sqrt(r2) * inv_h
    knd = KND[j]
    inside = ((r2 < sup2) and (knd != LEG or rx * NOX[j] + rz * NOZ[j] + DCL[j] > 0.0)
              and (knd != SOIL or si * DCL[j] >= 0.0))
    return dwc * t * t * t if inside else 0.0


@_source
def _strain_terms(rx, rz, dvx, dvz, fdw):
    """Pass 1 terms of a pair per unit volume of the other particle, seen from i (r_ij = (rx,
    rz), v_i - v_j = (dvx, dvz), grad_i W_ij = fdw r_ij): (dv . grad W, and the four
    components of dv (x) grad W). Particle i gets d rho += m_j (first) and L -= V_j (rest);
    particle j the same with m_i, V_i (grad_j W_ji = -grad_i W_ij, v_j - v_i = -dv)."""
    gwx = fdw * rx
    gwz = fdw * rz
    return (dvx * gwx + dvz * gwz, dvx * gwx, dvx * gwz, dvz * gwx, dvz * gwz)


@_source
def _strain_pair(j, xi, zi, vxi, vzi, X, Z, VX, VZ, VOL, RHO, NOX, NOZ, KND, DCL, sup2, inv_h,
                 dwc, si, acc):
    """Column ``j`` as a neighbour of :func:`_strain_stress_one`'s particle: returns (fdw,
    running sums (d rho, Lxx, Lxz, Lzx, Lzz)); fdw = 0 (and no contribution) outside the
    support or on the other side of the leg, else the kernel-gradient factor
    (grad W = fdw r_ij)."""
    rx = xi - X[j]
    rz = zi - Z[j]
    fdw = _pair_fdw(j, rx, rz, KND, NOX, NOZ, DCL, sup2, inv_h, dwc, si)
    if fdw == 0.0:
        return 0.0, acc
    dvg, txx, txz, tzx, tzz = _strain_terms(rx, rz, vxi - VX[j], vzi - VZ[j], fdw)
    dr, gxx, gxz, gzx, gzz = acc
    volj = VOL[j]
    return fdw, (dr + volj * RHO[j] * dvg, gxx - volj * txx, gxz - volj * txz,
                 gzx - volj * tzx, gzz - volj * tzz)


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
def _strain_stress_one(k, X, Z, VX, VZ, VOL, RHO, NOX, NOZ, KND, DCL, cell_index, cell_start,
                       rho, sxx, szz, sxz, syy, vj, vn, nbj, nbw, nbn, par):
    """Column ``k`` (cell order) of :func:`strain_stress`: the velocity gradient and new
    density and stress of its particle if granular.

    Candidates come from a Verlet list (vj: columns of every particle within the list radius
    ``rlist`` = 2h + skin when it was built, vn: their count, -1 when they did not fit in
    vj's width). With ``build`` true the list is made here from the cells; it stays valid
    while no particle has moved more than skin / 2 since (the solver checks that and keeps
    the cell order of the build until then). The neighbours found (inside the support, on
    this side of the leg) go to pass 2's list: nbj (columns), nbw (kernel-gradient factors),
    nbn (count; -1 if the Verlet list overflowed: pass 2 searches the cells too). The arrays
    are separate arguments, not a tuple: see :func:`_accel_kick_one`. X ... DCL: rows of the gathered copy; par = (h, xmin, zmin,
    inv_cell, ncx, ncz, dt, shear_mod, bulk_mod, alpha_phi, k_c, rho_min, rho_max, rlist,
    build)."""
    if KND[k] != SOIL:
        return
    (h, xmin, zmin, inv_cell, ncx, ncz, dt, shear_mod, bulk_mod, alpha_phi, k_c, rho_min,
     rho_max, rlist, build) = par
    sup2, dwc, inv_h = _support(h)
    i = cell_index[k]
    xi = X[k]
    zi = Z[k]
    vxi = VX[k]
    vzi = VZ[k]
    cx, cz = _cell_xz(xi, zi, xmin, zmin, inv_cell, ncx, ncz)
    if build:
        _build_list(k, xi, zi, cx, cz, X, Z, KND, False, rlist, ncx, ncz, cell_start, vj, vn)
    acc = (0.0, 0.0, 0.0, 0.0, 0.0)
    cnt = vn[k]
    nbn[k] = -1
    if cnt >= 0:
        m = 0
        for n in range(cnt):
            j = vj[k, n]
            fdw, acc = _strain_pair(j, xi, zi, vxi, vzi, X, Z, VX, VZ, VOL, RHO, NOX, NOZ, KND,
                                    DCL, sup2, inv_h, dwc, DCL[k], acc)
            if fdw != 0.0:
                nbj[k, m] = j
                nbw[k, m] = fdw
                m += 1
        nbn[k] = m
    else:
        for dz in range(-REACH, REACH + 1):
            lo, hi = _row_span(cx, cz, dz, ncx, ncz, cell_start)
            for j in range(lo, hi):
                fdw, acc = _strain_pair(j, xi, zi, vxi, vzi, X, Z, VX, VZ, VOL, RHO, NOX, NOZ,
                                        KND, DCL, sup2, inv_h, dwc, DCL[k], acc)
    dr, gxx, gxz, gzx, gzz = acc
    rho[i], sxx[i], szz[i], sxz[i], syy[i] = dp_update(
        rho[i], dr, gxx, gxz, gzx, gzz, sxx[i], szz[i], sxz[i], syy[i], dt, shear_mod,
        bulk_mod, alpha_phi, k_c, rho_min, rho_max)


@_source
def _stress_term(j, fdw, rx, rz, VX, VZ, PXX, PZZ, PXZ, RHO, KND, pp):
    """The momentum equation's pair term per unit mass of ``j``: (sigma_i / rho_i^2 +
    sigma_j / rho_j^2 - Pi_ij I) . grad_i W_ij (i: the particle of ``pp``, r_ij = (rx, rz),
    grad_i W_ij = fdw r_ij); particle j feels minus it per unit mass of i. Returns (tx, tz)."""
    (h, h2, c0, av_alpha, av_beta, av_boundary, half_t, hip_x, hip_z, xi, zi, vxi, vzi, rhoi,
     pxx, pzz, pxz, mi) = pp
    gwx = fdw * rx
    gwz = fdw * rz
    vdotr = (vxi - VX[j]) * rx + (vzi - VZ[j]) * rz
    pi_ij = 0.0
    if vdotr < 0.0 and (KND[j] == SOIL or av_boundary):
        mu = h * vdotr / (rx * rx + rz * rz + 0.01 * h2)
        pi_ij = (-av_alpha * c0 * mu + av_beta * mu * mu) / (0.5 * (rhoi + RHO[j]))
    txx = pxx + PXX[j] - pi_ij
    tzz = pzz + PZZ[j] - pi_ij
    txz = pxz + PXZ[j]
    return txx * gwx + txz * gwz, txz * gwx + tzz * gwz


@_source
def _accel_pair(j, fdw, X, Z, VX, VZ, PXX, PZZ, PXZ, VOL, RHO, NOX, NOZ, KND, DCL, GRD, pp,
                acc):
    """One neighbour ``j`` (column of the gathered copy, inside the support, on the same side
    of the leg) of :func:`_accel_kick_one`'s particle; fdw: the kernel gradient factor
    (grad W = fdw r_ij). pp: that particle's scalars, acc: its running sums (a_x, a_z, fx, fz,
    torque, dmin, pnx, pnz); returns the updated sums."""
    half_t = pp[6]
    hip_x = pp[7]
    hip_z = pp[8]
    mi = pp[17]
    a_x, a_z, fx, fz, tq, dmin, pnx, pnz = acc
    rx = pp[9] - X[j]
    rz = pp[10] - Z[j]
    tx, tz = _stress_term(j, fdw, rx, rz, VX, VZ, PXX, PZZ, PXZ, RHO, KND, pp)
    mj = VOL[j] * RHO[j]
    pax = mj * tx
    paz = mj * tz
    a_x += pax
    a_z += paz
    if KND[j] == LEG:
        if GRD[j] > 0.0:
            dn = rx * NOX[j] + rz * NOZ[j] + DCL[j] - half_t
            if dn < dmin:
                dmin = dn
                pnx = NOX[j]
                pnz = NOZ[j]
        # reaction on the leg, applied at the leg particle
        fx -= mi * pax
        fz -= mi * paz
        tq -= mi * ((X[j] - hip_x) * paz - (Z[j] - hip_z) * pax)
    return (a_x, a_z, fx, fz, tq, dmin, pnx, pnz)


@_source
def _accel_pp(k, X, Z, VX, VZ, PXX, PZZ, PXZ, RHO, mi, par):
    """The scalars of column ``k`` that its pair terms read (``pp`` of :func:`_accel_pair`)."""
    h = par[0]
    return (h, h * h, par[6], par[7], par[8], par[9], par[17], par[12], par[13], X[k], Z[k],
            VX[k], VZ[k], RHO[k], PXX[k], PZZ[k], PXZ[k], mi)


@_source
def _kick_one(i, xi, zi, vxi, vzi, acc, mass, x, z, vx, vz, rho, sxx, szz, fleg, bad, par):
    """Kick, contact and drift of granular particle ``i`` (at xi, zi with velocity vxi, vzi
    at the start of the step) from its summed pair terms acc = (a_x, a_z, fx, fz, torque,
    dmin, pnx, pnz) (see :func:`_accel_pair`); writes its velocity, position and force on
    the leg. Returns 1 if it went non-finite or too fast, else 0."""
    (h, xmin, zmin, inv_cell, ncx, ncz, c0, av_alpha, av_beta, av_boundary, gx, gz, hip_x,
     hip_z, hip_vx, hip_vz, omega, half_t, gap, max_push, dt, fdamp, vmax_allowed) = par
    a_x, a_z, fx, fz, tq, dmin, pnx, pnz = acc
    nvx = (vxi + dt * (a_x + gx)) * fdamp
    nvz = (vzi + dt * (a_z + gz)) * fdamp
    if pnx != 0.0 or pnz != 0.0:
        rx = xi - hip_x
        rz = zi - hip_z
        vn = (nvx - hip_vx - omega * rz) * pnx + (nvz - hip_vz + omega * rx) * pnz
        if vn < 0.0:
            nvx -= vn * pnx
            nvz -= vn * pnz
            cfx = mass[i] * vn * pnx / dt
            cfz = mass[i] * vn * pnz / dt
            fx += cfx
            fz += cfz
            tq += rx * cfz - rz * cfx
    fleg[i, 0] = fx
    fleg[i, 1] = fz
    fleg[i, 2] = tq
    dp = min(gap - dmin, max_push)
    vx[i] = nvx
    vz[i] = nvz
    x[i] = xi + dt * nvx + dp * pnx
    z[i] = zi + dt * nvz + dp * pnz
    ok = (nvx * nvx + nvz * nvz < vmax_allowed * vmax_allowed) and math.isfinite(
        x[i] + z[i] + rho[i] + sxx[i] + szz[i])
    if ok:
        bad[i] = 0
        return 0
    bad[i] = 1
    return 1


@_source
def _accel_kick_one(k, X, Z, VX, VZ, PXX, PZZ, PXZ, VOL, RHO, NOX, NOZ, KND, DCL, GRD,
                    cell_index, cell_start, mass, x, z, vx, vz, rho, sxx, szz, fleg, bad, nb,
                    par):
    """Column ``k`` (cell order) of the GPU's pass 2: acceleration, force on the leg, contact
    guard, kick and drift of its particle if granular, every neighbour visited from this
    side (the CPU's pass 2, :func:`accelerations_kick`, visits each granular pair once).
    Returns 1 if the particle went non-finite or too fast, else 0 (also 0 for non-granular
    columns). X ... GRD: rows of the gathered copy; nb = (nbj, nbw, nbn): the neighbour list
    of pass 1, read only (positions have not moved since; a negative count: the list
    overflowed, search the cells again); par: the scalars (see :func:`_accel_par`)."""
    if KND[k] != SOIL:
        return 0
    h = par[0]
    sup2, dwc, inv_h = _support(h)
    i = cell_index[k]
    pp = _accel_pp(k, X, Z, VX, VZ, PXX, PZZ, PXZ, RHO, mass[i], par)
    xi = X[k]
    zi = Z[k]
    acc = (0.0, 0.0, 0.0, 0.0, 0.0, par[18], 0.0, 0.0)
    nbj, nbw, nbn = nb
    cnt = nbn[k]
    if cnt >= 0:
        for n in range(cnt):
            acc = _accel_pair(nbj[k, n], nbw[k, n], X, Z, VX, VZ, PXX, PZZ, PXZ, VOL, RHO, NOX,
                              NOZ, KND, DCL, GRD, pp, acc)
    else:
        cx, cz = _cell_xz(xi, zi, par[1], par[2], par[3], par[4], par[5])
        for dz in range(-REACH, REACH + 1):
            lo, hi = _row_span(cx, cz, dz, par[4], par[5], cell_start)
            for j in range(lo, hi):
                fdw = _pair_fdw(j, xi - X[j], zi - Z[j], KND, NOX, NOZ, DCL, sup2, inv_h, dwc, DCL[k])
                if fdw != 0.0:
                    acc = _accel_pair(j, fdw, X, Z, VX, VZ, PXX, PZZ, PXZ, VOL, RHO, NOX, NOZ,
                                      KND, DCL, GRD, pp, acc)
    return _kick_one(i, xi, zi, VX[k], VZ[k], acc, mass, x, z, vx, vz, rho, sxx, szz, fleg,
                     bad, par)


@_source
def _accel_par(h, c0, av_alpha, av_beta, av_boundary, gx, gz, hip_x, hip_z, hip_vx, hip_vz,
               omega, half_t, gap, max_push, xmin, zmin, inv_cell, ncx, ncz, dt, damping,
               vmax_allowed):
    """The scalars of :func:`_accel_kick_one` as one tuple (CPython turns calls with more
    than 30 arguments into *args calls, which Numba cannot inline)."""
    fdamp = 1.0 / (1.0 + damping * dt)
    return (h, xmin, zmin, inv_cell, ncx, ncz, c0, av_alpha, av_beta, av_boundary, gx, gz,
            hip_x, hip_z, hip_vx, hip_vz, omega, half_t, gap, max_push, dt, fdamp, vmax_allowed)


@_source
def _place_one(kk, c, s, x, z, vx, vz, acc_x, acc_z, nox, noz, lidx, bx, bz, bnx, bnz, hip_x,
               hip_z, hip_vx, hip_vz, hip_ax, hip_az, omega, alpha):
    """Leg particle ``lidx[kk]`` at its rigid pose (see :func:`place_rigid`; c, s: cosine and
    sine of the angle)."""
    w = lidx[kk]
    rx = c * bx[kk] + s * bz[kk]
    rz = -s * bx[kk] + c * bz[kk]
    x[w] = hip_x + rx
    z[w] = hip_z + rz
    # clockwise rotation: v = v_hip + omega * (rz, -rx)
    vx[w] = hip_vx + omega * rz
    vz[w] = hip_vz - omega * rx
    acc_x[w] = hip_ax + alpha * rz - omega * omega * rx
    acc_z[w] = hip_az - alpha * rx - omega * omega * rz
    nox[w] = c * bnx[kk] + s * bnz[kk]
    noz[w] = -s * bnx[kk] + c * bnz[kk]


@_source
def _side_one(i, x, z, kind, dcl, cl, hip_x, hip_z, c, s, box, reach2):
    """Which side of the leg granular particle ``i`` is on, written to dcl[i] (its slot of
    the per-particle offset array, unused by granular particles): +1 / -1 where it lies
    within ``reach2`` (squared distance) of the leg's centre line ``cl`` ((2, m) body-frame
    polyline from hip to tip) and beside it (its foot point is not past either end), on the
    side of the body normal (-t_z, t_x) or the other; 0 elsewhere. ``box`` = (x0, x1, z0,
    z1): the polyline's body-frame bounding box grown by the reach (a cheap reject).
    :func:`_pair_fdw` drops granular pairs whose sides differ: a body thinner than the
    kernel support would otherwise pass stress straight through itself."""
    if kind[i] != SOIL:
        return
    dx = x[i] - hip_x
    dz = z[i] - hip_z
    bx = c * dx - s * dz  # into the body frame (the inverse of _place_one's rotation)
    bz = s * dx + c * dz
    side = 0.0
    if box[0] <= bx <= box[1] and box[2] <= bz <= box[3]:
        m = cl.shape[1]
        best = reach2
        for k in range(m - 1):
            tx = cl[0, k + 1] - cl[0, k]
            tz = cl[1, k + 1] - cl[1, k]
            rx = bx - cl[0, k]
            rz = bz - cl[1, k]
            ll = tx * tx + tz * tz
            u = (rx * tx + rz * tz) / ll
            past = (k == 0 and u < 0.0) or (k == m - 2 and u > 1.0)
            u = min(max(u, 0.0), 1.0)
            ex = rx - u * tx
            ez = rz - u * tz
            d2 = ex * ex + ez * ez
            if d2 < best:
                best = d2
                if past:
                    side = 0.0
                elif rz * tx - rx * tz > 0.0:  # r . (-t_z, t_x)
                    side = 1.0
                else:
                    side = -1.0
    dcl[i] = side


#: Verlet-list skin as a fraction of h: lists hold the particles within 2h + SKIN h and are
#: rebuilt when a particle has moved SKIN h / 2 (cells grow to (2 + SKIN) h / REACH).
SKIN = 0.2


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
        buf[j, 0] += voli * RHO[k] * dvg
        buf[j, 1] -= voli * txx
        buf[j, 2] -= voli * txz
        buf[j, 3] -= voli * tzx
        buf[j, 4] -= voli * tzz
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
    cells) and adds its sums to buf[k]. par = (h, xmin, zmin, inv_cell, ncx, ncz, rlist,
    build)."""
    if KND[k] != SOIL:
        return
    h, xmin, zmin, inv_cell, ncx, ncz, rlist, build = par
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
    buf[k, 0] += dr
    buf[k, 1] += gxx
    buf[k, 2] += gxz
    buf[k, 3] += gzx
    buf[k, 4] += gzz


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
    mi = pp[17]
    buf[j, 0] -= mi * tx
    buf[j, 1] -= mi * tz
    mj = VOL[j] * RHO[j]
    a_x, a_z, fx, fz, tq, dmin, pnx, pnz = acc
    return (a_x + mj * tx, a_z + mj * tz, fx, fz, tq, dmin, pnx, pnz)


@numba.njit(inline="always", fastmath=True)
def _accel_half_one(k, X, Z, VX, VZ, PXX, PZZ, PXZ, VOL, RHO, NOX, NOZ, KND, DCL, GRD,
                    cell_index, cell_start, mass, nbj, nbw, nbn, buf, fleg, cont, par):
    """Pass 2's pair sums of granular column ``k`` over its half list (see
    :func:`_strain_half_one`): accelerations to buf[k, 0:2], its force on the leg to
    fleg[i], the contact guard's nearest leg surface (dmin, nx, nz) to cont[k]."""
    if KND[k] != SOIL:
        return
    h = par[0]
    sup2, dwc, inv_h = _support(h)
    i = cell_index[k]
    pp = _accel_pp(k, X, Z, VX, VZ, PXX, PZZ, PXZ, RHO, mass[i], par)
    xi = X[k]
    zi = Z[k]
    acc = (0.0, 0.0, 0.0, 0.0, 0.0, par[18], 0.0, 0.0)
    cnt = nbn[k]
    if cnt >= 0:
        for n in range(cnt):
            acc = _accel_half_pair(k, nbj[k, n], nbw[k, n], X, Z, VX, VZ, PXX, PZZ, PXZ, VOL,
                                   RHO, NOX, NOZ, KND, DCL, GRD, pp, buf, acc)
    else:
        cx, cz = _cell_xz(xi, zi, par[1], par[2], par[3], par[4], par[5])
        for dz in range(-REACH, REACH + 1):
            lo, hi = _row_span(cx, cz, dz, par[4], par[5], cell_start)
            for j in range(lo, hi):
                if _wanted(k, j, KND):
                    fdw = _pair_fdw(j, xi - X[j], zi - Z[j], KND, NOX, NOZ, DCL, sup2, inv_h,
                                    dwc, DCL[k])
                    if fdw != 0.0:
                        acc = _accel_half_pair(k, j, fdw, X, Z, VX, VZ, PXX, PZZ, PXZ, VOL,
                                               RHO, NOX, NOZ, KND, DCL, GRD, pp, buf, acc)
    a_x, a_z, fx, fz, tq, dmin, pnx, pnz = acc
    buf[k, 0] += a_x
    buf[k, 1] += a_z
    fleg[i, 0] = fx
    fleg[i, 1] = fz
    fleg[i, 2] = tq
    cont[k, 0] = dmin
    cont[k, 1] = pnx
    cont[k, 2] = pnz


#: Most chunks of the pair passes (a multiple of 4: balanced on 1, 2 and 4 threads).
MAX_CHUNKS = 64


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


# ------------------------------------------------------------------ CPU kernels (prange)
@numba.njit(cache=True)
def column_sums3(a):
    """(sum a[:, 0], sum a[:, 1], sum a[:, 2]) of an (N, 3) array, as floats (the leg force
    of a step; NumPy's sum costs ~40 us of dispatch on a few thousand rows)."""
    s0 = 0.0
    s1 = 0.0
    s2 = 0.0
    for i in range(a.shape[0]):
        s0 += a[i, 0]
        s1 += a[i, 1]
        s2 += a[i, 2]
    return s0, s1, s2


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


@numba.njit(parallel=True, fastmath=True, cache=True)
def boundary_state(x, z, vx, vz, rho, mass, kind, nox, noz, dcl, sxx, szz, sxz, syy,
                   gvx, gvz, bidx, acc_x, acc_z, gx, gz, h,
                   xmin, zmin, inv_cell, ncx, ncz, cell_start, cell_index, noslip, bj, bn,
                   build):
    """Stress and ghost velocity of every boundary particle (ids ``bidx``) from the granular
    particles around it (Shepard average + hydrostatic term). acc_x/acc_z: (N,) wall
    accelerations. ``noslip``: ghost velocity 2 v_w - <v>; else <v> (free slip). bj, bn:
    the boundary particles' Verlet lists (rows as ``bidx``), rebuilt if ``build``."""
    grav = (gx, gz)
    grid = (h, xmin, zmin, inv_cell, ncx, ncz)
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
                  rho_max, vj, vn, nbj, nbw, nbn, rlist, build, buf, bounds, nchunk):
    """First pass (velocities only): d rho/dt and the velocity gradient L of every granular
    particle (lxx = dvx/dx, lxz = dvx/dz, ...), then its new density and stress
    (:func:`dp_update`). Reads only the cell-ordered copies made by :func:`gather`, so it can
    write the new state by particle id. vj, vn: the half Verlet lists, rebuilt from the cells
    if ``build`` with radius ``rlist``; nbj, nbw, nbn: pass 2's lists
    (:func:`neighbour_list`); buf: (N, 5) zeros, left zero; bounds, nchunk: the chunks of
    :func:`chunk_bounds`."""
    X = srt[0]
    Z = srt[1]
    VX = srt[2]
    VZ = srt[3]
    VOL = srt[7]
    RHO = srt[8]
    NOX = srt[9]
    NOZ = srt[10]
    KND = srtk[0]
    DCL = srtk[1]
    par = (h, xmin, zmin, inv_cell, ncx, ncz, rlist, build)
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
            rho[i], buf[k, 0], buf[k, 1], buf[k, 2], buf[k, 3], buf[k, 4], sxx[i], szz[i],
            sxz[i], syy[i], dt, shear_mod, bulk_mod, alpha_phi, k_c, rho_min, rho_max)
        for f in range(5):
            buf[k, f] = 0.0


@numba.njit(parallel=True, fastmath=_FM, cache=True)  # _FM: the NaN checks must stay
def accelerations_kick(srt, srtk, cell_index, mass, h, c0, av_alpha, av_beta, av_boundary, gx,
                       gz, hip_x, hip_z, hip_vx, hip_vz, omega, half_t, gap, max_push, xmin, zmin,
                       inv_cell, ncx, ncz, cell_start, x, z, vx, vz, rho, sxx, szz, dt, damping,
                       vmax_allowed, fleg, bad, nbj, nbw, nbn, buf, cont, bounds, nchunk):
    """Second pass (stresses): acceleration of every granular particle, the force it exerts on
    the leg (fleg[i] = (Fx, Fz, torque about (hip_x, hip_z)), per unit depth), and its kick and
    drift: v += dt a (optionally damped), x += dt v (symplectic Euler). The pair sums read
    only the cell-ordered copies made by :func:`gather`; the particles move after them.
    Returns the number of particles that went non-finite or faster than ``vmax_allowed``
    (``bad[i]`` = 1 for those). buf: (N, 5) zeros, left zero; cont: (N, 3) scratch; bounds,
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
    X = srt[0]
    Z = srt[1]
    VX = srt[2]
    VZ = srt[3]
    PXX = srt[4]
    PZZ = srt[5]
    PXZ = srt[6]
    VOL = srt[7]
    RHO = srt[8]
    NOX = srt[9]
    NOZ = srt[10]
    KND = srtk[0]
    DCL = srtk[1]
    GRD = srtk[2]
    par = _accel_par(h, c0, av_alpha, av_beta, av_boundary, gx, gz, hip_x, hip_z, hip_vx, hip_vz,
                     omega, half_t, gap, max_push, xmin, zmin, inv_cell, ncx, ncz, dt, damping,
                     vmax_allowed)
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
        acc = (buf[k, 0], buf[k, 1], fleg[i, 0], fleg[i, 1], fleg[i, 2], cont[k, 0],
               cont[k, 1], cont[k, 2])
        buf[k, 0] = 0.0
        buf[k, 1] = 0.0
        nbad += _kick_one(i, X[k], Z[k], VX[k], VZ[k], acc, mass, x, z, vx, vz, rho, sxx, szz,
                          fleg, bad, par)
    return nbad


@numba.njit(parallel=True, fastmath=True, cache=True)
def update_stress(rho, sxx, szz, sxz, syy, sidx, drho, lxx, lxz, lzx, lzz, dt, shear_mod,
                  bulk_mod, alpha_phi, k_c, rho_min, rho_max):
    """:func:`dp_update` for the granular particles ``sidx`` (the solver fuses it into
    :func:`strain_stress`; this form serves tests)."""
    for kk in prange(sidx.shape[0]):
        i = sidx[kk]
        rho[i], sxx[i], szz[i], sxz[i], syy[i] = dp_update(
            rho[i], drho[i], lxx[i], lxz[i], lzx[i], lzz[i], sxx[i], szz[i], sxz[i], syy[i], dt,
            shear_mod, bulk_mod, alpha_phi, k_c, rho_min, rho_max)


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


def warmup():
    """Compile every kernel on a tiny problem (for benchmarks: keeps JIT out of timings)."""
    from .solver import warmup as _w

    _w()


# ------------------------------------------------------------------- CPU: a block of steps
#: Scalars of :func:`cpu_steps` (float array ``fp``), by index.
FP = ("h", "xmin", "zmin", "inv_cell", "gx", "gz", "dt", "shear_mod", "bulk_mod", "alpha_phi",
      "k_c", "rho_min", "rho_max", "c0", "av_alpha", "av_beta", "half_t", "gap", "max_push",
      "vmax_allowed", "side_reach2")
#: Integers of :func:`cpu_steps` (int64 array ``ip``): grid size, flags, and two counters it
#: updates: the pair chunks and the list builds so far.
IP = ("ncx", "ncz", "noslip", "av_boundary", "has_leg", "nchunk", "builds", "sides")


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
    (h, xmin, zmin, inv_cell, gx, gz, dt, shear_mod, bulk_mod, alpha_phi, k_c, rho_min,
     rho_max, c0, av_alpha, av_beta, half_t, gap, max_push, vmax_allowed, side_reach2) = (
        fp[0], fp[1], fp[2], fp[3], fp[4], fp[5], fp[6], fp[7], fp[8], fp[9], fp[10], fp[11],
        fp[12], fp[13], fp[14], fp[15], fp[16], fp[17], fp[18], fp[19], fp[20])
    sides = ip[7] != 0
    ncx = ip[0]
    ncz = ip[1]
    noslip = ip[2] != 0
    av_boundary = ip[3] != 0
    has_leg = ip[4] != 0
    rlist = (2.0 + SKIN) * h
    thr = (0.5 * SKIN * h) ** 2
    for s in range(poses.shape[0]):
        hip_x, hip_z, hip_vx, hip_vz, hip_ax, hip_az, ang, omega, alpha = (
            poses[s, 0], poses[s, 1], poses[s, 2], poses[s, 3], poses[s, 4], poses[s, 5],
            poses[s, 6], poses[s, 7], poses[s, 8])
        if has_leg:
            place_rigid(x, z, vx, vz, acc_x, acc_z, nox, noz, lidx, body[0], body[1], body[2],
                        body[3], hip_x, hip_z, hip_vx, hip_vz, hip_ax, hip_az, ang, omega, alpha)
            if sides:
                leg_sides(x, z, kind, dcl, cl, hip_x, hip_z, ang, clbox, side_reach2)
        build = max_displacement2(x, z, xb, zb) > thr
        if build:
            bin_particles(x, z, xmin, zmin, inv_cell, ncx, ncz, cell_start, cell_index)
            ip[5] = chunk_bounds(cell_start, cell_index, kind, ncx, ncz, bounds)
            xb[:] = x
            zb[:] = z
            ip[6] += 1
        nchunk = ip[5]
        if bidx.shape[0]:
            boundary_state(x, z, vx, vz, rho, mass, kind, nox, noz, dcl, sxx, szz, sxz, syy,
                           gvx, gvz, bidx, acc_x, acc_z, gx, gz, h, xmin, zmin, inv_cell, ncx,
                           ncz, cell_start, cell_index, noslip, bj, bn, build)
        gather(cell_index, x, z, vx, vz, gvx, gvz, rho, mass, kind, nox, noz, dcl, guard, sxx,
               szz, sxz, srt, srtk)
        strain_stress(srt, srtk, cell_index, h, xmin, zmin, inv_cell, ncx, ncz, cell_start,
                      rho, sxx, szz, sxz, syy, dt, shear_mod, bulk_mod, alpha_phi, k_c, rho_min,
                      rho_max, vj, vn, nbj, nbw, nbn, rlist, build, buf, bounds, nchunk)
        if bidx.shape[0]:
            boundary_state(x, z, vx, vz, rho, mass, kind, nox, noz, dcl, sxx, szz, sxz, syy,
                           gvx, gvz, bidx, acc_x, acc_z, gx, gz, h, xmin, zmin, inv_cell, ncx,
                           ncz, cell_start, cell_index, noslip, bj, bn, False)
        regather(cell_index, vx, vz, gvx, gvz, rho, mass, kind, sxx, szz, sxz, srt)
        nbad = accelerations_kick(
            srt, srtk, cell_index, mass, h, c0, av_alpha, av_beta, av_boundary, gx, gz, hip_x,
            hip_z, hip_vx, hip_vz, omega, half_t, gap, max_push, xmin, zmin, inv_cell, ncx, ncz,
            cell_start, x, z, vx, vz, rho, sxx, szz, dt, dampings[s], vmax_allowed, fleg, bad,
            nbj, nbw, nbn, buf, cont, bounds, nchunk)
        if nbad:
            return s, nbad
        if has_leg:
            forces[s, 0], forces[s, 1], forces[s, 2] = column_sums3(fleg)
    return poses.shape[0], 0
