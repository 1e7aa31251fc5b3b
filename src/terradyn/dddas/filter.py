"""Online assimilation over surrogate coefficients: particle filter and exact Gaussian posterior.

Both work on the same linear-Gaussian model: coefficients c (D,) with a Gaussian prior from
the surrogate's GP, observations ``y = h @ c + offset + e``, ``e ~ N(0, sigma^2)``, one scalar
sample at a time (h (D,) comes from :meth:`Surrogate.observation_rows`). Because the model is
linear in c, :class:`GaussianPosterior` (a Kalman update per sample) is the exact posterior;
:class:`ParticleFilter` approximates it (and is what the thesis runs, and what stays valid
for non-Gaussian priors or likelihoods).

Particle filter (per sample): log-weights += Gaussian log-likelihood of the residual; the
effective sample size ESS = 1 / sum(w^2); when ESS < ``ess_threshold`` * N, resample
(multinomial as in the thesis, or systematic) and jitter the copies with a moment-matched
Liu-West kernel c <- a c + (1 - a) mean + h sd u, a = sqrt(1 - h^2), with u zero-mean,
unit-variance uniform noise per dimension (mean and variances are preserved; correlations
shrink by a^2 per resampling). The hot loops are Numba kernels; ``backend="numpy"`` is the
straightforward NumPy version the benchmark compares with.
"""
from __future__ import annotations

import math

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

from ..errors import InputError, choice, finite, finite_array, in_range, integer, positive

RESAMPLERS = ("multinomial", "systematic")
BACKENDS = ("numba", "numpy")


# ------------------------------------------------------------------------------ kernels
# The Numba kernels keep the particles as float32 structure-of-arrays (D, N) so that every
# loop runs over particles with unit stride and LLVM vectorises it (AVX2: 8 lanes). exp, log
# and the random numbers are written out so they vectorise too (libm calls do not):
#   exp(x) = 2^n 2^f (f in [0, 1), 2^f a degree-6 polynomial, rel. error ~3e-6 from the
#   rounding of f), the exponent n added to the float's bits;
#   log(v) = e ln 2 + log(m) (m in [1, 2), degree-8 polynomial, abs. error ~1e-7);
#   uniforms from an integer hash (lowbias32) of a counter, seeded per call from the
#   caller's np.random.Generator (so runs are reproducible and independent).
# Loops that cannot vectorise (cumulative sums, the resampling merge) run several
# independent chains at once so that the CPU overlaps their latencies.
def _poly(fn, lo, hi, deg):
    x = 0.5 * (lo + hi) + 0.5 * (hi - lo) * np.cos(np.pi * (np.arange(8 * deg) + 0.5) / (8 * deg))
    return tuple(np.float32(c) for c in np.polyfit(x - lo, fn(x), deg))


_E = _poly(lambda f: 2.0 ** f, 0.0, 1.0, 6)
_L = _poly(np.log, 1.0, 2.0, 8)
_LOG2E = np.float32(1.4426950408889634)
_LN2 = np.float32(0.6931471805599453)


_RENORM = -30.0  # shift the log-weights back to max 0 when their max falls below this
_SUM_RENORM = math.exp(_RENORM)  # sum(w) < N * this is necessary for max(logw) < _RENORM
_SQ = np.float32(2.0 ** 40)  # scale of the weights in the float32 sum of squares (no overflow)


@intrinsic
def _f32_bits(typingctx, x):  # pragma: no cover - compiled
    """The bits of a float32 as an int32 (a register bitcast: vectorises)."""
    def codegen(context, builder, sig, args):
        return builder.bitcast(args[0], ir.IntType(32))
    return types.int32(types.float32), codegen


@intrinsic
def _bits_f32(typingctx, x):  # pragma: no cover - compiled
    """The float32 with the bits of an int32."""
    def codegen(context, builder, sig, args):
        return builder.bitcast(args[0], ir.FloatType())
    return types.float32(types.int32), codegen


@njit(inline="always")
def _hash32(x):  # pragma: no cover - compiled
    # lowbias32 integer hash (C. Wellons). Numba widens integer arithmetic to 64 bits:
    # truncate back to 32 after every step (LLVM then keeps it in 32-bit SIMD lanes).
    x = np.uint32(x ^ (x >> np.uint32(16)))
    x = np.uint32(x * np.uint32(0x7FEB352D))
    x = np.uint32(x ^ (x >> np.uint32(15)))
    x = np.uint32(x * np.uint32(0x846CA68B))
    return np.uint32(x ^ (x >> np.uint32(16)))


@njit(inline="always")
def _u01(i, seed):  # pragma: no cover - compiled
    """float32 uniform in [0, 1) from the hash of counter i + seed (24 random bits)."""
    r = _hash32(np.uint32(np.uint32(i) + seed))
    return np.float32(np.int32(r >> np.uint32(8))) * np.float32(5.960464477539063e-08)


@njit(inline="always")
def _u12(i, seed):  # pragma: no cover - compiled
    """float32 uniform in [1, 2) from the hash of counter i + seed: the top 23 bits are the
    mantissa (no int-to-float conversion)."""
    r = _hash32(np.uint32(np.uint32(i) + seed))
    return _bits_f32(np.int32(r >> np.uint32(9)) | np.int32(0x3F800000))


@njit(inline="always")
def _exp_neg(v):  # pragma: no cover - compiled
    """exp(v) for float32 v <= 0, clamped below at 2^-126 (a normal float)."""
    e0, e1, e2, e3, e4, e5, e6 = _E
    t = v * _LOG2E + np.float32(127.0)          # biased exponent, clamped to normals
    t = t if t > np.float32(1.0) else np.float32(1.0)
    n = np.int32(t)                              # t > 0: truncation is floor
    f = t - np.float32(n)
    p = ((((((e0 * f + e1) * f + e2) * f + e3) * f + e4) * f + e5) * f + e6)  # 2^f in [1, 2)
    return _bits_f32(_f32_bits(p) + ((n - np.int32(127)) << np.int32(23)))


@njit(inline="always")
def _log01(v):  # pragma: no cover - compiled
    """log(v) for float32 v in (0, 1] (normal)."""
    l0, l1, l2, l3, l4, l5, l6, l7, l8 = _L
    b = _f32_bits(v)
    e = np.float32((b >> np.int32(23)) - np.int32(127))
    x = _bits_f32((b & np.int32(0x007FFFFF)) | np.int32(0x3F800000)) - np.float32(1.0)
    lg = ((((((((l0 * x + l1) * x + l2) * x + l3) * x + l4) * x + l5) * x + l6) * x + l7) * x + l8)
    return e * _LN2 + lg


@njit(inline="always")
def _rows_dot(Ct, h, d0, nr, o, pred, add):  # pragma: no cover - compiled
    """pred (+)= o + sum over rows d0 .. d0 + nr - 1 (nr <= 4) of h[d] Ct[d]: one pass."""
    N = Ct.shape[1]
    if nr >= 4:
        a0, a1, a2, a3 = h[d0], h[d0 + 1], h[d0 + 2], h[d0 + 3]
        for i in range(N):
            p = o + Ct[d0, i] * a0 + Ct[d0 + 1, i] * a1 + Ct[d0 + 2, i] * a2 + Ct[d0 + 3, i] * a3
            pred[i] = pred[i] + p if add else p
    elif nr == 3:
        a0, a1, a2 = h[d0], h[d0 + 1], h[d0 + 2]
        for i in range(N):
            p = o + Ct[d0, i] * a0 + Ct[d0 + 1, i] * a1 + Ct[d0 + 2, i] * a2
            pred[i] = pred[i] + p if add else p
    elif nr == 2:
        a0, a1 = h[d0], h[d0 + 1]
        for i in range(N):
            p = o + Ct[d0, i] * a0 + Ct[d0 + 1, i] * a1
            pred[i] = pred[i] + p if add else p
    else:
        a0 = h[d0]
        for i in range(N):
            p = o + Ct[d0, i] * a0
            pred[i] = pred[i] + p if add else p


@njit(inline="always")
def _weigh(ws, yy, hv, shift):  # pragma: no cover - compiled
    """logw = max(logw - shift - hv (y - pred)^2, -1e30); w = exp(logw). Returns float32
    sum(w) and sum((w 2^40)^2) (vectorised float32 sums; the scale keeps squares of weights
    down to 2^-103 normal)."""
    N = ws.shape[1]
    lo = np.float32(-1.0e30)  # never -inf (float32 overflow)
    s = np.float32(0.0)
    s2 = np.float32(0.0)
    for i in range(N):
        r = yy - ws[2, i]
        v = ws[0, i] - shift - hv * r * r
        v = v if v > lo else lo
        ws[0, i] = v
        w = _exp_neg(v)
        ws[1, i] = w
        s += w
        q = w * _SQ
        s2 += q * q
    return s, s2


# Workspaces: ws float32 (3, N): log-weights, weights, predictions; w64 float64 (2, N + 1):
# cumulative weights (w64[0, j + 1] = w[0] + ... + w[j]) and sorted uniforms; wi int32
# (2, N + 1): scatter marks and ancestors.
@njit(fastmath=True, nogil=True, cache=True)
def _nb_update(Ct, h, off, y, half_inv_var, ws):  # pragma: no cover - compiled
    """logw += log N(y; h @ C + off, sigma^2); w = exp(logw). The log-weights are shifted
    back to max 0 only when their max drops below _RENORM (the ESS does not depend on the
    shift; the max is only looked at when sum(w) says it may be that low). Ct (D, N)
    float32; h (D,) float32. Returns the ESS = (sum w)^2 / sum w^2."""
    D, N = Ct.shape
    pred = ws[2]
    zero = np.float32(0.0)
    if D > 4:  # rows 4.. first, four per pass; rows 0-3 and the offset last
        for d0 in range(4, D, 4):
            nr = min(D - d0, 4)
            if nr == 4:
                _rows_dot(Ct, h, d0, 4, zero, pred, d0 > 4)
            elif nr == 3:
                _rows_dot(Ct, h, d0, 3, zero, pred, d0 > 4)
            elif nr == 2:
                _rows_dot(Ct, h, d0, 2, zero, pred, d0 > 4)
            else:
                _rows_dot(Ct, h, d0, 1, zero, pred, d0 > 4)
    o = np.float32(off)
    if D >= 4:
        _rows_dot(Ct, h, 0, 4, o, pred, D > 4)
    elif D == 3:
        _rows_dot(Ct, h, 0, 3, o, pred, False)
    elif D == 2:
        _rows_dot(Ct, h, 0, 2, o, pred, False)
    else:
        _rows_dot(Ct, h, 0, 1, o, pred, False)
    yy = np.float32(y)
    hv = np.float32(half_inv_var)
    s, s2 = _weigh(ws, yy, hv, zero)
    if s < N * _SUM_RENORM:  # max(logw) may be below _RENORM: look, and shift back to 0
        m = ws[0, 0]
        for i in range(N):
            m = max(m, ws[0, i])
        if m < _RENORM:
            # logw - m - hv (y - pred)^2 with pred = y: the same update, shifted by m
            for i in range(N):
                ws[2, i] = yy
            s, s2 = _weigh(ws, yy, hv, m)
    sd = np.float64(s)
    return sd * sd / (np.float64(s2) / (np.float64(_SQ) * np.float64(_SQ)))


@njit(inline="always")
def _cumsum(src, dst, off, n, scale):  # pragma: no cover - compiled
    """dst[off + k] = scale * (src[0] + ... + src[k]) in float64 for k < n (in place if
    dst is src and off is 0), in four interleaved chains (one chain's adds wait for each
    other; four hide that latency). Returns the unscaled total."""
    q = n // 4
    s0 = 0.0
    for k in range(q):
        s0 += src[k]
    s1 = 0.0
    for k in range(q, 2 * q):
        s1 += src[k]
    s2 = 0.0
    for k in range(2 * q, 3 * q):
        s2 += src[k]
    a0 = 0.0
    a1 = s0
    a2 = s0 + s1
    a3 = a2 + s2
    for k in range(q):
        a0 += src[k]
        dst[off + k] = a0 * scale
        a1 += src[q + k]
        dst[off + q + k] = a1 * scale
        a2 += src[2 * q + k]
        dst[off + 2 * q + k] = a2 * scale
        a3 += src[3 * q + k]
        dst[off + 3 * q + k] = a3 * scale
    for k in range(4 * q, n):
        a3 += src[k]
        dst[off + k] = a3 * scale
    return a3


@njit(inline="always")
def _lower_bound(cwp, N, t):  # pragma: no cover - compiled
    """Smallest j in [0, N - 1] with cw[j] >= t (cw[j] = cwp[j + 1]; N - 1 if none)."""
    lo = 0
    hi = N - 1
    while lo < hi:
        mid = (lo + hi) // 2
        if cwp[mid + 1] < t:
            lo = mid + 1
        else:
            hi = mid
    return lo


@njit(inline="always")
def _path_start(T, cwp, N, p):  # pragma: no cover - compiled
    """The merge of the sorted points T[0 .. N-1] with the cumulative weights cw[0 .. N-2]
    (cw[j] goes first iff cw[j] < T[i]): the state (i, j) after its first p elements."""
    lo = max(0, p - (N - 1))
    hi = min(p, N)
    while lo < hi:  # smallest i with cw[p - i - 1] < T[i] (true at hi)
        mid = (lo + hi) // 2
        if cwp[p - mid] < T[mid]:
            hi = mid
        else:
            lo = mid + 1
    return lo, p - lo


@njit(inline="always")
def _merge_step(T, cwp, anc, i, j):  # pragma: no cover - compiled
    """One element of the merge, without branches: T[i] maps to ancestor j unless cw[j] < T[i]."""
    c = np.int64(cwp[j + 1] < T[i])
    anc[i] = j
    return i + 1 - c, j + c


@njit(inline="always")
def _ancestors(w, w64, wi, systematic, seed):  # pragma: no cover - compiled
    """wi[1, :N] = the ancestor of each new particle, nondecreasing: particle j is picked
    for the points t (sorted in [0, sum w)) with cw[j - 1] < t <= cw[j]."""
    N = w.shape[0]
    cwp = w64[0]
    anc = wi[1]
    s = _cumsum(w, cwp, 1, N, 1.0)
    if systematic:
        # points t_i = (i + u) s / N: particle j gets n_j - n_(j-1) of them, where
        # n_j = #{i: t_i <= cw[j]}. No search: mark where each particle's run starts
        # (mark[n_(j-1)] = j, later j overwrite), then a running max fills the runs in.
        mark = wi[0]
        u1 = 1.0 - np.float64(_u01(0, seed))
        inv = N / s
        top = np.int32(N)
        for i in range(N + 1):
            mark[i] = 0
        for j in range(N - 1):
            anc[j] = min(np.int32(cwp[j + 1] * inv + u1), top)  # n_j (scratch)
        for j in range(1, N):
            mark[anc[j - 1]] = j
        a = np.int32(0)
        for i in range(N):
            a = max(a, mark[i])
            anc[i] = a
    else:
        # Multinomial: sorted uniforms as normalised partial sums of N + 1 exponentials
        # (O(N), no sort), merged with cw in four chains that start at equal distances
        # along the merge (binary search on the merge path).
        T = w64[1]
        tot = 0.0
        for i in range(N + 1):
            e = -_log01(np.float32(1.0) - _u01(i, seed))  # Exp(1); 1 - u in (0, 1]
            T[i] = e
            tot += e
        _cumsum(T, T, 0, N, s / tot)
        T[N] = np.inf
        cwp[0] = -np.inf
        cwp[N] = np.inf  # cw[N - 1]: the last particle takes whatever rounding leaves
        L = 2 * N - 1  # elements of the merge: N points, N - 1 finite cw
        P = L // 4
        i0, j0 = 0, 0
        i1, j1 = _path_start(T, cwp, N, P)
        i2, j2 = _path_start(T, cwp, N, 2 * P)
        i3, j3 = _path_start(T, cwp, N, 3 * P)
        b1, b2, b3 = i1, i2, i3
        for _ in range(P):
            i0, j0 = _merge_step(T, cwp, anc, i0, j0)
            i1, j1 = _merge_step(T, cwp, anc, i1, j1)
            i2, j2 = _merge_step(T, cwp, anc, i2, j2)
            i3, j3 = _merge_step(T, cwp, anc, i3, j3)
        for _ in range(4 * P, L):
            i3, j3 = _merge_step(T, cwp, anc, i3, j3)
        # A chain can leave an unfinished value in the first slot of the next: redo those.
        for b in (b1, b2, b3):
            if b < N:
                anc[b] = _lower_bound(cwp, N, T[b])


@njit(inline="always")
def _gather_rows(Ct, out, anc, d0, nr, N):  # pragma: no cover - compiled
    """out[d, i] = Ct[d, anc[i]] for rows d0 .. d0 + nr - 1 (nr <= 4): one pass."""
    if nr >= 4:
        for i in range(N):
            a = anc[i]
            out[d0, i] = Ct[d0, a]
            out[d0 + 1, i] = Ct[d0 + 1, a]
            out[d0 + 2, i] = Ct[d0 + 2, a]
            out[d0 + 3, i] = Ct[d0 + 3, a]
    elif nr == 3:
        for i in range(N):
            a = anc[i]
            out[d0, i] = Ct[d0, a]
            out[d0 + 1, i] = Ct[d0 + 1, a]
            out[d0 + 2, i] = Ct[d0 + 2, a]
    elif nr == 2:
        for i in range(N):
            a = anc[i]
            out[d0, i] = Ct[d0, a]
            out[d0 + 1, i] = Ct[d0 + 1, a]
    else:
        for i in range(N):
            out[d0, i] = Ct[d0, anc[i]]


@njit(fastmath=True, nogil=True, cache=True)
def _nb_resample(Ct, out, ws, w64, wi, systematic, seed, jitter, jfloor):  # pragma: no cover
    """Resample the columns of Ct (D, N) by the weights ws[1] (set by _nb_update), jitter
    them (Liu-West, uniform noise), and reset the weights. ``seed``: uint32 from the
    caller's Generator; out (D, N) float32 scratch; jfloor (D,): lower bound on the jitter
    noise std per coefficient (process noise)."""
    D, N = Ct.shape
    _ancestors(ws[1], w64, wi, systematic, seed)
    anc = wi[1]
    for d0 in range(0, D, 4):
        _gather_rows(Ct, out, anc, d0, min(4, D - d0), N)
    if jitter > 0.0:
        a = math.sqrt(1.0 - jitter * jitter)
        a32 = np.float32(a)
        for d in range(D):
            x0 = out[d, 0]
            s1 = np.float32(0.0)
            sq = np.float32(0.0)
            for i in range(N):
                x = out[d, i] - x0  # shifted sums: no cancellation
                s1 += x
                sq += x * x
            mu = np.float64(s1) / N
            var = max(np.float64(sq) / N - mu * mu, 0.0)
            # u uniform in [1, 2): mean 3/2, variance 1/12.
            amp = np.float32(max(jitter * math.sqrt(var), jfloor[d]) * math.sqrt(12.0))
            c0 = np.float32((1.0 - a) * (mu + x0)) - amp * np.float32(1.5)
            sd = np.uint32(seed + np.uint32(np.uint32(d + 1) * np.uint32(0x9E3779B9)))
            for i in range(N):
                Ct[d, i] = a32 * out[d, i] + c0 + amp * _u12(i, sd)
    else:
        for d in range(D):
            for i in range(N):
                Ct[d, i] = out[d, i]
    for i in range(N):
        ws[0, i] = 0.0
        ws[1, i] = 1.0


# ------------------------------------------------------------------------------ filters
class GaussianPosterior:
    """Exact posterior of the linear-Gaussian model: prior N(mean (D,), cov (D, D)),
    rank-one Kalman update per scalar sample. Same interface as :class:`ParticleFilter`."""

    def __init__(self, mean, cov):
        self.m = finite_array("prior mean", mean, ndim=1).copy()
        P = finite_array("prior covariance", cov, ndim=2)
        if P.shape != (len(self.m), len(self.m)):
            raise InputError("prior covariance", f"must be {len(self.m)} x {len(self.m)}, got {P.shape}")
        self.P = 0.5 * (P + P.T)
        self.n_updates = 0

    def update(self, h, offset: float, y: float, sigma: float) -> float:
        """Condition on one sample y (N) with noise std sigma (N). Returns inf (no ESS)."""
        Ph = self.P @ h
        S = float(h @ Ph) + sigma * sigma
        K = Ph / S
        self.m = self.m + K * (y - offset - float(h @ self.m))
        self.P = self.P - np.outer(K, Ph)
        self.P = 0.5 * (self.P + self.P.T)
        self.n_updates += 1
        return math.inf

    def update_many(self, H, offsets, ys, sigmas) -> None:
        """Condition on many samples at once (information form); same result as the loop."""
        H = np.atleast_2d(H)
        R = np.asarray(sigmas, float) ** 2 * np.ones(len(H))
        Pinv = np.linalg.inv(self.P)
        A = Pinv + (H.T / R) @ H
        b = Pinv @ self.m + H.T @ ((np.asarray(ys) - np.asarray(offsets)) / R)
        self.P = np.linalg.inv(A)
        self.P = 0.5 * (self.P + self.P.T)
        self.m = self.P @ b
        self.n_updates += len(H)

    @property
    def mean(self) -> np.ndarray:
        return self.m.copy()

    @property
    def cov(self) -> np.ndarray:
        return self.P.copy()


class ParticleFilter:
    """Particle filter over D coefficients.

    prior_mean (D,), prior_cov (D, D) or prior_std (D,): the Gaussian the N particles are
    drawn from (equal weights). ``resample``: "systematic" (default, as in the CLI and the
    studies: less resampling noise than multinomial, Douc, Cappe & Moulines 2005, and cheaper:
    one uniform draw instead of N) or "multinomial" (the thesis's);
    ``ess_threshold``: resample when ESS < ess_threshold * N (1.0: after every sample, as in
    the thesis); ``jitter``: Liu-West bandwidth h in [0, 1) (0: none); ``move_sweeps``:
    resample-move (Gilks & Berzuini 2001): after each resampling, that many random-walk
    Metropolis-Hastings sweeps (Gaussian proposals with the particles' covariance x
    2.38^2 / D) targeting the posterior given all samples so far, which on this linear model
    needs only sufficient statistics (sum h h^T / sigma^2, sum (y - offset) h / sigma^2), so a
    sweep costs O(N D^2) whatever the number of samples; the remedy for the degeneracy of
    the copies resampling makes (0: none, the thesis's filter); ``rng``: a
    np.random.Generator or a seed; ``backend``: "numba" (float32 kernels, the fast path) or
    "numpy" (float64, straightforward; the benchmark's reference).
    """

    def __init__(self, prior_mean, prior_cov=None, *, prior_std=None, n_particles: int = 5000,
                 resample: str = "systematic", ess_threshold: float = 0.5, jitter: float = 0.1,
                 jitter_floor: float = 0.0, rng: np.random.Generator | int | None = 0,
                 backend: str = "numba", move_sweeps: int = 0):
        m = finite_array("prior mean", prior_mean, ndim=1)
        D = len(m)
        if (prior_cov is None) == (prior_std is None):
            raise InputError("prior", "give exactly one of prior_cov or prior_std")
        if prior_std is not None:
            sd = finite_array("prior std", prior_std, ndim=1)
            if sd.shape != (D,) or (sd < 0).any():
                raise InputError("prior std", f"must be {D} values >= 0")
            L = np.diag(sd)
        else:
            P = finite_array("prior covariance", prior_cov, ndim=2)
            if P.shape != (D, D):
                raise InputError("prior covariance", f"must be {D} x {D}, got {P.shape}")
            w, V = np.linalg.eigh(0.5 * (P + P.T))
            if w.min() < -1e-10 * max(1.0, w.max()):
                raise InputError("prior covariance", "must be positive semi-definite")
            L = V * np.sqrt(np.clip(w, 0, None))
        self.n = N = integer("particles", n_particles, 2)
        self.resample_method = choice("resample", resample, RESAMPLERS)
        self.ess_threshold = in_range("ess-threshold", ess_threshold, 0.0, 1.0)
        self.jitter = in_range("jitter", jitter, 0.0, 0.999)
        floor = in_range("jitter-floor", jitter_floor, 0.0, 1.0)
        self._jfloor = floor * np.sqrt(np.sum(L * L, axis=1))  # prior std per coefficient
        self._has_floor = bool(self._jfloor.any())
        self.backend = choice("backend", backend, BACKENDS)
        self.move_sweeps = integer("move-sweeps", move_sweeps, 0)
        if self.move_sweeps > 100:
            raise InputError("move-sweeps", f"must be an integer in [0, 100], got {move_sweeps!r}")
        if self.move_sweeps:
            self._prior_prec = np.linalg.pinv(L @ L.T)
            self._prior_mean = m.copy()
            self._Qs = np.zeros((D, D))
            self._rs = np.zeros(D)
            self.acceptance: list[float] = []
        self.rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
        z = self.rng.standard_normal((N, D))
        C = m + z @ L.T
        self.ess = float(N)
        self.n_updates = 0
        self.n_resamples = 0
        if self.backend == "numba":
            self.Ct = np.ascontiguousarray(C.T, dtype=np.float32)       # (D, N)
            # Work arrays, allocated once (see the kernels): log-weights, weights, predictions;
            # cumulative weights and sorted uniforms; scatter marks and ancestors.
            self._ws = np.zeros((3, N), np.float32)
            self._ws[1] = 1.0
            self._w64 = np.zeros((2, N + 1))
            self._wi = np.zeros((2, N + 1), np.int32)
            self._out = np.empty_like(self.Ct)
            self._h32 = np.empty(D, np.float32)
            self._seeds = np.empty(0, np.uint32)
            self._k = 0
        else:
            self.C = C                                                   # (N, D)
            self._logw = np.zeros(N)

    @property
    def dim(self) -> int:
        return self.Ct.shape[0] if self.backend == "numba" else self.C.shape[1]

    @property
    def particles(self) -> np.ndarray:
        """(N, D) float64 copy of the particles."""
        return self.Ct.T.astype(float) if self.backend == "numba" else self.C.copy()

    def update(self, h, offset: float, y: float, sigma: float) -> float:
        """Assimilate one sample y (predicted ``h @ c + offset``, noise std ``sigma``, same
        units); resample when the ESS falls below the threshold. Returns the ESS after the
        update, before any resampling."""
        if not sigma > 0:
            raise InputError("sigma", f"observation noise std must be > 0, got {sigma!r}")
        if self.backend == "numba":
            h32 = self._h32
            h32[:] = h
            ess = _nb_update(self.Ct, h32, float(offset), float(y), 0.5 / (sigma * sigma), self._ws)
        else:
            r = y - (self.C @ h + offset)
            lw = self._logw
            lw -= 0.5 * r * r / (sigma * sigma)
            lw -= lw.max()
            w = np.exp(lw)
            ess = float(w.sum() ** 2 / (w * w).sum())
        self.ess = ess
        self.n_updates += 1
        if self.move_sweeps:
            hs = np.asarray(h, float) / sigma
            self._Qs += np.outer(hs, hs)
            self._rs += hs * ((y - offset) / sigma)
        if ess < self.ess_threshold * self.n or self.ess_threshold >= 1.0:
            self.resample()
        return ess

    def resample(self) -> None:
        """Resample now (method and jitter as configured); weights become equal."""
        self.n_resamples += 1
        if self.backend == "numba":
            if self._k >= len(self._seeds):  # seeds drawn in blocks: one Generator call per 1024
                self._seeds = self.rng.integers(0, 2 ** 32, size=1024, dtype=np.uint32)
                self._k = 0
            seed = self._seeds[self._k]
            self._k += 1
            _nb_resample(self.Ct, self._out, self._ws, self._w64, self._wi,
                         self.resample_method == "systematic", seed,
                         max(self.jitter, 1e-12) if self._has_floor else self.jitter, self._jfloor)
            self.ess = float(self.n)
            if self.move_sweeps:
                self.Ct[:] = self._move(self.Ct.T.astype(float)).T
            return
        w = np.exp(self._logw - self._logw.max())
        cw = np.cumsum(w)
        cw /= cw[-1]
        if self.resample_method == "systematic":
            u = (np.arange(self.n) + self.rng.random()) / self.n
        else:
            u = np.sort(self.rng.random(self.n))
        idx = np.minimum(np.searchsorted(cw, u), self.n - 1)
        X = self.C[idx]
        if self.jitter > 0 or self._jfloor.any():
            a = math.sqrt(1 - self.jitter ** 2)
            mu = X.mean(0)
            amp = np.maximum(self.jitter * X.std(0), self._jfloor)
            X = a * X + (1 - a) * mu + amp * self.rng.standard_normal(X.shape)
        self.C = self._move(X) if self.move_sweeps else X
        self._logw[:] = 0.0
        self.ess = float(self.n)

    def _move(self, C: np.ndarray) -> np.ndarray:
        """Metropolis-Hastings sweeps on equally weighted particles C (N, D) targeting
        prior x likelihood of all samples so far (a Gaussian: precision A, shift b)."""
        A = self._prior_prec + self._Qs
        b = self._prior_prec @ self._prior_mean + self._rs
        D = C.shape[1]

        def logt(X):
            return -0.5 * np.einsum("nd,de,ne->n", X, A, X) + X @ b

        cov = np.atleast_2d(np.cov(C.T)) * (2.38 ** 2 / D)
        w, V = np.linalg.eigh(0.5 * (cov + cov.T))
        L = V * np.sqrt(np.clip(w, 1e-30, None))
        lt = logt(C)
        acc = 0
        for _ in range(self.move_sweeps):
            prop = C + self.rng.standard_normal(C.shape) @ L.T
            lp = logt(prop)
            ok = np.log(self.rng.random(len(C))) < lp - lt
            C[ok] = prop[ok]
            lt[ok] = lp[ok]
            acc += int(ok.sum())
        self.acceptance.append(acc / (len(C) * self.move_sweeps))
        return C

    @property
    def logw(self) -> np.ndarray:
        """(N,) log-weights (unnormalised; max 0 after an update for the numpy backend, in
        [-30, 0] for numba's)."""
        return self._ws[0] if self.backend == "numba" else self._logw

    @property
    def weights(self) -> np.ndarray:
        """(N,) normalised weights (float64)."""
        lw = self.logw.astype(float)
        w = np.exp(lw - lw.max())
        return w / w.sum()

    @property
    def mean(self) -> np.ndarray:
        """(D,) weighted mean of the particles."""
        return self.weights @ self.particles

    @property
    def cov(self) -> np.ndarray:
        """(D, D) weighted covariance of the particles."""
        w = self.weights
        C = self.particles
        X = C - w @ C
        return (X.T * w) @ X


def warmup() -> None:
    """Compile (or load from Numba's cache) the particle-filter kernels, for both resamplers."""
    for method in RESAMPLERS:
        pf = ParticleFilter(np.zeros(2), prior_std=np.ones(2), n_particles=16, resample=method, rng=0)
        pf.update(np.ones(2), 0.0, 0.5, 1.0)
        pf.resample()
    ParticleFilter(np.zeros(2), prior_std=np.ones(2), n_particles=16, jitter_floor=0.1).resample()
