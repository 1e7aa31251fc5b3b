"""The SPH physics, written once for both backends: the per-particle and per-pair functions.

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
  non-dilatant (psi = 0, the choice Bui et al. found to match their experiment) unless the
  material has a dilatancy angle: then non-associated, while the packing is denser than its
  critical state (:func:`dp_update`).
* Boundaries: dummy particles (walls, rigid leg) whose stress and velocity are extrapolated
  from the granular particles around them (Adami, Hu & Adams 2012, J. Comput. Phys. 231:7057,
  generalised from pressure to the stress tensor), with the gravity / wall-acceleration term.
  Leg particles belong to one side of the (thin) leg and only see material on that side.

Particle kinds: 0 granular, 1 fixed wall, 2 leg (moving rigid body), 3 lost (left the
container; parked far away and ignored).

One source for CPU and GPU: the physics of one particle or one pair is a plain Python
function of (index, arrays..., scalars) that allocates nothing (``_boundary_one``,
``_pair_fdw``, ``_strain_pair``, ``_stress_term``, ``_accel_pair``, ``dp_update``,
``_kick_one``, ...; registered in :data:`terradyn.sph.source.SOURCES`). Each is compiled as an
inlined ``numba.njit`` function called from the ``prange`` loops of :mod:`terradyn.sph.cpu`;
:mod:`terradyn.sph.gpu` compiles the very same functions as CUDA device functions called from
one-thread-per-particle kernels. The loops around them differ where the hardware does: a GPU
thread visits every neighbour of its particle (no write conflicts; :func:`_strain_stress_one`,
:func:`_accel_kick_one` here); the CPU visits each granular pair once and adds its terms to
both particles (half the pair work; the half-list functions of :mod:`terradyn.sph.cpu`).
Scalars travel in named tuples (:class:`Grid`, :class:`Gravity`, :class:`StrainPar`,
:class:`AccelPar`, :class:`PairPar`), read by field name.
"""
from __future__ import annotations

import math
from collections import namedtuple

from .neighbours import REACH, SKIN, _build_list, _cell_xz, _row_span
from .source import source as _source
from .state import LEG, SOIL

_W2D = 7.0 / (4.0 * math.pi)
#: Columns of the (N, 3) per-particle force on the leg ``fleg``: Fx, Fz, torque about the hip.
FLEG_X, FLEG_Z, FLEG_TQ = 0, 1, 2

#: The scalars of the physics functions, by name (Numba compiles named tuples to the same
#: structs as plain tuples; CPython turns calls with more than 30 arguments into *args calls,
#: which Numba cannot inline, hence the bundles).
#: The cell grid: smoothing length, origin, 1 / cell side, cells per row and column.
Grid = namedtuple("Grid", "h xmin zmin inv_cell ncx ncz")
#: Gravity (m/s^2).
Gravity = namedtuple("Gravity", "gx gz")
#: Pass 1 (:func:`_strain_stress_one`, the CPU's half-list pass): grid, time step, the
#: material's elastic and Drucker-Prager constants, density bounds, Verlet-list radius, and
#: whether the lists are rebuilt this step.
StrainPar = namedtuple("StrainPar", "h xmin zmin inv_cell ncx ncz dt shear_mod bulk_mod "
                                    "alpha_phi k_c rho_min rho_max alpha_psi rho_crit rlist build "
                                    "mu_s mu_rise mu_i0 mu_dscale")
#: Pass 2 (:func:`_accel_kick_one`, :func:`_kick_one`), made by :func:`_accel_par`: grid,
#: sound speed, artificial viscosity, gravity, the hip's position and velocity and the leg's
#: clockwise angular speed, the contact guard (leg half thickness, gap, largest push per
#: step), time step, damping factor 1 / (1 + damping dt), the speed limit of stability, and
#: the side-wall friction factor wall_k = 2 mu_w / W (1/m; 0: plane strain without walls), and
#: the grain-leg friction coefficient leg_mu (< 0: a rough, no-slip leg).
AccelPar = namedtuple("AccelPar", "h xmin zmin inv_cell ncx ncz c0 av_alpha av_beta av_boundary "
                                  "gx gz hip_x hip_z hip_vx hip_vz omega half_t gap max_push dt "
                                  "fdamp vmax_allowed wall_k leg_mu")
#: One granular particle's scalars that its pair terms read (:func:`_accel_pp`): h, h^2, the
#: viscosity and guard constants of :class:`AccelPar`, its position, velocity, density,
#: sigma / rho^2 and mass.
PairPar = namedtuple("PairPar", "h h2 c0 av_alpha av_beta av_boundary half_t hip_x hip_z xi zi "
                                "vxi vzi rhoi pxx pzz pxz mi")


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
def _mu_i_implicit(sj, p, k_c, gdt, mu_s, mu_rise, mu_i0, mu_dscale):
    """mu of the mu(I) cone after a return from the trial deviator sqrt(J2) = ``sj`` at mean
    pressure ``p`` > 0 (``gdt`` = G dt): the plastic shear rate g >= 0 solves
    h(g) = sj - G dt g - R(g) = 0, R(g) = p mu / sqrt(1 + mu^2) + k_c the cone's radius at
    mu = mu(I(g)), I(g) = g mu_dscale / sqrt(p) (the return scales sqrt(J2) down by G dt times
    the equivalent plastic shear rate sqrt(2 e_p:e_p)). g = 0 (mu_s) where the trial stress is
    inside the static cone. R is concave and increasing in g, so h is convex and decreasing
    and Newton's method from g = 0 climbs to the root monotonically, without overshoot."""
    r_s = p * mu_s / math.sqrt(1.0 + mu_s * mu_s) + k_c
    if sj <= r_s:
        return mu_s
    c = mu_dscale / math.sqrt(p)  # I = c g
    g = 0.0
    mu = mu_s
    for _ in range(50):
        inum = c * g
        q = 1.0 / (inum + mu_i0)
        mu = mu_s + mu_rise * inum * q
        w = 1.0 / math.sqrt(1.0 + mu * mu)
        h = sj - gdt * g - (p * mu * w + k_c)
        dh = -gdt - p * w * w * w * mu_rise * mu_i0 * q * q * c
        step = -h / dh
        g += step
        if step <= 1e-12 * g:
            break
    inum = c * g
    return mu_s + mu_rise * inum / (inum + mu_i0)


@_source
def dp_update(rho, drho, lxx, lxz, lzx, lzz, sxx, szz, sxz, syy, dt, shear_mod, bulk_mod,
              alpha_phi, k_c, rho_min, rho_max, alpha_psi, rho_crit, mu_s, mu_rise, mu_i0,
              mu_dscale):
    """One particle's density and Drucker-Prager stress over one step: Jaumann rate + Hooke's
    law (plane strain), then the Bui et al. (2008) return: tension cut-off and stress scaling
    onto the yield surface. The density is kept in [rho_min, rho_max]: a dry packing neither
    compacts nor dilutes much, and grains splashed off the free surface must not get tiny
    densities (their sigma/rho^2 would explode). Returns (rho, sxx, szz, sxz, syy).

    Flow rule: non-dilatant (psi = 0: the deviator is scaled at constant mean stress) unless
    ``alpha_psi`` > 0 and the particle is denser than ``rho_crit``; then non-associated
    (plastic potential g = sqrt(J2) + alpha_psi I1): the closed-form return of a linear
    Drucker-Prager cone, d lambda = f / (G + 9 K alpha_phi alpha_psi), s -> s (1 - G d lambda
    / sqrt(J2)), I1 -> I1 - 9 K alpha_psi d lambda (de Souza Neto, Peric & Owen 2008, sec.
    8.3.3), to the apex where the cone return overshoots it. Plastic dilation raises the
    mean compression of a confined particle; below rho_crit (the critical-state, loosest
    packing) it stops.

    Rate dependence (``mu_rise`` > 0; :class:`terradyn.sph.materials.GranularMaterial`): the
    cone's friction is that of mu(I) = mu_s + mu_rise I / (I + I_0) (Jop et al. 2006), with
    I = gamma_p d sqrt(rho_s) / sqrt(P) (``mu_dscale`` = d sqrt(rho_s); P the trial mean
    pressure; I = inf where P <= 0) and the plane-strain match alpha_phi = sin(atan mu) / 3 =
    mu / (3 sqrt(1 + mu^2)). gamma_p is the step's *plastic* shear rate, found implicitly
    (:func:`_mu_i_implicit`, the elasto-viscoplastic return): an elastic particle keeps the
    static cone, and particle-scale noise in the total strain rate does not move the cone of
    a yielding one; in steady shear gamma_p is the applied rate. The tension cut-off keeps the
    static cone. mu_rise = 0: the rate-independent model, unchanged."""
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
    if mu_rise > 0.0:  # mu(I): the cone's friction from the plastic shear rate
        if m < 0.0:
            mu = _mu_i_implicit(math.sqrt(j2), -m, k_c, dt * shear_mod, mu_s, mu_rise, mu_i0,
                                mu_dscale)
        else:
            mu = mu_s + mu_rise
        alpha_phi = mu / (3.0 * math.sqrt(1.0 + mu * mu))
    lim = -alpha_phi * i1 + k_c
    if alpha_psi > 0.0 and rho > rho_crit and j2 > lim * lim and j2 > 0.0:
        sj = math.sqrt(j2)
        dlam = (sj - lim) / (shear_mod + 9.0 * bulk_mod * alpha_phi * alpha_psi)
        if sj > shear_mod * dlam:
            rr = 1.0 - shear_mod * dlam / sj
            m = (i1 - 9.0 * bulk_mod * alpha_psi * dlam) / 3.0
        else:  # the apex of the cone
            rr = 0.0
            m = k_c / (3.0 * alpha_phi) if alpha_phi > 0.0 else m
        return rho, dxx * rr + m, dzz * rr + m, s_xz * rr, dyy * rr + m
    if j2 > lim * lim and j2 > 0.0:
        rr = lim / math.sqrt(j2)
        dxx *= rr
        dzz *= rr
        dyy *= rr
        s_xz *= rr
    return rho, dxx + m, dzz + m, s_xz, dyy + m


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
    Reads granular particles only and writes the boundary particle only. grav: a
    :class:`Gravity`; grid: a :class:`Grid`. Candidates come from its Verlet list (bj[kk,
    :bn[kk]]: the granular particles within 2h + skin at the last build, -1: more than fit, or
    no list: search the cells), made here from the cells if ``build``."""
    gx, gz = grav.gx, grav.gz
    h, xmin, zmin, inv_cell = grid.h, grid.xmin, grid.zmin, grid.inv_cell
    ncx, ncz = grid.ncx, grid.ncz
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
    are separate arguments, not a tuple: see :func:`_accel_kick_one`. X ... DCL: rows of the
    gathered copy; par: a :class:`StrainPar`."""
    if KND[k] != SOIL:
        return
    h, xmin, zmin, inv_cell = par.h, par.xmin, par.zmin, par.inv_cell
    ncx, ncz, dt, rlist, build = par.ncx, par.ncz, par.dt, par.rlist, par.build
    shear_mod, bulk_mod, alpha_phi, k_c = par.shear_mod, par.bulk_mod, par.alpha_phi, par.k_c
    rho_min, rho_max = par.rho_min, par.rho_max
    alpha_psi, rho_crit = par.alpha_psi, par.rho_crit
    mu_s, mu_rise, mu_i0, mu_dscale = par.mu_s, par.mu_rise, par.mu_i0, par.mu_dscale
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
        bulk_mod, alpha_phi, k_c, rho_min, rho_max, alpha_psi, rho_crit, mu_s, mu_rise, mu_i0,
        mu_dscale)


@_source
def _stress_term(j, fdw, rx, rz, VX, VZ, PXX, PZZ, PXZ, RHO, KND, pp):
    """The momentum equation's pair term per unit mass of ``j``: (sigma_i / rho_i^2 +
    sigma_j / rho_j^2 - Pi_ij I) . grad_i W_ij (i: the particle of ``pp``, r_ij = (rx, rz),
    grad_i W_ij = fdw r_ij; pp: a :class:`PairPar`); particle j feels minus it per unit mass
    of i. Returns (tx, tz)."""
    h, h2, c0, av_alpha, av_beta = pp.h, pp.h2, pp.c0, pp.av_alpha, pp.av_beta
    av_boundary = pp.av_boundary
    vxi, vzi, rhoi, pxx, pzz, pxz = pp.vxi, pp.vzi, pp.rhoi, pp.pxx, pp.pzz, pp.pxz
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
    (grad W = fdw r_ij). pp: that particle's scalars (:class:`PairPar`), acc: its running
    sums (a_x, a_z, fx, fz, torque, dmin, pnx, pnz, lnx, lnz: (lnx, lnz) the leg's boundary
    normal at the grain, -sum_j V_j grad_i W_ij over the leg particles it sees, for the
    grain-leg friction of :func:`_kick_one`); returns the updated sums."""
    half_t = pp.half_t
    hip_x = pp.hip_x
    hip_z = pp.hip_z
    mi = pp.mi
    a_x, a_z, fx, fz, tq, dmin, pnx, pnz, lnx, lnz = acc
    rx = pp.xi - X[j]
    rz = pp.zi - Z[j]
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
        # the leg's boundary normal at the grain: -sum_j V_j grad_i W_ij over its leg
        # particles (points from them to the grain; along the face normal beside a face,
        # along the chord ahead of an end, which carries no end markers)
        wv = -VOL[j] * fdw
        lnx += wv * rx
        lnz += wv * rz
    return (a_x, a_z, fx, fz, tq, dmin, pnx, pnz, lnx, lnz)


@_source
def _accel_pp(k, X, Z, VX, VZ, PXX, PZZ, PXZ, RHO, mi, par):
    """The scalars of column ``k`` that its pair terms read (the :class:`PairPar` ``pp`` of
    :func:`_accel_pair`); par: the :class:`AccelPar` of the step."""
    h = par.h
    return PairPar(h=h, h2=h * h, c0=par.c0, av_alpha=par.av_alpha, av_beta=par.av_beta,
                   av_boundary=par.av_boundary, half_t=par.half_t, hip_x=par.hip_x,
                   hip_z=par.hip_z, xi=X[k], zi=Z[k], vxi=VX[k], vzi=VZ[k], rhoi=RHO[k],
                   pxx=PXX[k], pzz=PZZ[k], pxz=PXZ[k], mi=mi)


@_source
def _leg_slip(rx, rz, mi, a_x, a_z, fx, fz, tq, lnx, lnz, mu):
    """Coulomb's cap on the leg's force on one grain (see :func:`_kick_one`): the grain at
    (rx, rz) from the hip, of mass ``mi``, with acceleration (a_x, a_z) and force on the leg
    (fx, fz, torque tq) from its pair terms, (lnx, lnz) the leg's boundary normal there (any
    length), mu the friction coefficient. Returns (a_x, a_z, fx, fz, tq) with the
    leg's tangential force on the grain at most mu times its normal push; the part taken off
    acts at the grain's position."""
    inv = 1.0 / math.sqrt(lnx * lnx + lnz * lnz)
    nx = lnx * inv
    nz = lnz * inv
    # the leg's force on the grain is minus the grain's on the leg
    fn = -(fx * nx + fz * nz)
    ftx = -fx - fn * nx
    ftz = -fz - fn * nz
    ft = math.sqrt(ftx * ftx + ftz * ftz)
    cap = mu * fn if fn > 0.0 else 0.0
    if ft <= cap:
        return a_x, a_z, fx, fz, tq
    k = cap / ft - 1.0  # the change of the tangential force, as a multiple of it
    dfx = k * ftx
    dfz = k * ftz
    return (a_x + dfx / mi, a_z + dfz / mi, fx - dfx, fz - dfz,
            tq - (rx * dfz - rz * dfx))


@_source
def _kick_one(i, xi, zi, vxi, vzi, acc, mass, x, z, vx, vz, rho, sxx, szz, syy, fleg, bad,
              par):
    """Kick, contact and drift of granular particle ``i`` (at xi, zi with velocity vxi, vzi
    at the start of the step) from its summed pair terms acc = (a_x, a_z, fx, fz, torque,
    dmin, pnx, pnz, lnx, lnz) (see :func:`_accel_pair`); writes its velocity, position and
    force on the leg; par: the :class:`AccelPar` of the step. Returns 1 if it went
    non-finite or too fast, else 0.

    Grain-leg friction (par.leg_mu >= 0; a rough, no-slip leg otherwise): Coulomb's law on
    the force the leg's particles exert on this grain. Split along the leg's boundary normal
    n at the grain (-sum_j V_j grad W_ij over the leg particles it sees, the usual SPH
    boundary normal: the face normal beside a face, the chord's direction ahead of an end),
    its tangential part is capped at
    leg_mu times its normal push (none where the leg pulls); below the cap the no-slip force
    stands (stick), above it the grain slides with the capped force. The part taken off
    leaves the grain's acceleration and the leg's force together, so momentum stays balanced.

    Side walls (par.wall_k > 0, a quasi-2D channel of width W): Coulomb friction of the two
    walls, each pressed by the out-of-plane stress -sigma_yy, averaged over the width: a
    deceleration of at most wall_k (-sigma_yy) / rho = 2 mu_w (-sigma_yy) / (rho W) against
    the velocity, applied to the kicked velocity and never past rest (so it holds a particle
    that the other forces would set moving no faster, as static friction does)."""
    gx, gz, dt, fdamp, vmax_allowed = par.gx, par.gz, par.dt, par.fdamp, par.vmax_allowed
    hip_x, hip_z, hip_vx, hip_vz, omega = par.hip_x, par.hip_z, par.hip_vx, par.hip_vz, par.omega
    gap, max_push = par.gap, par.max_push
    a_x, a_z, fx, fz, tq, dmin, pnx, pnz, lnx, lnz = acc
    if par.leg_mu >= 0.0 and (lnx != 0.0 or lnz != 0.0):
        a_x, a_z, fx, fz, tq = _leg_slip(xi - hip_x, zi - hip_z, mass[i], a_x, a_z, fx, fz, tq,
                                         lnx, lnz, par.leg_mu)
    nvx = (vxi + dt * (a_x + gx)) * fdamp
    nvz = (vzi + dt * (a_z + gz)) * fdamp
    if par.wall_k > 0.0 and syy[i] < 0.0:
        sp = math.sqrt(nvx * nvx + nvz * nvz)
        dv = dt * par.wall_k * (-syy[i]) / rho[i]
        keep = 1.0 - dv / sp if sp > dv else 0.0
        nvx *= keep
        nvz *= keep
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
    fleg[i, FLEG_X] = fx
    fleg[i, FLEG_Z] = fz
    fleg[i, FLEG_TQ] = tq
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
                    cell_index, cell_start, mass, x, z, vx, vz, rho, sxx, szz, syy, fleg, bad,
                    nb, par):
    """Column ``k`` (cell order) of the GPU's pass 2: acceleration, force on the leg, contact
    guard, kick and drift of its particle if granular, every neighbour visited from this
    side (the CPU's pass 2, :func:`accelerations_kick`, visits each granular pair once).
    Returns 1 if the particle went non-finite or too fast, else 0 (also 0 for non-granular
    columns). X ... GRD: rows of the gathered copy; nb = (nbj, nbw, nbn): the neighbour list
    of pass 1, read only (positions have not moved since; a negative count: the list
    overflowed, search the cells again); par: the :class:`AccelPar` (:func:`_accel_par`)."""
    if KND[k] != SOIL:
        return 0
    h = par.h
    sup2, dwc, inv_h = _support(h)
    i = cell_index[k]
    pp = _accel_pp(k, X, Z, VX, VZ, PXX, PZZ, PXZ, RHO, mass[i], par)
    xi = X[k]
    zi = Z[k]
    acc = (0.0, 0.0, 0.0, 0.0, 0.0, par.gap, 0.0, 0.0, 0.0, 0.0)  # see _accel_pair
    nbj, nbw, nbn = nb
    cnt = nbn[k]
    if cnt >= 0:
        for n in range(cnt):
            acc = _accel_pair(nbj[k, n], nbw[k, n], X, Z, VX, VZ, PXX, PZZ, PXZ, VOL, RHO, NOX,
                              NOZ, KND, DCL, GRD, pp, acc)
    else:
        cx, cz = _cell_xz(xi, zi, par.xmin, par.zmin, par.inv_cell, par.ncx, par.ncz)
        for dz in range(-REACH, REACH + 1):
            lo, hi = _row_span(cx, cz, dz, par.ncx, par.ncz, cell_start)
            for j in range(lo, hi):
                fdw = _pair_fdw(j, xi - X[j], zi - Z[j], KND, NOX, NOZ, DCL, sup2, inv_h, dwc, DCL[k])
                if fdw != 0.0:
                    acc = _accel_pair(j, fdw, X, Z, VX, VZ, PXX, PZZ, PXZ, VOL, RHO, NOX, NOZ,
                                      KND, DCL, GRD, pp, acc)
    return _kick_one(i, xi, zi, VX[k], VZ[k], acc, mass, x, z, vx, vz, rho, sxx, szz, syy,
                     fleg, bad, par)


@_source
def _accel_par(h, c0, av_alpha, av_beta, av_boundary, gx, gz, hip_x, hip_z, hip_vx, hip_vz,
               omega, half_t, gap, max_push, xmin, zmin, inv_cell, ncx, ncz, dt, damping,
               vmax_allowed, wall_k, leg_mu):
    """The scalars of :func:`_accel_kick_one` as one :class:`AccelPar` (the damping rate
    becomes the factor fdamp = 1 / (1 + damping dt))."""
    fdamp = 1.0 / (1.0 + damping * dt)
    return AccelPar(h=h, xmin=xmin, zmin=zmin, inv_cell=inv_cell, ncx=ncx, ncz=ncz, c0=c0,
                    av_alpha=av_alpha, av_beta=av_beta, av_boundary=av_boundary, gx=gx, gz=gz,
                    hip_x=hip_x, hip_z=hip_z, hip_vx=hip_vx, hip_vz=hip_vz, omega=omega,
                    half_t=half_t, gap=gap, max_push=max_push, dt=dt, fdamp=fdamp,
                    vmax_allowed=vmax_allowed, wall_k=wall_k, leg_mu=leg_mu)


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
    x0, x1, z0, z1 = box[0], box[1], box[2], box[3]
    if x0 <= bx <= x1 and z0 <= bz <= z1:
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
