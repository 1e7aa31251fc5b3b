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
from numba import njit

from ..errors import InputError, choice, finite, finite_array, in_range, integer, positive

RESAMPLERS = ("multinomial", "systematic")
BACKENDS = ("numba", "numpy")


# ------------------------------------------------------------------------------ kernels
# The Numba kernels keep the particles as float32 structure-of-arrays (D, N) so that every
# loop runs over particles with unit stride and LLVM vectorises it (AVX2: 8 lanes). exp, log
# and the random numbers are written out so they vectorise too (libm calls do not):
#   exp(x) = 2^n 2^f (f in [0, 1), 2^f a degree-6 polynomial, rel. error ~1e-7);
#   log(v) = e ln 2 + log(m) (m in [1, 2), degree-8 polynomial, abs. error ~1e-7);
#   uniforms from an integer hash (lowbias32) of a counter, seeded per call from the
#   caller's np.random.Generator (so runs are reproducible and independent).
def _poly(fn, lo, hi, deg):
    x = 0.5 * (lo + hi) + 0.5 * (hi - lo) * np.cos(np.pi * (np.arange(8 * deg) + 0.5) / (8 * deg))
    return tuple(np.float32(c) for c in np.polyfit(x - lo, fn(x), deg))


_E = _poly(lambda f: 2.0 ** f, 0.0, 1.0, 6)
_L = _poly(np.log, 1.0, 2.0, 8)
_LOG2E = np.float32(1.4426950408889634)
_LN2 = np.float32(0.6931471805599453)


_RENORM = -30.0  # shift the log-weights back to max 0 when their max falls below this


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


# Workspace layout: float32 array of 8 blocks of N + 1 (with an int32 view of it):
# 0 log-weights, 1 predictions, 2 weights, 3 unused, 4-7 scratch for multinomial
# resampling. float64 workspace of 2 N (with an int64 view): cumulative weights [0, N),
# ancestors [N, 2 N) (int view).
@njit(fastmath=True, nogil=True, cache=True)
def _nb_update(Ct, h, off, y, half_inv_var, ws, wsi):  # pragma: no cover - compiled
    """logw += log N(y; h @ C + off, sigma^2); w = exp(logw). The log-weights are shifted
    back to max 0 only when their max drops below _RENORM (the ESS does not depend on the
    shift). Ct (D, N) float32; h (D,) float32. Returns the ESS = (sum w)^2 / sum w^2.
    exp(v) = 2^n 2^f: the polynomial 2^f in [1, 2) goes to the weights, n to the exponent
    bits in a second pass through the int32 view (each loop vectorises)."""
    D, N = Ct.shape
    K = N + 1
    logw = ws[0:N]
    pred = ws[K:K + N]
    wbuf = ws[2 * K:2 * K + N]
    wint = wsi[2 * K:2 * K + N]
    nbuf = wsi[3 * K:3 * K + N]
    o = np.float32(off)
    h0 = h[0]
    for i in range(N):
        pred[i] = o + Ct[0, i] * h0
    for d in range(1, D):
        hd = h[d]
        for i in range(N):
            pred[i] += Ct[d, i] * hd
    m = np.float32(-3.0e38)
    yy = np.float32(y)
    hv = np.float32(half_inv_var)
    for i in range(N):
        r = yy - pred[i]
        v = max(logw[i] - hv * r * r, np.float32(-1.0e30))  # never -inf (float32 overflow)
        logw[i] = v
        m = max(m, v)
    shift = m if m < _RENORM else np.float32(0.0)
    e0, e1, e2, e3, e4, e5, e6 = _E
    for i in range(N):
        v = logw[i] - shift
        logw[i] = v
        t = v * _LOG2E + np.float32(127.0)          # biased exponent, clamped to normals
        t = t if t > np.float32(1.0) else np.float32(1.0)
        n = np.int32(t)                              # t > 0: truncation is floor
        fr = t - np.float32(n)
        wbuf[i] = ((((((e0 * fr + e1) * fr + e2) * fr + e3) * fr + e4) * fr + e5) * fr + e6)
        nbuf[i] = (n - np.int32(127)) << np.int32(23)
    for i in range(N):
        wint[i] += nbuf[i]
    s = 0.0
    s2 = 0.0
    for i in range(N):
        w = np.float64(wbuf[i])
        s += w
        s2 += w * w
    return s * s / s2


@njit(fastmath=True, nogil=True, cache=True)
def _nb_resample(Ct, out, ws, wsi, w64, w64i, systematic, seed, jitter, jfloor):  # pragma: no cover
    """Resample the columns of Ct (D, N) by the weights in the workspace (set by
    _nb_update), jitter them (Liu-West, uniform noise), and reset the log-weights.
    ``seed``: uint32 from the caller's Generator; out (D, N) float32 scratch; jfloor (D,):
    lower bound on the jitter noise std per coefficient (process noise)."""
    D, N = Ct.shape
    K = N + 1
    logw = ws[0:N]
    wbuf = ws[2 * K:2 * K + N]
    vbuf, vint = ws[5 * K:6 * K], wsi[5 * K:6 * K]
    ebuf = ws[6 * K:7 * K]
    mbuf, mint = ws[7 * K:8 * K], wsi[7 * K:8 * K]
    cw = w64[0:N]
    anc = w64i[N:2 * N]
    s = 0.0
    for i in range(N):
        s += wbuf[i]
        cw[i] = s
    j = 0
    if systematic:
        u0 = np.float64(_u01(0, seed))
        step = s / N
        for i in range(N):
            t = (i + u0) * step
            while j < N - 1 and cw[j] < t:
                j += 1
            anc[i] = j
    else:
        # Sorted uniforms as normalised partial sums of N + 1 exponentials: O(N), no sort.
        for i in range(K):
            vbuf[i] = np.float32(1.0) - _u01(i, seed)  # uniform in (0, 1]
        for i in range(K):
            b = vint[i]
            ebuf[i] = np.float32((b >> 23) - 127)
            mint[i] = (b & np.int32(0x007FFFFF)) | np.int32(0x3F800000)
        l0, l1, l2, l3, l4, l5, l6, l7, l8 = _L
        tot = 0.0
        for i in range(K):
            x = mbuf[i] - np.float32(1.0)
            lg = ((((((((l0 * x + l1) * x + l2) * x + l3) * x + l4) * x + l5) * x + l6) * x + l7) * x + l8)
            e = -(ebuf[i] * _LN2 + lg)  # an Exp(1) sample
            vbuf[i] = e
            tot += e
        scale = s / tot
        acc = 0.0
        for i in range(N):
            acc += vbuf[i]
            t = acc * scale
            while j < N - 1 and cw[j] < t:
                j += 1
            anc[i] = j
    for d in range(D):
        for i in range(N):
            out[d, i] = Ct[d, anc[i]]
    if jitter > 0.0:
        a = np.float32(math.sqrt(1.0 - jitter * jitter))
        for d in range(D):
            x0 = out[d, 0]
            s1 = 0.0
            sq = 0.0
            for i in range(N):
                x = np.float64(out[d, i] - x0)  # shifted sums: no cancellation
                s1 += x
                sq += x * x
            mu = s1 / N
            var = max(sq / N - mu * mu, 0.0)
            # u uniform in [0, 1): mean 1/2, variance 1/12.
            amp = np.float32(max(jitter * math.sqrt(var), jfloor[d]) * math.sqrt(12.0))
            c0 = np.float32((1.0 - a) * (mu + x0)) - amp * np.float32(0.5)
            sd = np.uint32(seed + np.uint32(np.uint32(d + 1) * np.uint32(0x9E3779B9)))
            for i in range(N):
                Ct[d, i] = a * out[d, i] + c0 + amp * _u01(i, sd)
    else:
        for d in range(D):
            for i in range(N):
                Ct[d, i] = out[d, i]
    for i in range(N):
        logw[i] = 0.0
        wbuf[i] = 1.0


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
    drawn from (equal weights). ``resample``: "multinomial" (thesis) or "systematic";
    ``ess_threshold``: resample when ESS < ess_threshold * N (1.0: after every sample, as in
    the thesis); ``jitter``: Liu-West bandwidth h in [0, 1) (0: none); ``rng``: a
    np.random.Generator or a seed; ``backend``: "numba" (float32 kernels, the fast path) or
    "numpy" (float64, straightforward; the benchmark's reference).
    """

    def __init__(self, prior_mean, prior_cov=None, *, prior_std=None, n_particles: int = 5000,
                 resample: str = "multinomial", ess_threshold: float = 0.5, jitter: float = 0.1,
                 jitter_floor: float = 0.0, rng: np.random.Generator | int | None = 0,
                 backend: str = "numba"):
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
        self.backend = choice("backend", backend, BACKENDS)
        self.rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
        z = self.rng.standard_normal((N, D))
        C = m + z @ L.T
        self.ess = float(N)
        self.n_updates = 0
        self.n_resamples = 0
        if self.backend == "numba":
            self.Ct = np.ascontiguousarray(C.T, dtype=np.float32)       # (D, N)
            self._ws = np.zeros(8 * (N + 1), np.float32)
            self._wsi = self._ws.view(np.int32)
            self._ws[2 * (N + 1):3 * (N + 1)] = 1.0
            self._w64 = np.zeros(2 * N)
            self._w64i = self._w64.view(np.int64)
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
            ess = _nb_update(self.Ct, h32, offset, y, 0.5 / (sigma * sigma), self._ws, self._wsi)
        else:
            r = y - (self.C @ h + offset)
            lw = self._logw
            lw -= 0.5 * r * r / (sigma * sigma)
            lw -= lw.max()
            w = np.exp(lw)
            ess = float(w.sum() ** 2 / (w * w).sum())
        self.ess = ess
        self.n_updates += 1
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
            _nb_resample(self.Ct, self._out, self._ws, self._wsi, self._w64, self._w64i,
                         self.resample_method == "systematic", seed, max(self.jitter, 1e-12)
                         if self._jfloor.any() else self.jitter, self._jfloor)
            self.ess = float(self.n)
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
        self.C = X
        self._logw[:] = 0.0
        self.ess = float(self.n)

    @property
    def logw(self) -> np.ndarray:
        """(N,) log-weights (unnormalised; max 0 after an update)."""
        return self._ws[: self.n] if self.backend == "numba" else self._logw

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
