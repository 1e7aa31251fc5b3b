"""The RFT force engine: any leg, any planar rigid motion, any stress model.

For every element i and time step j the engine places the element in the world
(``r = R(theta) s``, ``v = v_hip + omega x r``), takes its depth below the free surface
(z = 0), its attack angle beta (tangent angle from horizontal) and intrusion angle gamma
(direction of v below horizontal), looks up the stress per depth alpha(beta, gamma) and adds

    f_z = alpha_z * depth * area,   f_x = -alpha_x * depth * area

(alpha_x > 0 opposes the horizontal motion; the symmetry relations of Li 2013 make this one
formula valid for motion in either direction). Elements above the surface, or at rest, feel
nothing. Net force is the sum over elements, torque the sum of r x f about the hip
(anticlockwise positive).

Two paths compute the same thing:

* :func:`element_states` / :func:`element_forces` - NumPy, any stress model (tables,
  user models), all per-element quantities available (frames, diagnostics);
* a compiled kernel for the Fourier fit (:func:`net_forces` picks it): no trigonometric call
  per element - cos 2beta, sin 2beta come from the body-frame tangent rotated by 2 theta and
  cos gamma, sin gamma from the normalised velocity - parallel over designs x steps.
"""
from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from ..geometry import Elements, Leg
from ..media import FourierFit, StressModel
from ..motion import Trajectory

#: Speeds below this (m/s) count as "at rest": RFT gives no force.
REST_SPEED = 1e-12


@dataclass(frozen=True, eq=False)
class ElementStates:
    """Per-element kinematics, arrays (S, n): world position x, z (m); depth below the surface
    (m, clipped at 0); beta, gamma (rad); velocity vx, vz (m/s)."""

    x: np.ndarray
    z: np.ndarray
    depth: np.ndarray
    beta: np.ndarray
    gamma: np.ndarray
    vx: np.ndarray
    vz: np.ndarray


def element_states(el: Elements, traj: Trajectory, surface: float = 0.0) -> ElementStates:
    """Kinematics of every element at every step (NumPy, (S, n) arrays)."""
    c = np.cos(traj.angle)[:, None]
    s = np.sin(traj.angle)[:, None]
    sx, sz = el.centers[:, 0], el.centers[:, 1]
    rx = c * sx + s * sz  # clockwise rotation by the leg angle
    rz = -s * sx + c * sz
    tx = c * el.tangents[:, 0] + s * el.tangents[:, 1]
    tz = -s * el.tangents[:, 0] + c * el.tangents[:, 1]
    w = traj.angular_velocity[:, None]
    vx = traj.hip_vx[:, None] + w * rz
    vz = traj.hip_vz[:, None] - w * rx
    x = traj.hip_x[:, None] + rx
    z = traj.hip_z[:, None] + rz
    beta = np.arctan2(tz, tx)
    beta = np.mod(beta + np.pi / 2, np.pi) - np.pi / 2  # a plate is the same after a half turn
    gamma = np.arctan2(-vz, vx)
    depth = np.maximum(surface - z, 0.0)
    return ElementStates(x, z, depth, beta, gamma, vx, vz)


def element_forces(el: Elements, traj: Trajectory, model: StressModel, surface: float = 0.0,
                   states: ElementStates | None = None, dynamic: tuple[float, float] | None = None,
                   surface_correction=None):
    """Force on each element, (fx, fz) arrays (S, n) in N, and the states used. ``el``: the
    elements or a leg (``leg.elements()``); ``traj``: a trajectory or a motion
    (``motion.trajectory()``).

    ``dynamic=(lambda, rho)`` adds the dynamic-RFT inertial term of Agarwal et al. (2021),
    -n lambda rho v_n^2 dA on each touching element (n its normal on the side it moves
    towards, v_n the normal speed; rho the bulk density, kg/m^3). ``surface_correction``:
    hook ``f(states) -> delta_h`` (S, n) m; the depth used is that of z~ = z + delta_h."""
    if hasattr(el, "elements") and callable(el.elements):  # a leg: its elements
        el = el.elements()
    if hasattr(traj, "trajectory") and callable(traj.trajectory):  # a motion: its trajectory
        traj = traj.trajectory()
    st = states if states is not None else element_states(el, traj, surface)
    if surface_correction is not None:
        dh = np.asarray(surface_correction(st), dtype=float)
        if dh.shape != st.depth.shape or not np.isfinite(dh).all():
            from ..errors import InputError

            raise InputError("surface_correction", f"must return finite delta_h of shape {st.depth.shape} in m")
        st = ElementStates(st.x, st.z, np.maximum(surface - st.z - dh, 0.0), st.beta, st.gamma,
                           st.vx, st.vz)
    touching = (st.depth > 0) & (np.hypot(st.vx, st.vz) > REST_SPEED)
    fx = np.zeros_like(st.depth)
    fz = np.zeros_like(st.depth)
    if touching.any():
        ax, az = model.alpha(st.beta[touching], st.gamma[touching])
        load = st.depth[touching] * np.broadcast_to(el.areas, st.depth.shape)[touching]
        fx[touching] = -np.asarray(ax) * load
        fz[touching] = np.asarray(az) * load
    if dynamic is not None and dynamic[0]:
        lam, rho = dynamic
        nx, nz = -np.sin(st.beta), np.cos(st.beta)  # a plate normal (either side)
        vn = st.vx * nx + st.vz * nz
        k = -lam * rho * vn * np.abs(vn) * np.broadcast_to(el.areas, st.depth.shape) * touching
        fx += k * nx
        fz += k * nz
    return fx, fz, st


def _net_numpy(el: Elements, traj: Trajectory, model: StressModel, surface: float,
               dynamic: tuple[float, float] | None = None, surface_correction=None):
    fx, fz, st = element_forces(el, traj, model, surface, dynamic=dynamic,
                                surface_correction=surface_correction)
    rx = st.x - traj.hip_x[:, None]
    rz = st.z - traj.hip_z[:, None]
    return fx.sum(1), fz.sum(1), (rx * fz - rz * fx).sum(1)


# ------------------------------------------------------------------------------------------
# Compiled Fourier-fit kernel
# ------------------------------------------------------------------------------------------
@numba.njit(inline="always", fastmath=True)
def _alpha(coef, c2, s2, cg, sg):  # pragma: no cover - compiled
    """Fourier fit from cos/sin of 2 beta and gamma: (alpha_x, alpha_z), no trig calls."""
    az = (coef[0] + coef[1] * c2 + coef[2] * (s2 * cg + c2 * sg) + coef[3] * sg
          + coef[4] * (c2 * sg - s2 * cg))
    ax = coef[5] * (c2 * cg - s2 * sg) + coef[6] * cg + coef[7] * (c2 * cg + s2 * sg) + coef[8] * s2
    return ax, az


@numba.njit(parallel=True, fastmath=True, cache=True, error_model="numpy", nogil=True)
def _fourier_kernel(sx, sz, c2b, s2b, area, hx, hz, vhx, vhz, ang_c, ang_s, c2t, s2t, w,
                    coef, surface, out):  # pragma: no cover - compiled
    """Fourier fit for any planar motion (the hip may move).

    sx, sz, c2b, s2b, area: (D, n) body-frame element data (zero area pads); trajectory
    arrays (S,); coef (9,) N/m^3; out (D, S, 3): Fx, Fz, torque. Generic in the float type:
    every constant takes the type of ``sx``. One square root per element for 1/|v|.
    """
    D, n = sx.shape
    S = hx.shape[0]
    zero = sx.dtype.type(0.0)
    one = sx.dtype.type(1.0)
    rest = sx.dtype.type(1e-24)
    for k in numba.prange(D * S):
        d = k // S
        j = k - d * S
        c, s, cc, ss, wj = ang_c[j], ang_s[j], c2t[j], s2t[j], w[j]
        ux, uz = vhx[j], vhz[j]
        depth0 = surface - hz[j]
        sxd, szd, c2d, s2d, ad = sx[d], sz[d], c2b[d], s2b[d], area[d]
        fx_sum = zero
        fz_sum = zero
        tq_sum = zero
        for i in range(n):
            rx = c * sxd[i] + s * szd[i]
            rz = -s * sxd[i] + c * szd[i]
            vx = ux + wj * rz
            vz = uz - wj * rx
            v2 = vx * vx + vz * vz
            inv = one / np.sqrt(v2 + rest * rest)
            c2 = c2d[i] * cc + s2d[i] * ss  # 2 beta = 2 beta_body - 2 theta
            s2 = s2d[i] * cc - c2d[i] * ss
            ax, az = _alpha(coef, c2, s2, vx * inv, -vz * inv)
            load = max(depth0 - rz, zero) * (ad[i] if v2 > rest else zero)
            fx_sum -= ax * load
            fz_sum += az * load
            tq_sum += (rx * az + rz * ax) * load
        out[d, j, 0] = fx_sum
        out[d, j, 1] = fz_sum
        out[d, j, 2] = tq_sum


@numba.njit(parallel=True, fastmath=True, cache=True, error_model="numpy", nogil=True)
def _fourier_rotation_kernel(G, T, a00, surface, out):  # pragma: no cover - compiled
    """Fourier fit for a rotation about a hip at rest (any angle history, any omega(t)).

    For a hip at rest an element's direction of motion turns with the body, so gamma = phi +
    theta, 2 beta = 2 beta_body - 2 theta, and each of the fit's terms is a harmonic of theta
    of order 1, 2 or 3 with per-element amplitudes H (12, D, n) precomputed from the body
    geometry and the coefficients (see :meth:`PackedElements.harmonics`). Per element and
    step this leaves ~30 flops: no square root, division or trigonometric call.

    G (16, D, n): rows 0-11 the amplitudes H, 12-14 sx, sz, area, row 15 a bounding circle
    (centre x, z, radius in its first three columns; a step whose circle lies wholly above the
    surface is skipped). T (8, S): hip z, cos/sin of theta, 2 theta, 3 theta, omega. Few
    arguments keep the call overhead low for single curves.
    """
    D, n = G.shape[1], G.shape[2]
    S = T.shape[1]
    sx, sz, area = G[12], G[13], G[14]
    hz, c1, s1, c2, s2, c3, s3, w = T[0], T[1], T[2], T[3], T[4], T[5], T[6], T[7]
    H = G
    zero = sx.dtype.type(0.0)
    one = sx.dtype.type(1.0)
    for k in numba.prange(D * S):
        d = k // S
        j = k - d * S
        C1, S1, C2, S2, C3, S3, wj = c1[j], s1[j], c2[j], s2[j], c3[j], s3[j], w[j]
        sgn = zero if wj == zero else (one if wj > zero else -one)
        depth0 = surface - hz[j]
        if depth0 + S1 * G[15, d, 0] - C1 * G[15, d, 1] + G[15, d, 2] <= zero:
            out[d, j, 0] = zero
            out[d, j, 1] = zero
            out[d, j, 2] = zero
            continue
        sxd, szd, ad = sx[d], sz[d], area[d]
        z2c, z2s, z1c, z1s, z3c, z3s = H[0, d], H[1, d], H[2, d], H[3, d], H[4, d], H[5, d]
        x2c, x2s, x1c, x1s, x3c, x3s = H[6, d], H[7, d], H[8, d], H[9, d], H[10, d], H[11, d]
        fx_sum = zero
        fz_sum = zero
        tq_sum = zero
        for i in range(n):
            rx = C1 * sxd[i] + S1 * szd[i]
            rz = -S1 * sxd[i] + C1 * szd[i]
            az = a00 + z2c[i] * C2 + z2s[i] * S2 + sgn * (z1c[i] * C1 + z1s[i] * S1
                                                           + z3c[i] * C3 + z3s[i] * S3)
            ax = x2c[i] * C2 + x2s[i] * S2 + sgn * (x1c[i] * C1 + x1s[i] * S1
                                                     + x3c[i] * C3 + x3s[i] * S3)
            load = max(depth0 - rz, zero) * ad[i] * sgn * sgn
            fx_sum -= ax * load
            fz_sum += az * load
            tq_sum += (rx * az + rz * ax) * load
        out[d, j, 0] = fx_sum
        out[d, j, 1] = fz_sum
        out[d, j, 2] = tq_sum


# Serial twins of the parallel kernels (prange runs as range): a small call must not pay for
# a parallel region (on a busy 2-core machine the standard curve took 0.52 ms with two Numba
# threads against 0.038 ms single-threaded). :func:`_net_fourier` picks by the work size.
_fourier_kernel_serial = numba.njit(fastmath=True, cache=True, error_model="numpy", nogil=True)(
    _fourier_kernel.py_func)
_fourier_rotation_kernel_serial = numba.njit(fastmath=True, cache=True, error_model="numpy", nogil=True)(
    _fourier_rotation_kernel.py_func)

#: Element evaluations (designs x steps x elements) from which the Fourier kernels run in
#: parallel; below it they run serially (benchmarks/bench_rft3d.py measures the crossover).
PARALLEL_MIN_WORK = 200_000


@dataclass(frozen=True, eq=False)
class PackedElements:
    """Element sets of D designs padded to (D, n_max) arrays for the compiled kernel."""

    sx: np.ndarray
    sz: np.ndarray
    c2b: np.ndarray
    s2b: np.ndarray
    area: np.ndarray
    bound: np.ndarray  # (D, 3): centre x, z and radius of a circle holding the elements

    @classmethod
    def of(cls, elements: list[Elements], dtype=np.float64) -> "PackedElements":
        D = len(elements)
        n = max(len(e) for e in elements)
        a = {k: np.zeros((D, n)) for k in ("sx", "sz", "c2b", "s2b", "area")}
        for d, e in enumerate(elements):
            m = len(e)
            a["sx"][d, :m], a["sz"][d, :m] = e.centers[:, 0], e.centers[:, 1]
            tx, tz = e.tangents[:, 0], e.tangents[:, 1]
            a["c2b"][d, :m] = tx * tx - tz * tz
            a["s2b"][d, :m] = 2 * tx * tz
            a["area"][d, :m] = e.areas
        a["bound"] = np.zeros((D, 3))
        for d, e in enumerate(elements):
            c = e.centers.mean(0)
            a["bound"][d] = (*c, np.hypot(*(e.centers - c).T).max() * (1 + 1e-9) + 1e-12)
        return cls(**{k: np.ascontiguousarray(v, dtype=dtype) for k, v in a.items()})

    def harmonics(self, fit: FourierFit) -> np.ndarray:
        """Per-element amplitudes of the fit's harmonics in theta for a rotation about a hip
        at rest, stacked with the element data as the rotation kernel's ``G`` (16, D, n);
        cached per fit. Order: alpha_z cos2, sin2, cos1, sin1, cos3, sin3,
        then the same for alpha_x; the order-1 and -3 terms flip sign with omega."""
        cache = self.__dict__.setdefault("_harmonics", {})
        key = id(fit)  # hashing the dataclass costs microseconds; the entry keeps fit alive
        if key not in cache or cache[key][0] is not fit:
            A00, A10, B11, B01, Bm11, C11, C01, Cm11, D10 = fit.as_array()
            sx, sz = self.sx.astype(float), self.sz.astype(float)
            phi = np.arctan2(sx, sz)  # body direction of motion: gamma = phi + theta
            P2 = np.arctan2(self.s2b.astype(float), self.c2b.astype(float))  # 2 beta_body
            Q1, Q3 = P2 + phi, phi - P2
            H = np.stack([
                A10 * np.cos(P2), A10 * np.sin(P2),
                B11 * np.sin(Q1) + B01 * np.sin(phi), -B11 * np.cos(Q1) + B01 * np.cos(phi),
                Bm11 * np.sin(Q3), Bm11 * np.cos(Q3),
                D10 * np.sin(P2), -D10 * np.cos(P2),
                C11 * np.cos(Q1) + C01 * np.cos(phi), C11 * np.sin(Q1) - C01 * np.sin(phi),
                Cm11 * np.cos(Q3), -Cm11 * np.sin(Q3)])
            # An element on the rotation axis never moves: no RFT force in a rotation.
            area = np.where(np.hypot(sx, sz) > 0, self.area, 0.0)
            D, n = sx.shape
            G = np.zeros((16, D, max(n, 3)))  # zero-area padding holds the bound's 3 numbers
            G[:12, :, :n] = H
            G[12, :, :n], G[13, :, :n], G[14, :, :n] = sx, sz, area
            G[15, :, :3] = self.bound
            cache[key] = (fit, np.ascontiguousarray(G, dtype=self.sx.dtype))
        return cache[key][1]


def _net_fourier(packed: PackedElements, traj: Trajectory, fit: FourierFit, surface: float,
                 parallel: bool | None = None) -> np.ndarray:
    dt = packed.sx.dtype
    out = np.empty((packed.sx.shape[0], len(traj), 3), dtype=dt)
    hx, hz, vhx, vhz, c1, s1, c2, s2, w = traj.kernel_arrays(dt)
    if parallel is None:
        parallel = packed.sx.size * len(traj) >= PARALLEL_MIN_WORK
    rot_kernel = _fourier_rotation_kernel if parallel else _fourier_rotation_kernel_serial
    kernel = _fourier_kernel if parallel else _fourier_kernel_serial
    if traj.hip_at_rest:  # rotation about a hip at rest: harmonic form
        rot_kernel(packed.harmonics(fit), traj.kernel_rotation_table(dt), dt.type(fit.A00), dt.type(surface), out)
    else:
        kernel(packed.sx, packed.sz, packed.c2b, packed.s2b, packed.area, hx, hz, vhx, vhz, c1, s1, c2, s2, w, fit.as_array(dt), dt.type(surface), out)
    return out


def net_forces(leg: Leg | Elements, traj: Trajectory, model: StressModel, surface: float = 0.0,
               dynamic: tuple[float, float] | None = None, surface_correction=None):
    """Net (Fx, Fz, torque), each (S,), N and N m. Uses the compiled kernel for a
    :class:`FourierFit`, NumPy for any other stress model or with ``dynamic=(lambda, rho)``
    or a ``surface_correction`` hook (dynamic RFT, see :func:`element_forces`)."""
    el = leg.elements() if isinstance(leg, Leg) else leg
    if (dynamic is not None and dynamic[0]) or surface_correction is not None:
        return _net_numpy(el, traj, model, surface, dynamic, surface_correction)
    if isinstance(model, FourierFit):
        # Elements are immutable: pack once and keep the packed arrays with them.
        packed = el.__dict__.get("_packed")
        if packed is None:
            packed = el.__dict__["_packed"] = PackedElements.of([el])
        out = _net_fourier(packed, traj, model, surface)[0]
        return out[:, 0], out[:, 1], out[:, 2]
    return _net_numpy(el, traj, model, surface)


def batch_forces(legs: list[Leg | Elements] | PackedElements, traj: Trajectory,
                 model: StressModel, surface: float = 0.0, dtype=np.float64) -> np.ndarray:
    """Net forces for many designs under one motion: array (D, S, 3) of Fx, Fz (N), torque
    (N m). Designs may have different numbers of elements. ``dtype=np.float32`` roughly
    doubles the Fourier-fit throughput (8-wide SIMD, hardware reciprocal square root) at
    ~1e-6 relative precision; pass a :class:`PackedElements` to reuse packing."""
    if isinstance(legs, PackedElements):
        if not isinstance(model, FourierFit):
            raise TypeError("PackedElements only work with a FourierFit stress model")
        return _net_fourier(legs, traj, model, surface)
    els = [leg.elements() if isinstance(leg, Leg) else leg for leg in legs]
    if isinstance(model, FourierFit):
        return _net_fourier(PackedElements.of(els, dtype), traj, model, surface)
    return np.stack([np.stack(_net_numpy(e, traj, model, surface), -1) for e in els])
