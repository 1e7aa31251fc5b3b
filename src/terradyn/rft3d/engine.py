"""3D-RFT force engine: net wrench and per-element tractions of a body at given poses.

Conventions (SI): world frame x forward, y left, z up; the free surface of the bed is the plane
z = ``surface`` (m; bed below). A pose is a position ``X`` (3,) m of the body-frame origin and a
unit quaternion ``q = (w, x, y, z)`` (scalar first, as MuJoCo) rotating body to world: a body
point ``c`` sits at ``X + R(q) c``. Velocities: ``V`` (3,) m/s of the body-frame origin and
angular velocity ``W`` (3,) rad/s, both in the world frame; an element moves at V + W x r,
r = R(q) c. Forces are those of the medium on the body (N); torques (N m) are about a world
point (default: the body-frame origin X at each step).

Each element below the surface (depth = surface - z > 0) and leading (n . v >= 0) feels
``t = alpha(n, v^) depth`` (N/m^2, :mod:`terradyn.rft3d.model`) and, with the dynamic option
(Agarwal et al. 2021), ``- n lambda rho (n . v)^2`` in addition.

Two paths compute the same thing:

* :func:`element_tractions` - NumPy, every per-element quantity (tractions, depths,
  velocities, world positions), any surface-correction hook; the straightforward reference;
* a compiled kernel (:func:`wrench`, :func:`wrench_batch`, :class:`Evaluator`) - the same law
  per element without a trigonometric call; serial for small work (one pose of a
  2,000-triangle foot: no parallel region to pay for), parallel over poses and element blocks
  above :data:`PARALLEL_MIN_WORK` when a core is free (:func:`choose_parallel`).
"""
from __future__ import annotations

from .._jitcache import bind_to_sources as _bind_cache

import numba
import numpy as np

from ..errors import InputError, finite_array
from .body import Body
from .model import NZ_TIE, Medium3D, cap_tangential, coefficients, generic_alpha

#: Speeds below this (m/s) count as "at rest": no RFT force.
REST_SPEED = 1e-12
#: Element evaluations (poses x elements) from which the compiled kernel runs in parallel.
#: Below it a Numba parallel region costs more than it saves, and much more on a busy machine
#: (benchmarks/bench_rft3d.py).
PARALLEL_MIN_WORK = 200_000
#: Unit-norm tolerance of quaternions (|q| must be within this of 1).
QUAT_TOL = 1e-6


# ------------------------------------------------------------------------------------------
# Poses
# ------------------------------------------------------------------------------------------
def check_quaternions(q, field: str = "quaternion") -> np.ndarray:
    """(S, 4) or (4,) unit quaternions (w, x, y, z); raise if any is not normalised."""
    q = finite_array(field, q)
    if q.shape[-1] != 4:
        raise InputError(field, f"must have 4 components (w, x, y, z), got shape {q.shape}")
    norm = np.linalg.norm(q, axis=-1)
    bad = np.abs(norm - 1.0) > QUAT_TOL
    if np.any(bad):
        i = int(np.argmax(np.atleast_1d(bad)))
        raise InputError(field, f"must be a unit quaternion (w, x, y, z) with |q| = 1 within "
                                f"{QUAT_TOL:g}; sample {i} has |q| = {np.atleast_1d(norm)[i]:.9g}")
    return q


def rotation_matrices(q) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of unit quaternions (..., 4) in (w, x, y, z) order."""
    q = np.asarray(q, float)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)], -2)


def _steps(position, quaternion, velocity, angular_velocity, point, surface):
    """Broadcast pose inputs to (S, .) float arrays; checks finiteness and quaternions."""
    X = np.atleast_2d(finite_array("position", position))
    q = np.atleast_2d(check_quaternions(quaternion))
    V = np.atleast_2d(finite_array("velocity", velocity))
    W = np.atleast_2d(finite_array("angular_velocity", angular_velocity))
    S = max(len(X), len(q), len(V), len(W))
    for name, a in (("position", X), ("velocity", V), ("angular_velocity", W)):
        if a.shape[-1] != 3 or len(a) not in (1, S):
            raise InputError(name, f"must be (3,) or ({S}, 3) in m, m/s or rad/s, got shape {a.shape}")
    if len(q) not in (1, S):
        raise InputError("quaternion", f"must be (4,) or ({S}, 4), got shape {q.shape}")
    X, V, W = (np.broadcast_to(a, (S, 3)) for a in (X, V, W))
    q = np.broadcast_to(q, (S, 4))
    P = X if point is None else np.broadcast_to(np.atleast_2d(finite_array("point", point)), (S, 3))
    h = np.broadcast_to(np.atleast_1d(finite_array("surface", surface)).astype(float), (S,))
    return X, q, V, W, P, h


# ------------------------------------------------------------------------------------------
# NumPy reference: every per-element quantity
# ------------------------------------------------------------------------------------------
def element_kinematics(body: Body, position, quaternion, velocity, angular_velocity, surface=0.0,
                       point=None, surface_correction=None) -> dict:
    """World-frame kinematics of every element at S poses (NumPy): ``r`` centroids (S, n, 3) m,
    ``v`` velocities (S, n, 3) m/s, ``normal`` (S, n, 3), ``depth`` (S, n) m (after the
    surface correction, clipped at 0), ``vn`` = n . v (S, n), ``vhat`` unit directions,
    ``active`` (S, n) (submerged, moving, leading), ``point`` (S, 3) torque points."""
    X, q, V, W, P, h = _steps(position, quaternion, velocity, angular_velocity, point, surface)
    R = rotation_matrices(q)
    off = np.einsum("sij,nj->sni", R, body.centroids)
    n = np.einsum("sij,nj->sni", R, body.normals)
    r = X[:, None, :] + off
    v = V[:, None, :] + np.cross(W[:, None, :], off)
    depth = h[:, None] - r[..., 2]
    if surface_correction is not None:
        dh = np.asarray(surface_correction(r, v), float)
        if dh.shape != depth.shape or not np.isfinite(dh).all():
            raise InputError("surface_correction", f"must return finite delta_h of shape {depth.shape} in m")
        depth = depth - dh
    depth = np.maximum(depth, 0.0)
    speed = np.linalg.norm(v, axis=-1)
    vn = np.einsum("snk,snk->sn", n, v)
    active = (depth > 0) & (speed > REST_SPEED) & (vn >= 0)
    vhat = v / np.maximum(speed, REST_SPEED)[..., None]
    return {"r": r, "v": v, "normal": n, "depth": depth, "vn": vn, "vhat": vhat,
            "active": active, "point": P}


def net_of(body: Body, kin: dict, traction: np.ndarray) -> dict:
    """Element forces, net force and torque from tractions (S, n, 3) N/m^2: the dict of
    :func:`element_tractions`."""
    force = traction * body.areas[None, :, None]
    F = force.sum(1)
    T = np.cross(kin["r"] - kin["point"][:, None, :], force).sum(1)
    return {"traction": traction, "force": force, "r": kin["r"], "v": kin["v"],
            "normal": kin["normal"], "depth": kin["depth"], "active": kin["active"],
            "wrench": np.concatenate([F, T], axis=1)}


def dynamic_traction(kin: dict, lamrho: float) -> np.ndarray:
    """Dynamic-RFT inertial traction -n lambda rho (n . v)^2 on active elements, (S, n, 3)."""
    return -kin["normal"] * (lamrho * np.where(kin["active"], kin["vn"], 0.0) ** 2)[..., None]


def element_tractions(body: Body, position, quaternion, velocity, angular_velocity,
                      medium: Medium3D, surface=0.0, point=None, dynamic_lambda: float | None = None,
                      surface_correction=None, coef: np.ndarray | None = None) -> dict:
    """Per-element 3D-RFT result for S poses (NumPy).

    Inputs as :func:`wrench_batch` (single poses broadcast). ``surface_correction``: optional
    hook ``f(r, v) -> delta_h`` with world element positions r and velocities v (S, n, 3) giving
    delta_h (S, n) in m; the depth used is that of z~ = z + delta_h (Agarwal 2021), i.e.
    ``max(surface - z - delta_h, 0)``.

    Returns a dict of arrays: ``traction`` (S, n, 3) N/m^2 (force per element area on the body),
    ``force`` (S, n, 3) N, ``r`` (S, n, 3) m world centroids, ``v`` (S, n, 3) m/s,
    ``normal`` (S, n, 3), ``depth`` (S, n) m, ``active`` (S, n) bool, and the net ``wrench``
    (S, 6): Fx, Fy, Fz (N), Tx, Ty, Tz (N m) about ``point``.
    """
    k = element_kinematics(body, position, quaternion, velocity, angular_velocity, surface,
                           point, surface_correction)
    r, v, n, depth, vn, vhat, active, P = (k[x] for x in ("r", "v", "normal", "depth", "vn", "vhat",
                                                            "active", "point"))
    t = np.zeros_like(r)
    if active.any():
        a = generic_alpha(n[active], vhat[active], coefficients() if coef is None else coef)
        a = medium.xi_n * cap_tangential(a, n[active], medium.mu_surf)
        t[active] = a * depth[active][:, None]
    if dynamic_lambda:
        t += dynamic_traction(k, dynamic_lambda * medium.bulk_density)
    return net_of(body, k, t)


# ------------------------------------------------------------------------------------------
# Compiled kernel
# ------------------------------------------------------------------------------------------
#: Columns of a pose table row: X(3) R(9, row-major) V(3) W(3) point(3) surface(1).
POSE_COLUMNS = 22


def pose_table(X, q, V, W, P, h) -> np.ndarray:
    """(S, 22) contiguous pose table for the kernel (see :data:`POSE_COLUMNS`)."""
    S = len(X)
    T = np.empty((S, POSE_COLUMNS))
    T[:, 0:3] = X
    T[:, 3:12] = rotation_matrices(q).reshape(S, 9)
    T[:, 12:15] = V
    T[:, 15:18] = W
    T[:, 18:21] = P
    T[:, 21] = h
    return T


@numba.njit(fastmath=True, inline="always", error_model="numpy")
def _cubic(c, x1, x2, x3, x11, x22, x33):  # pragma: no cover - compiled
    """One of the cubic fits at (x1, x2, x3), monomials in :data:`model.MONOMIALS` order,
    written out so that the element loop stays a straight line (SIMD)."""
    return (c[0] + c[1] * x1 + c[2] * x2 + c[3] * x3 + c[4] * x11 + c[5] * x22
            + c[6] * x33 + c[7] * x1 * x2 + c[8] * x2 * x3 + c[9] * x3 * x1
            + c[10] * x11 * x1 + c[11] * x22 * x2 + c[12] * x33 * x3
            + c[13] * x1 * x22 + c[14] * x2 * x11 + c[15] * x2 * x33
            + c[16] * x3 * x22 + c[17] * x3 * x11 + c[18] * x1 * x33
            + c[19] * x1 * x2 * x3)


@numba.njit(fastmath=True, cache=True, error_model="numpy", nogil=True)
def _block(G, T, j, lo, hi, C, prm, out, k):  # pragma: no cover - compiled
    """Sum of the wrenches of elements lo..hi at pose j into out[k] (Fx, Fy, Fz, Tx, Ty, Tz).

    G (7, n) body data as rows cx, cy, cz, nx, ny, nz, area (struct of arrays); T (S, 22)
    poses; C (3, 20) coefficients; prm (7,) xi_n, mu_surf, lambda rho and the body's bounding
    sphere (centre x, y, z, radius; body frame): a pose whose sphere is above the surface is
    skipped. Written without branches (a mask multiplies each element's force) and with the
    cubic fits unrolled so that the element loop compiles to SIMD instructions."""
    c1, c2, c3 = C[0], C[1], C[2]
    xi, mus, lamrho = prm[0], prm[1], prm[2]
    r00, r01, r02 = T[j, 3], T[j, 4], T[j, 5]
    r10, r11, r12 = T[j, 6], T[j, 7], T[j, 8]
    r20, r21, r22 = T[j, 9], T[j, 10], T[j, 11]
    Xx, Xy, Xz = T[j, 0], T[j, 1], T[j, 2]
    if Xz + r20 * prm[3] + r21 * prm[4] + r22 * prm[5] - prm[6] >= T[j, 21]:
        for c in range(6):
            out[k, c] = 0.0  # the whole body is above the surface
        return
    Vx, Vy, Vz = T[j, 12], T[j, 13], T[j, 14]
    wx, wy, wz = T[j, 15], T[j, 16], T[j, 17]
    px, py, pz = Xx - T[j, 18], Xy - T[j, 19], Xz - T[j, 20]  # origin relative to the torque point
    h0 = T[j, 21] - Xz
    # constants in the arrays' float type: float32 data keep the loop in float32 (twice the
    # SIMD width); TINY keeps 1/sqrt finite at rest in either type
    zero = G.dtype.type(0.0)
    one = G.dtype.type(1.0)
    rest2 = G.dtype.type(1e-24)
    tiny = G.dtype.type(1e-30)
    tie = G.dtype.type(NZ_TIE)
    Fx = Fy = Fz = Tx = Ty = Tz = zero
    for i in range(lo, hi):
        bx, by, bz = G[0, i], G[1, i], G[2, i]
        ox = r00 * bx + r01 * by + r02 * bz
        oy = r10 * bx + r11 * by + r12 * bz
        oz = r20 * bx + r21 * by + r22 * bz
        depth = h0 - oz
        gx, gy, gz = G[3, i], G[4, i], G[5, i]
        nx = r00 * gx + r01 * gy + r02 * gz
        ny = r10 * gx + r11 * gy + r12 * gz
        nz = r20 * gx + r21 * gy + r22 * gz
        vx = Vx + wy * oz - wz * oy
        vy = Vy + wz * ox - wx * oz
        vz = Vz + wx * oy - wy * ox
        vn = nx * vx + ny * vy + nz * vz
        v2 = vx * vx + vy * vy + vz * vz
        on = (depth > zero) & (vn >= zero) & (v2 > rest2)
        inv = one / np.sqrt(v2 + tiny)
        s = one if nz >= tie else -one
        x1 = -vz * inv
        x2 = abs(nz)
        x3 = -s * vn * inv
        x11 = x1 * x1
        x22 = x2 * x2
        x33 = x3 * x3
        f1 = _cubic(c1, x1, x2, x3, x11, x22, x33)
        f2 = _cubic(c2, x1, x2, x3, x11, x22, x33)
        f3 = _cubic(c3, x1, x2, x3, x11, x22, x33)
        g1 = -s * f1
        f2i = f2 * inv
        ax_ = g1 * nx + f2i * vx
        ay_ = g1 * ny + f2i * vy
        az_ = g1 * nz + f2i * vz - f3
        an = ax_ * nx + ay_ * ny + az_ * nz  # normal part an n; tangential part capped
        tx, ty, tz = ax_ - an * nx, ay_ - an * ny, az_ - an * nz
        kt = min(one, mus * abs(an) / np.sqrt(tx * tx + ty * ty + tz * tz + tiny))
        # the mask multiplies the area: a conditional expression around the loads here kept
        # LLVM's loop vectorizer out on AVX2 CPUs (scalar code, 4.5x slower in float64 and
        # 10x in float32 on the 2-core AMD VM: benchmarks/bench_rft3d.py); every term is
        # finite off the mask
        area = (one if on else zero) * G[6, i]
        load = xi * max(depth, zero) * area
        dyn = lamrho * vn * vn * area
        fx = (an * nx + kt * tx) * load - dyn * nx
        fy = (an * ny + kt * ty) * load - dyn * ny
        fz = (an * nz + kt * tz) * load - dyn * nz
        rx, ry, rz = px + ox, py + oy, pz + oz
        Fx += fx
        Fy += fy
        Fz += fz
        Tx += ry * fz - rz * fy
        Ty += rz * fx - rx * fz
        Tz += rx * fy - ry * fx
    out[k, 0] = Fx
    out[k, 1] = Fy
    out[k, 2] = Fz
    out[k, 3] = Tx
    out[k, 4] = Ty
    out[k, 5] = Tz


@numba.njit(fastmath=True, cache=True, error_model="numpy", nogil=True)
def _wrench_serial(G, T, C, prm, out):  # pragma: no cover - compiled
    """Net wrench of every pose, serial. G (n, 7) body; T (S, 22) poses; C (3, 20) coefficients;
    prm (7,) see :func:`_block`; out (S, 6)."""
    n = G.shape[1]
    for j in range(T.shape[0]):
        _block(G, T, j, 0, n, C, prm, out, j)


@numba.njit(parallel=True, fastmath=True, cache=True, error_model="numpy", nogil=True)
def _wrench_parallel(G, T, C, prm, nblk, part):  # pragma: no cover - compiled
    """Parallel over poses x element blocks; part (S * nblk, 6) partial sums."""
    n = G.shape[1]
    S = T.shape[0]
    size = (n + nblk - 1) // nblk
    for k in numba.prange(S * nblk):
        j = k // nblk
        b = k - j * nblk
        lo = b * size
        hi = min(n, lo + size)
        _block(G, T, j, lo, hi, C, prm, part, k)


@numba.njit(fastmath=True, cache=True, error_model="numpy", nogil=True)
def _wrench_one(G, C, prm, X, q, V, W, P, h, T, out):  # pragma: no cover - compiled
    """One pose from raw vectors (X, q w-x-y-z, V, W, P (3,), h scalar) into T (1, 22) and
    out (1, 6): the per-step call of a physics engine, no NumPy temporaries."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    T[0, 0], T[0, 1], T[0, 2] = X[0], X[1], X[2]
    T[0, 3] = 1 - 2 * (y * y + z * z)
    T[0, 4] = 2 * (x * y - w * z)
    T[0, 5] = 2 * (x * z + w * y)
    T[0, 6] = 2 * (x * y + w * z)
    T[0, 7] = 1 - 2 * (x * x + z * z)
    T[0, 8] = 2 * (y * z - w * x)
    T[0, 9] = 2 * (x * z - w * y)
    T[0, 10] = 2 * (y * z + w * x)
    T[0, 11] = 1 - 2 * (x * x + y * y)
    for k in range(3):
        T[0, 12 + k] = V[k]
        T[0, 15 + k] = W[k]
        T[0, 18 + k] = P[k]
    T[0, 21] = h
    _block(G, T, 0, 0, G.shape[1], C, prm, out, 0)


def _params(medium: Medium3D, dynamic_lambda: float | None, body: Body) -> np.ndarray:
    """Kernel parameters (7,): xi_n, mu_surf, lambda rho, bounding sphere of the body."""
    return np.array([medium.xi_n, medium.mu_surf, (dynamic_lambda or 0.0) * medium.bulk_density,
                     *body.bounding_sphere()], dtype=float)


def choose_parallel(work: int) -> bool:
    """Parallel only for work (element evaluations) >= :data:`PARALLEL_MIN_WORK` and only
    when the machine has a free core: with the 1-minute load average at or above the number
    of CPUs the threads of a parallel region wait for cores and the call runs slower than
    serially (benchmarks/bench_rft3d.py measured 0.6-0.8x at load 7-10 on 2 cores)."""
    if work < PARALLEL_MIN_WORK or numba.get_num_threads() < 2:
        return False
    try:
        import os

        return os.getloadavg()[0] < (os.cpu_count() or 1)
    except OSError:  # no load average on this platform
        return True


def run_kernel(G: np.ndarray, T: np.ndarray, C: np.ndarray, prm: np.ndarray,
               parallel: bool | None = None, dtype=np.float64) -> np.ndarray:
    """Net wrenches (S, 6) from packed arrays. ``parallel=None`` chooses by the work size
    (:func:`choose_parallel`). ``dtype=np.float32`` runs the element
    loop in single precision (about twice the throughput, ~1e-5 relative precision); the
    result is float64 either way."""
    S, n = T.shape[0], G.shape[1]
    if parallel is None:
        parallel = choose_parallel(S * n)
    if np.dtype(dtype) != np.float64:
        G, T, C, prm = (np.ascontiguousarray(a, dtype=dtype) for a in (G, T, C, prm))
    if not parallel:
        out = np.empty((S, 6), dtype=G.dtype)
        _wrench_serial(G, T, C, prm, out)
        return out.astype(float, copy=False)
    threads = numba.get_num_threads()
    nblk = max(1, min(-(-2 * threads // S), max(1, n // 256)))  # enough blocks for all threads
    part = np.empty((S * nblk, 6), dtype=G.dtype)
    _wrench_parallel(G, T, C, prm, nblk, part)
    return part.reshape(S, nblk, 6).astype(float).sum(1)


def wrench_batch(body: Body, position, quaternion, velocity, angular_velocity, medium: Medium3D,
                 surface=0.0, point=None, dynamic_lambda: float | None = None,
                 coef: np.ndarray | None = None, parallel: bool | None = None,
                 dtype=np.float64) -> np.ndarray:
    """Net wrench of ``body`` at S poses: array (S, 6) of Fx, Fy, Fz (N), Tx, Ty, Tz (N m).

    position (S, 3) m; quaternion (S, 4) unit (w, x, y, z), body to world; velocity (S, 3) m/s
    of the body-frame origin; angular_velocity (S, 3) rad/s (world frame); any of them may be
    a single (3,) / (4,) row for all steps. ``surface``: free-surface height, m (scalar or
    (S,)). ``point``: torque reference point(s) (3,) or (S, 3) m in the world frame; default
    the body-frame origin at each step. ``dynamic_lambda``: add the dynamic-RFT inertial term
    with this lambda (None: quasi-static). ``parallel``: force the threading (None: by size).
    ``dtype=np.float32``: single-precision element loop (see :func:`run_kernel`); poses are
    best given relative to a nearby origin then (positions of O(1 m) lose ~0.1 um).
    """
    X, q, V, W, P, h = _steps(position, quaternion, velocity, angular_velocity, point, surface)
    C = coefficients() if coef is None else np.ascontiguousarray(coef, float)
    return run_kernel(body.packed(), pose_table(X, q, V, W, P, h), C,
                      _params(medium, dynamic_lambda, body), parallel, dtype)


def wrench(body: Body, position, quaternion, velocity, angular_velocity, medium: Medium3D,
           surface: float = 0.0, point=None, dynamic_lambda: float | None = None) -> np.ndarray:
    """Net wrench (6,) of one pose: Fx, Fy, Fz (N), Tx, Ty, Tz (N m) about ``point`` (default
    the body-frame origin). Arguments as :func:`wrench_batch` with single rows; checked, then
    the serial compiled kernel (no parallel region for one pose)."""
    vecs = []
    for name, a, k in (("position", position, 3), ("quaternion", quaternion, 4),
                       ("velocity", velocity, 3), ("angular_velocity", angular_velocity, 3),
                       ("point", position if point is None else point, 3)):
        a = np.asarray(a, dtype=float)
        if a.shape != (k,) or not np.isfinite(a).all():
            finite_array(name, a)
            raise InputError(name, f"must be {k} finite numbers (SI), got shape {a.shape}")
        vecs.append(a)
    X, q, V, W, P = vecs
    if abs(q @ q - 1.0) > 2 * QUAT_TOL:
        check_quaternions(q)
    h = float(surface)
    if not np.isfinite(h):
        raise InputError("surface", f"must be finite (m), got {surface!r}")
    out = np.empty((1, 6))
    _wrench_one(body.packed(), coefficients(), _params(medium, dynamic_lambda, body), X, q, V, W, P,
                h, np.empty((1, POSE_COLUMNS)), out)
    return out[0]


class Evaluator:
    """A fast single-pose wrench for physics-engine steps: inputs are checked once here, and
    :meth:`__call__` only packs the pose and runs the serial compiled kernel.

    ``Evaluator(body, medium)(X, q, V, W, surface=0.0, point=None) -> (6,)`` (SI, q = w, x, y, z
    unit: not re-checked per call beyond a norm test). ``dtype=np.float32`` halves the time
    (~1e-6 relative precision; keep X near the origin of a local frame, e.g. the body's own
    position relative to a terrain patch, for the precision to hold)."""

    def __init__(self, body: Body, medium: Medium3D, dynamic_lambda: float | None = None,
                 coef: np.ndarray | None = None, dtype=np.float64):
        self.body = body
        self.medium = medium
        dt = np.dtype(dtype)
        self._G = np.ascontiguousarray(body.packed(), dtype=dt)
        self._C = np.ascontiguousarray(coefficients() if coef is None else coef, dtype=dt)
        self._prm = _params(medium, dynamic_lambda, body).astype(dt)
        self._T = np.empty((1, POSE_COLUMNS), dtype=dt)
        self._out = np.empty((1, 6), dtype=dt)

    def __call__(self, X, q, V, W, surface: float = 0.0, point=None) -> np.ndarray:
        X = np.asarray(X, dtype=float)
        q = np.asarray(q, dtype=float)
        if abs(q @ q - 1.0) > 2 * QUAT_TOL:
            check_quaternions(q)
        _wrench_one(self._G, self._C, self._prm, X, q, np.asarray(V, dtype=float),
                    np.asarray(W, dtype=float), X if point is None else np.asarray(point, dtype=float),
                    float(surface), self._T, self._out)
        return self._out[0].astype(float)

# Cached kernels above use jitted code and constants of other modules: make their on-disk
# cache stale when those change too (terradyn._jitcache; Numba checks only this file).
_bind_cache(globals(), 'terradyn.rft3d.model')
