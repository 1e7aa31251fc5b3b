"""Terrain identification and stance forecasting: the unknown condition in the filter's state.

The device does not know the medium it steps on (which of Li 2013's five, and how strong:
a factor ``k`` on its stress coefficients, so zeta = k x zeta_medium), nor its hip height
or sinkage, nor (for a foot) the wearer's foot length. :class:`TerrainModel` holds one
HOSVD + GP :class:`~terradyn.dddas.surrogate.Surrogate` per medium over the continuous
conditions (trained on RFT sweeps generated in-process by :func:`training_stack`; any
other stack with the same coordinates, e.g. SPH, fits the same way). :class:`TerrainFilter`
is a particle filter whose particles are the *conditions* (medium m, continuous conditions
u), not the basis coefficients:

* **Rao-Blackwellisation** (Doucet, de Freitas, Murphy & Russell 2000; Chen & Liu 2000):
  given (m, u), every channel is linear in the strength factor k and in the channel's
  sensor bias b: ``y = k g_m(theta; u) + b + e``, where g is the surrogate's force (its GP
  mean at u; the truncation error of the basis is added to the sensor noise). With Gaussian
  priors on k and the biases these are marginalised exactly; each particle carries running
  sums (sum w g^2, sum w g, sum w g y per channel) and its log marginal likelihood is a
  closed form (an arrowhead linear system of size 1 + channels).
* **Resample-move** (Gilks & Berzuini 2001, JRSS B 63:127) for static parameters, as in
  IBIS (Chopin 2002, Biometrika 89:539): after each resampling a random-walk
  Metropolis-Hastings sweep over (m, u) targets the posterior given *all* samples so far.
  Because g is linear in the surrogate's coefficients z = [c(u), 1], that full-history
  likelihood needs only sufficient statistics per medium and channel (sum w a a^T,
  sum w a, sum w y a over the observation rows a), so a move costs O(channels x D^2) per
  particle whatever the number of samples. Without the move the copies made by resampling
  stay identical (the parameters are static) and the filter degenerates. The move runs over
  runs of equal medium with branch-free loops (medium jumps by a random reflection of the
  media, an involution, so the Metropolis ratio needs no proposal correction; Tierney 1998,
  Ann. Appl. Probab. 8:1); with one condition a proposal's k posterior is an exact per-cell
  quadratic in its position in the table (O(1) per particle).

The hot loops are Numba kernels (float64). Components are read from :data:`COMPONENTS`
only, so the list can follow a force schema.
"""
from __future__ import annotations

from .._jitcache import bind_to_sources as _bind_cache

import math
from dataclasses import dataclass, field
from typing import Iterable, Sequence

import numpy as np
import xarray as xr
from numba import njit

from ..errors import InputError, choice, finite, in_range, integer, positive
from ..media import FITS, ZETA
from .filter import _exp_neg, _log01, _u01
from .surrogate import Surrogate

#: Kernels of the Metropolis-Hastings move (see :class:`TerrainFilter`).
MOVE_KERNELS = ("vector", "per-particle")
#: Li 2013's five media (Table S2).
MEDIA = ("poppy LP", "poppy CP", "0.3 mm glass LP", "0.3 mm glass CP", "3 mm glass CP")
#: Force components the terrain surrogates model (one list: switch here to a schema's).
COMPONENTS = ("Fx", "Fz", "torque")
COMPONENT_UNITS = {"Fx": "N", "Fz": "N", "torque": "N m"}
#: Leg kinds and their default conditions (name -> training values); the stroke is the
#: stance: theta -90..90 deg for the legs (horizontal to horizontal), 0..3 deg for the foot.
LEG_KINDS = ("flat", "c", "reverse-c", "foot")


def default_conditions(leg: str) -> dict[str, np.ndarray]:
    """Training values of the conditions a device does not know, per leg kind: hip height
    (cm) for the standard legs; foot length (cm) and ankle sinkage (cm) for the foot."""
    choice("leg", leg, LEG_KINDS)
    if leg == "foot":
        return {"length_cm": np.linspace(25.0, 35.0, 6), "sinkage_cm": np.linspace(0.0, 1.0, 5)}
    return {"hip_height_cm": np.linspace(1.0, 3.25, 10)}


def _motion(leg: str, cond: dict, n_theta: int):
    from ..motion import Rotation
    from ..units import CM, DEG

    if leg == "foot":
        return Rotation(0.2, -cond["sinkage_cm"] * CM, 0.0, 3.0 * DEG, n_theta)
    return Rotation(0.2, cond["hip_height_cm"] * CM, -90 * DEG, 90 * DEG, n_theta)


def default_n_theta(leg: str) -> int:
    return 61 if leg == "foot" else 181


def rft_forces(leg: str, medium: str, cond: dict, k: float = 1.0, n_theta: int | None = None) -> xr.Dataset:
    """Noise-free RFT force series of ``leg`` in ``medium`` (coefficients x ``k``) at the
    condition ``cond`` (cm), over the stance stroke: the truth of the studies."""
    from .. import geometry, rft
    from ..units import CM

    n_theta = n_theta or default_n_theta(leg)
    model = FITS[choice("medium", medium, MEDIA)].scaled(positive("k", k))
    if leg == "foot":
        shape = geometry.foot(positive("length_cm", cond["length_cm"], "cm") * CM)
    else:
        shape = geometry.make_leg(leg)
    return rft.simulate(shape, _motion(leg, cond, n_theta), model, medium=medium)


def training_stack(leg: str, medium: str, conditions: dict | None = None, n_theta: int | None = None) -> xr.Dataset:
    """RFT sweep of ``leg`` in ``medium`` over the grid of ``conditions`` (name -> values, cm;
    default :func:`default_conditions`): a stack along ``case`` with one coordinate per name."""
    from .. import geometry, rft
    from ..series import stack
    from ..units import CM

    conds = default_conditions(leg) if conditions is None else {k: np.asarray(v, float) for k, v in conditions.items()}
    n_theta = n_theta or default_n_theta(leg)
    model = FITS[choice("medium", medium, MEDIA)]
    names = list(conds)
    grid = np.stack(np.meshgrid(*[conds[n] for n in names], indexing="ij"), -1).reshape(-1, len(names))
    series = []
    if leg == "foot":
        il, isk = names.index("length_cm"), names.index("sinkage_cm")
        for s in np.unique(grid[:, isk]):
            rows = grid[grid[:, isk] == s]
            legs = [geometry.foot(L * CM) for L in rows[:, il]]
            st = rft.simulate_many(legs, _motion(leg, {"sinkage_cm": s}, n_theta), model, medium=medium)
            for j in range(len(rows)):
                series.append((rows[j], st.isel(case=j)))
    else:
        shape = geometry.make_leg(leg)
        for row in grid:
            series.append((row, rft.simulate(shape, _motion(leg, dict(zip(names, row)), n_theta), model,
                                             medium=medium)))
    X = np.array([r for r, _ in series])
    ds = stack([s.drop_vars([v for v in s.coords if v not in s.dims and v != "time"], errors="ignore")
                for _, s in series], {n: X[:, k] for k, n in enumerate(names)})
    ds.attrs.update(model="rft", medium=medium, leg=leg,
                    dddas_note=f"RFT sweep of the {leg} leg in {medium} over {names}")
    return ds


# ------------------------------------------------------------------------------ channels
@dataclass(frozen=True)
class Channel:
    """One sensor: a linear combination of force components (``weights``: component ->
    factor) with its own noise std ``noise`` and a bias (offset) prior std ``bias_std``, both
    in the channel's units. ``Channel.load_cell(lever_arm_m)`` reads torque / lever arm (N)."""

    name: str
    weights: dict = field(default_factory=dict)
    noise: float = 0.1
    bias_std: float = 0.0
    units: str = "N"

    def __post_init__(self):
        if not self.weights:
            object.__setattr__(self, "weights", {self.name: 1.0})
        for c, v in self.weights.items():
            choice(f"channel {self.name}", c, COMPONENTS)
            finite(f"channel {self.name} weight", v)
        positive(f"noise of {self.name}", self.noise, self.units)
        s = finite(f"bias-std of {self.name}", self.bias_std, self.units)
        if s < 0:
            raise InputError(f"bias-std of {self.name}", f"must be >= 0 {self.units}, got {s!r}")

    @classmethod
    def load_cell(cls, lever_arm_m: float, noise: float = 0.1, bias_std: float = 0.0) -> "Channel":
        arm = positive("lever-arm", lever_arm_m, "m")
        return cls("load_cell", {"torque": 1.0 / arm}, noise, bias_std, "N")

    def of(self, forces: dict) -> np.ndarray:
        """The channel's reading from component arrays (no noise, no bias)."""
        return sum(w * np.asarray(forces[c], float) for c, w in self.weights.items())


# ------------------------------------------------------------------------------ the model
class TerrainModel:
    """Per-medium surrogates over continuous conditions, tabulated for the filter.

    ``surrogates``: medium -> fitted :class:`Surrogate` with the same inputs, components
    :data:`COMPONENTS` and motion grid; ``bounds`` (name -> (lo, hi)) is the prior box of the
    conditions (default: the training range); ``table_points``: points per input of the grid
    the GP means are tabulated on (bilinear interpolation in between)."""

    def __init__(self, surrogates: dict, leg: str = "", bounds: dict | None = None, table_points: int = 41):
        if not surrogates:
            raise InputError("surrogates", "need at least one medium")
        self.media = list(surrogates)
        self.surrogates = [surrogates[m] for m in self.media]
        s0 = self.surrogates[0]
        self.inputs = list(s0.input_names_)
        if len(self.inputs) not in (1, 2):
            raise InputError("inputs", f"the terrain filter takes 1 or 2 continuous conditions, got {self.inputs}")
        for m, s in zip(self.media, self.surrogates):
            if s.input_names_ != self.inputs or list(s.components_) != list(COMPONENTS) \
                    or not np.array_equal(s.coord_values_, s0.coord_values_):
                raise InputError("surrogates", f"{m}: inputs, components and motion grid must match the others")
        self.leg = leg
        self.theta = s0.coord_values_
        X = np.concatenate([s.X_train_ for s in self.surrogates])
        lo, hi = X.min(0), X.max(0)
        if bounds:
            lo = np.array([bounds[n][0] for n in self.inputs], float)
            hi = np.array([bounds[n][1] for n in self.inputs], float)
        if (hi <= lo).any():
            raise InputError("bounds", "each condition needs lo < hi")
        self.lo, self.hi = lo, hi
        self.D = max(s.basis_.shape[0] for s in self.surrogates)
        self.P = self.D + 1
        G = integer("table-points", table_points, 2)
        self.grid = [np.linspace(lo[j], hi[j], G) for j in range(len(self.inputs))]
        G2 = G if len(self.inputs) == 2 else 1
        M = len(self.media)
        T = np.zeros((M, G, G2, self.P))
        mesh = np.stack(np.meshgrid(*self.grid, indexing="ij"), -1).reshape(-1, len(self.inputs))
        for i, s in enumerate(self.surrogates):
            mu, _ = s.predict_coefficients(mesh)
            d = mu.shape[1]
            T[i, :, :, :d] = mu.reshape(G, G2, d)
            T[i, :, :, -1] = 1.0
        self.table = T
        # rows per medium, component: A[m, c] (S, P) with forces = A @ [c, 1]; residual (S,)
        S = len(self.theta)
        self.A = np.zeros((M, len(COMPONENTS), S, self.P))
        self.res = np.zeros((M, len(COMPONENTS), S))
        for i, s in enumerate(self.surrogates):
            d = s.basis_.shape[0]
            for j, c in enumerate(COMPONENTS):
                H, off, err = s.observation_rows(self.theta, c, with_error=True)
                self.A[i, j, :, :d] = H
                self.A[i, j, :, -1] = off
                self.res[i, j] = err

    @classmethod
    def from_rft(cls, leg: str = "flat", media: Sequence[str] = MEDIA, conditions: dict | None = None,
                 n_theta: int | None = None, energy: float = 0.9999, table_points: int = 41,
                 seed: int = 0) -> "TerrainModel":
        """Train one surrogate per medium on an RFT sweep (:func:`training_stack`).

        ``energy``: the cumulative explained variance kept in the condition mode. 0.9999 (one
        more basis function than 0.999 for the flat and C legs): at 0.999 the truncation error,
        smooth along the stroke and so not covered by the per-sample representation-error
        std, biased the posterior (zeta 95 % intervals covered 72 % / 82 % on the flat / C
        legs at 30 % of the stroke, 88 % / 92 % at 0.9999, and the flat leg's medium was found
        in 93 % of trials, 96 % at 0.9999): ``benchmarks/dddas_model_discrepancy.py``."""
        choice("leg", leg, LEG_KINDS)
        for m in media:
            choice("medium", m, MEDIA)
        surs = {}
        for m in media:
            ds = training_stack(leg, m, conditions, n_theta)
            names = list(default_conditions(leg) if conditions is None else conditions)
            surs[m] = Surrogate(inputs=names, components=COMPONENTS,
                                energy=energy, n_restarts=0, random_state=seed).fit(ds)
        return cls(surs, leg, table_points=table_points)

    # -------------------------------------------------------------- helpers
    def unit(self, cond) -> np.ndarray:
        """Condition(s) (dict or (m, q) array, field units) -> box coordinates in [0, 1]^q."""
        X = np.atleast_2d(np.array([[cond[n] for n in self.inputs]], float) if isinstance(cond, dict) else cond)
        return (X - self.lo) / (self.hi - self.lo)

    def coefficients(self, m: int, u: np.ndarray) -> np.ndarray:
        """Tabulated z = [c, 1] (P,) of medium index m at box coordinates u (q,)."""
        out = np.empty(self.P)
        _interp_table(self.table[m], float(u[0]), float(u[1]) if len(u) > 1 else 0.0, out)
        return out

    def forces(self, m: int, cond, k: float = 1.0) -> np.ndarray:
        """Surrogate forces (S, C) of medium index m at ``cond`` x k."""
        z = self.coefficients(m, self.unit(cond)[0])
        return k * np.einsum("csp,p->sc", self.A[m], z)

    def channel_rows(self, ch: Channel) -> tuple[np.ndarray, np.ndarray]:
        """(M, S, P) rows and (M, S) representation-error std of a channel."""
        A = np.zeros(self.A.shape[:1] + self.A.shape[2:])
        v = np.zeros(self.res.shape[:1] + self.res.shape[2:])
        for c, w in ch.weights.items():
            j = COMPONENTS.index(c)
            A += w * self.A[:, j]
            v += (w * self.res[:, j]) ** 2
        return A, np.sqrt(v)

    @property
    def zeta(self) -> np.ndarray:
        return np.array([ZETA[m] for m in self.media])


# ------------------------------------------------------------------------------ kernels
#: LLVM fast-math flags without nnan / ninf: the kernels test for NaN (missing channels) and
#: start maxima at -inf, which full fast-math may fold away.
_FAST = {"nsz", "arcp", "contract", "afn", "reassoc"}
# Per-particle arrays: mi (N,) medium index; U (N, q) conditions in box units; Zt (P, N)
# tabulated coefficients [c, 1]; S (3, nch, N) running sums sum w g^2, sum w g, sum w g y
# per channel; logml (N,) log marginal likelihood; ref (N,) its value at the last
# resampling (weights = exp(logml - ref)); kpost (2, N) posterior mean and variance of k.
# Per-medium statistics: n1, y1 (M, nch) sums of w and w y; yy, logc (M,) sum of w y^2 and
# of -log(2 pi sigma^2) / 2; Q (M, nch, P, P), q1, r (M, nch, P) sums of w a a^T, w a, w y a
# over the observation rows a; derived (M, 2 nch + 1): 1/d_ch, y1_ch/d_ch (d_ch = bias
# precision + n1_ch) and the particle-independent part of the log marginal likelihood.
@njit(cache=True, inline="always")
def _interp_table(T, u0, u1, out):  # pragma: no cover - compiled
    G1, G2, P = T.shape
    x = min(max(u0, 0.0), 1.0) * (G1 - 1)
    i0 = min(int(x), G1 - 2) if G1 > 1 else 0
    f0 = x - i0
    if G2 > 1:
        y = min(max(u1, 0.0), 1.0) * (G2 - 1)
        j0 = min(int(y), G2 - 2)
        f1 = y - j0
        for p in range(P):
            out[p] = ((1 - f0) * ((1 - f1) * T[i0, j0, p] + f1 * T[i0, j0 + 1, p])
                      + f0 * ((1 - f1) * T[i0 + 1, j0, p] + f1 * T[i0 + 1, j0 + 1, p]))
    else:
        for p in range(P):
            out[p] = (1 - f0) * T[i0, 0, p] + f0 * T[i0 + 1, 0, p]


@njit(cache=True, inline="always")
def _interp_into(T, m, u0, u1, out, i):  # pragma: no cover - compiled
    """out[i, :] = the bilinear interpolation of T[m] (G1, G2, P) at (u0, u1) in [0, 1]^2
    (no array views: used per particle in the move)."""
    G1, G2, P = T.shape[1], T.shape[2], T.shape[3]
    x = min(max(u0, 0.0), 1.0) * (G1 - 1)
    i0 = min(int(x), G1 - 2)
    f0 = x - i0
    if G2 > 1:
        y = min(max(u1, 0.0), 1.0) * (G2 - 1)
        j0 = min(int(y), G2 - 2)
        f1 = y - j0
        w00 = (1 - f0) * (1 - f1)
        w01 = (1 - f0) * f1
        w10 = f0 * (1 - f1)
        w11 = f0 * f1
        for p in range(P):
            out[i, p] = (w00 * T[m, i0, j0, p] + w01 * T[m, i0, j0 + 1, p]
                         + w10 * T[m, i0 + 1, j0, p] + w11 * T[m, i0 + 1, j0 + 1, p])
    else:
        for p in range(P):
            out[i, p] = (1 - f0) * T[m, i0, 0, p] + f0 * T[m, i0 + 1, 0, p]


@njit(cache=True)
def _nb_table(T, mi, U, Z):  # pragma: no cover - compiled
    q = U.shape[1]
    for i in range(mi.shape[0]):
        _interp_table(T[mi[i]], U[i, 0], U[i, 1] if q > 1 else 0.0, Z[i])


@njit(cache=True, inline="always")
def _derive(n1, y1, yy, logc, pk, mk, pb, der):  # pragma: no cover - compiled
    """Particle-independent parts of the log marginal likelihood, per medium."""
    M, nch = n1.shape
    for m in range(M):
        c0 = logc[m] - 0.5 * yy[m] - 0.5 * pk * mk * mk
        for c in range(nch):
            d = pb[c] + n1[m, c]
            der[m, c] = 1.0 / d
            der[m, nch + c] = y1[m, c] / d
            c0 += 0.5 * y1[m, c] * y1[m, c] / d - 0.5 * math.log(d / pb[c])
        der[m, 2 * nch] = c0


@njit(cache=True, fastmath=_FAST, inline="always")
def _finish(lmp, ar, logml, ref):  # pragma: no cover - compiled
    """logml = lmp - log(ar) / 2 (ar >= 1; float32 polynomial log, vectorised), then the ESS
    of exp(logml - ref) (float32 polynomial exp). Separate loops so that each vectorises."""
    N = logml.shape[0]
    for i in range(N):
        v = np.float32(1.0) / np.float32(min(ar[i], 1e30))
        logml[i] = lmp[i] + 0.5 * np.float64(_log01(v))
    lw_max = -np.inf
    for i in range(N):
        lw_max = max(lw_max, logml[i] - ref[i])
    sw = np.float32(0.0)
    sw2 = np.float32(0.0)
    for i in range(N):
        w = _exp_neg(np.float32(logml[i] - ref[i] - lw_max))
        sw += w
        sw2 += w * w
    return np.float64(sw) * np.float64(sw) / np.float64(sw2)


@njit(cache=True, fastmath=_FAST)
def _block(m, obs, no, ys, rows, wts, Zt, S, der, pk, mk, kpost, lmp, ar):  # pragma: no cover - compiled
    """The particle loops of :func:`_nb_assimilate` over one run of medium m (views, so the
    loops start at 0 and vectorise)."""
    n = ar.shape[0]
    nch = S.shape[1]
    P = Zt.shape[0]
    g = kpost[0]
    for i in range(n):
        ar[i] = pk
        lmp[i] = pk * mk
    for o in range(no):
        c = obs[o]
        y = ys[c]
        w = wts[o, m]
        r0 = rows[o, m, 0]
        for i in range(n):
            g[i] = r0 * Zt[0, i]
        for p in range(1, P):
            rp = rows[o, m, p]
            for i in range(n):
                g[i] += rp * Zt[p, i]
        S0 = S[0, c]
        S1 = S[1, c]
        S2 = S[2, c]
        for i in range(n):
            wg = w * g[i]
            S0[i] += wg * g[i]
            S1[i] += wg
            S2[i] += wg * y
    for c in range(nch):
        dc = der[m, c]
        yc = der[m, nch + c]
        S0 = S[0, c]
        S1 = S[1, c]
        S2 = S[2, c]
        for i in range(n):
            s1 = S1[i]
            ar[i] += S0[i] - s1 * s1 * dc
            lmp[i] += S2[i] - s1 * yc
    c0 = der[m, 2 * nch]
    kv = kpost[1]
    for i in range(n):
        a = ar[i]
        ek = lmp[i]
        xk = ek / a
        g[i] = xk
        kv[i] = 1.0 / a
        lmp[i] = c0 + 0.5 * ek * xk
        ar[i] = a / pk


@njit(cache=True, inline="always")
def _run_end(mi, s):  # pragma: no cover - compiled
    """End (exclusive) of the run of equal medium that starts at s."""
    e = s + 1
    while e < mi.shape[0] and mi[e] == mi[s]:
        e += 1
    return e


@njit(cache=True, fastmath=_FAST)
def _nb_assimilate(k0, f, ys, noise2, R, RES2, Q, q1, r, n1, y1, yy, logc, der, pk, mk, pb,
                   mi, Zt, S, logml, ref, kpost, rows, wts, buf2):  # pragma: no cover - compiled
    """One sample, all channels (ys (nch,), NaN = missing) at fraction f between grid points
    k0 and k0 + 1: update the statistics, then every particle's running sums, log marginal
    likelihood and k posterior. Zt (P, N): the particles' coefficients; rows (nch, M, P),
    wts (nch, M) and buf2 (2, N) are scratch. Particles are processed in runs of equal
    medium (kept sorted by medium, so the loops over a run vectorise). Returns the ESS of
    the weights exp(logml - ref) (-1 if nothing was observed)."""
    nch, M, _, P = R.shape
    N = mi.shape[0]
    obs = np.empty(nch, np.int64)
    no = 0
    for c in range(nch):
        if ys[c] == ys[c]:
            obs[no] = c
            no += 1
    if no == 0:
        return -1.0
    for o in range(no):
        c = obs[o]
        y = ys[c]
        for m in range(M):
            w = 1.0 / (noise2[c] + (1 - f) * RES2[c, m, k0] + f * RES2[c, m, k0 + 1])
            wts[o, m] = w
            for p in range(P):
                rows[o, m, p] = (1 - f) * R[c, m, k0, p] + f * R[c, m, k0 + 1, p]
            n1[m, c] += w
            y1[m, c] += w * y
            yy[m] += w * y * y
            logc[m] += 0.5 * math.log(w / (2 * math.pi))
            for p in range(P):
                ap = w * rows[o, m, p]
                q1[m, c, p] += ap
                r[m, c, p] += ap * y
                for p2 in range(P):
                    Q[m, c, p, p2] += ap * rows[o, m, p2]
    _derive(n1, y1, yy, logc, pk, mk, pb, der)
    lmp = buf2[0]
    ar = buf2[1]
    s = 0
    while s < N:
        m = mi[s]
        e = _run_end(mi, s)
        _block(m, obs, no, ys, rows, wts, Zt[:, s:e], S[:, :, s:e], der, pk, mk, kpost[:, s:e], lmp[s:e], ar[s:e])
        s = e
    return _finish(lmp, ar, logml, ref)


@njit(cache=True)
def _gather(idx, src, dst):  # pragma: no cover - compiled
    """dst = every per-particle array of src reordered by idx (N,): src and dst are tuples
    (mi, U, Zt, S, logml, kpost) of distinct arrays (the caller swaps them afterwards, so each
    element is moved once)."""
    mi, U, Zt, S, logml, kpost = src
    mi2, U2, Zt2, S2, logml2, kpost2 = dst
    N = mi.shape[0]
    for i in range(N):
        j = idx[i]
        mi2[i] = mi[j]
        logml2[i] = logml[j]
        kpost2[0, i] = kpost[0, j]
        kpost2[1, i] = kpost[1, j]
    for j in range(U.shape[1]):
        for i in range(N):
            U2[i, j] = U[idx[i], j]
    for p in range(Zt.shape[0]):
        for i in range(N):
            Zt2[p, i] = Zt[p, idx[i]]
    for k in range(3):
        for c in range(S.shape[1]):
            for i in range(N):
                S2[k, c, i] = S[k, c, idx[i]]


@njit(cache=True)
def _nb_runs(mi):  # pragma: no cover - compiled
    """Number of runs of equal medium."""
    n = 1
    for i in range(1, mi.shape[0]):
        n += mi[i] != mi[i - 1]
    return n


@njit(cache=True)
def _nb_sort(src, dst, idx, M):  # pragma: no cover - compiled
    """Stable counting sort of the particles by medium (keeps the runs long): src -> dst."""
    mi = src[0]
    N = mi.shape[0]
    cnt = np.zeros(M + 1, np.int64)
    for i in range(N):
        cnt[mi[i] + 1] += 1
    for m in range(M):
        cnt[m + 1] += cnt[m]
    for i in range(N):
        m = mi[i]
        idx[cnt[m]] = i
        cnt[m] += 1
    _gather(idx, src, dst)


@njit(cache=True)
def _nb_step(U, step_max, out):  # pragma: no cover - compiled
    """out = clip(1.5 x the particles' std of each condition, 1e-3, step_max)."""
    N, q = U.shape
    for j in range(q):
        s = 0.0
        for i in range(N):
            s += U[i, j]
        mu = s / N
        v = 0.0
        for i in range(N):
            d = U[i, j] - mu
            v += d * d
        out[j] = min(max(1.5 * math.sqrt(v / N), 1e-3), step_max[j])


@njit(cache=True)
def _nb_seed(seed):  # pragma: no cover - compiled
    np.random.seed(seed)


@njit(cache=True)
def _nb_resample(src, dst, ref, idx, buf):  # pragma: no cover - compiled
    """Systematic resampling of every per-particle array by the weights exp(logml - ref)
    (ancestors in order, so particles sorted by medium stay sorted), src -> dst (tuples
    (mi, U, Zt, S, logml, kpost)); idx (N,) int64 and buf (N,) float64 scratch. Afterwards
    ref = the new logml (equal weights)."""
    logml = src[4]
    N = logml.shape[0]
    lw_max = -np.inf
    for i in range(N):
        lw_max = max(lw_max, logml[i] - ref[i])
    tot = 0.0
    for i in range(N):
        tot += math.exp(logml[i] - ref[i] - lw_max)
        buf[i] = tot
    u0 = np.random.random()
    j = 0
    for i in range(N):
        t = (i + u0) * tot / N
        while j < N - 1 and buf[j] < t:
            j += 1
        idx[i] = j
    _gather(idx, src, dst)
    new = dst[4]
    for i in range(N):
        ref[i] = new[i]


@njit(cache=True, inline="always")
def _take(i, lmp, logml, kp, kpost):  # pragma: no cover - compiled
    """Particle i takes its accepted proposal's log marginal likelihood and k posterior."""
    logml[i] = lmp[i]
    kpost[0, i] = kp[0, i]
    kpost[1, i] = kp[1, i]


@njit(cache=True)
def _effective(Q, q1, r, der, qe, re):  # pragma: no cover - compiled
    """All channels in one quadratic form: with the biases integrated out, the k posterior of
    coefficients z has precision pk + z qe z and precision x mean pk mk + re . z, where per
    medium qe = sum_c (Q_c - q1_c q1_c^T / d_c) and re = sum_c (r_c - q1_c y1_c / d_c)
    (der as in :func:`_derive`)."""
    M, nch, P, _ = Q.shape
    for m in range(M):
        for p in range(P):
            re[m, p] = 0.0
            for p2 in range(P):
                qe[m, p, p2] = 0.0
        for c in range(nch):
            d = der[m, c]
            y = der[m, nch + c]
            for p in range(P):
                re[m, p] += r[m, c, p] - y * q1[m, c, p]
                for p2 in range(P):
                    qe[m, p, p2] += Q[m, c, p, p2] - d * q1[m, c, p] * q1[m, c, p2]


@njit(cache=True, fastmath=_FAST)
def _nb_move_per_particle(mi, U, Zt, S, logml, ref, kpost, tables, Q, q1, r, der, pk, mk, step, p_jump, seed,
                          mp, Up, Zp, Sp, kp, buf2, acc):  # pragma: no cover - compiled
    """The previous move kernel (``move_kernel="per-particle"``, kept as the reference the
    benchmark compares with): one particle at a time, scalar. One random-walk Metropolis-Hastings sweep on (medium, u in [0, 1]^q) targeting the
    posterior given all samples so far (uniform prior on the box and the media): proposals
    move u by a uniform step of std ``step`` per input and, with probability p_jump, switch to
    another medium (uniform, symmetric); random numbers from the counter hash seeded by
    ``seed``. The full-history likelihood comes from the sufficient statistics Q (M, nch, P,
    P), q1 and r (M, nch, P). mp, Up, Zp, Sp, kp, buf2, acc: scratch for the proposals.
    Returns the acceptance rate; the weights become equal (ref = logml)."""
    N, q = U.shape
    M = tables.shape[0]
    nch = S.shape[1]
    P = Zt.shape[0]
    lmp = buf2[0]
    ar = buf2[1]
    amp = np.empty(q)
    for j in range(q):
        amp[j] = step[j] * math.sqrt(12.0)
    for i in range(N):
        base = np.uint32(i * 4)
        m = mi[i]
        mn = m
        if M > 1 and p_jump > 0.0 and _u01(base, seed) < p_jump:
            mn = min(int(_u01(base + np.uint32(1), seed) * (M - 1)), M - 2)
            if mn >= m:
                mn += 1
        mp[i] = mn
        ok = True
        for j in range(q):
            v = U[i, j] + amp[j] * (np.float64(_u01(base + np.uint32(2 + j), seed)) - 0.5)
            Up[i, j] = v
            if v < 0.0 or v > 1.0:
                ok = False
        if not ok:
            ar[i] = -1.0
            continue
        _interp_into(tables, mn, Up[i, 0], Up[i, 1] if q > 1 else 0.0, Zp, i)
        a = pk
        ek = pk * mk
        for c in range(nch):
            s0 = 0.0
            s1 = 0.0
            s2 = 0.0
            for p in range(P):
                zp = Zp[i, p]
                qz = 0.0
                for p2 in range(P):
                    qz += Q[mn, c, p, p2] * Zp[i, p2]
                s0 += zp * qz
                s1 += q1[mn, c, p] * zp
                s2 += r[mn, c, p] * zp
            Sp[0, c, i] = s0
            Sp[1, c, i] = s1
            Sp[2, c, i] = s2
            a += s0 - s1 * s1 * der[mn, c]
            ek += s2 - s1 * der[mn, nch + c]
        xk = ek / a
        lmp[i] = der[mn, 2 * nch] + 0.5 * ek * xk
        ar[i] = a / pk
        kp[0, i] = xk
        kp[1, i] = 1.0 / a
    seed2 = np.uint32(seed ^ np.uint32(0x5BD1E995))
    for i in range(N):
        v = np.float32(1.0) / np.float32(max(ar[i], 1.0))
        v = v if v > np.float32(1e-30) else np.float32(1e-30)
        lm = lmp[i] + 0.5 * np.float64(_log01(v))
        lmp[i] = lm
        d = np.float32(min(max(lm - logml[i], -80.0), 0.0))
        u = _u01(np.uint32(i), seed2)
        acc[i] = 1 if (ar[i] >= 1.0 and u < _exp_neg(d)) else 0
    n_acc = 0
    for i in range(N):
        if acc[i]:
            n_acc += 1
            mi[i] = mp[i]
            for j in range(q):
                U[i, j] = Up[i, j]
            for p in range(P):
                Zt[p, i] = Zp[i, p]
            for c in range(nch):
                for k in range(3):
                    S[k, c, i] = Sp[k, c, i]
            _take(i, lmp, logml, kp, kpost)
    for i in range(N):
        ref[i] = logml[i]
    return n_acc / N


@njit(cache=True, fastmath=_FAST)
def _node_stats(tables, Q, q1, r, der, pk, mk, nodes, cq):  # pragma: no cover - compiled
    """One condition (tables (M, G, 1, P)): per medium m, channel c and node g, nodes[m, c, g] =
    (T_g Q T_g, T_g Q T_g+1, q1 . T_g, r . T_g). Along the cell between g and g + 1,
    z = (1 - f) T_g + f T_g+1 gives exactly z Q z = (1-f)^2 n0_g + 2 f (1-f) n1_g + f^2 n0_g+1,
    q1 . z and r . z linear in f, so the k posterior's precision a = pk + sum_c (z Q z - (q1 .
    z)^2 / d_c) is a quadratic and a x E[k] = pk mk + sum_c (r . z - (q1 . z) y1_c / d_c) a
    linear function of f: cq[m, g] = (a0, a1, a2, e0, e1) with a = a0 + a1 f + a2 f^2 and
    a E[k] = e0 + e1 f (der as in :func:`_derive`)."""
    M, G, _, P = tables.shape
    nch = Q.shape[1]
    for m in range(M):
        for c in range(nch):
            for g in range(G):
                v0 = 0.0
                v1 = 0.0
                v2 = 0.0
                v3 = 0.0
                for p in range(P):
                    qt = 0.0
                    qn = 0.0
                    for p2 in range(P):
                        qt += Q[m, c, p, p2] * tables[m, g, 0, p2]
                        if g + 1 < G:
                            qn += Q[m, c, p, p2] * tables[m, g + 1, 0, p2]
                    tp = tables[m, g, 0, p]
                    v0 += tp * qt
                    v1 += tp * qn
                    v2 += q1[m, c, p] * tp
                    v3 += r[m, c, p] * tp
                nodes[m, c, g, 0] = v0
                nodes[m, c, g, 1] = v1
                nodes[m, c, g, 2] = v2
                nodes[m, c, g, 3] = v3
        for g in range(G - 1):
            a0 = pk
            a1 = 0.0
            a2 = 0.0
            e0 = pk * mk
            e1 = 0.0
            for c in range(nch):
                A0 = nodes[m, c, g, 0]
                B = nodes[m, c, g, 1]
                A1 = nodes[m, c, g + 1, 0]
                u0 = nodes[m, c, g, 2]
                u1 = nodes[m, c, g + 1, 2] - u0
                r0 = nodes[m, c, g, 3]
                r1 = nodes[m, c, g + 1, 3] - r0
                d = der[m, c]
                y = der[m, nch + c]
                a0 += A0 - d * u0 * u0
                a1 += 2.0 * (B - A0) - 2.0 * d * u0 * u1
                a2 += A0 - 2.0 * B + A1 - d * u1 * u1
                e0 += r0 - y * u0
                e1 += r1 - y * u1
            cq[m, g, 0] = a0
            cq[m, g, 1] = a1
            cq[m, g, 2] = a2
            cq[m, g, 3] = e0
            cq[m, g, 4] = e1


@njit(cache=True, fastmath=_FAST)
def _run_move(m, m2, base, seed, U, Zt, S, logml, kpost, tables, Q, q1, r, der, pk, mk, amp, p_jump, nodes, cq,
              qe, re, jf, Up, Zp, kp, lmp, ar, acc, mi, cidx):  # pragma: no cover - compiled
    """The Metropolis-Hastings sweep over one run of particles of medium m (views, so every
    loop starts at 0 and vectorises): proposals stay in m or (with probability p_jump) go to
    m2; coefficients and statistics of the two media are blended by the 0/1 mask jf, so the
    loops over particles are branch-free. Particles are counted from ``base`` for the random
    numbers. With one condition (G2 = 1) the k posterior's precision and mean come from the
    per-cell quadratics ``cq`` (see :func:`_node_stats`) in O(1) per particle, and the
    coefficients and running sums are interpolated for the accepted proposals only; with two,
    from one quadratic form over all channels (``qe``, ``re``: :func:`_effective`), O(D^2) per
    particle, the running sums again for the accepted proposals only (compacted, vectorised).
    cidx: int scratch (the run's part of mi0, which the caller has read). Returns the number of
    accepted proposals."""
    n, q = U.shape
    G1, G2, P = tables.shape[1], tables.shape[2], tables.shape[3]
    nch = S.shape[1]
    dm = m2 != m and p_jump > 0.0
    for i in range(n):
        b = np.uint32(base + i) * np.uint32(4)
        jf[i] = 1.0 if (dm and _u01(b, seed) < p_jump) else 0.0
        ar[i] = 1.0
    for j in range(q):
        a = amp[j]
        for i in range(n):
            v = U[i, j] + a * (np.float64(_u01(np.uint32(base + i) * np.uint32(4) + np.uint32(1 + j), seed)) - 0.5)
            Up[j, i] = v
            ar[i] = ar[i] if (v >= 0.0 and v <= 1.0) else -1.0
    ek = lmp
    kp0 = kp[0]
    kp1 = kp[1]
    if G2 == 1:
        # one condition: the k posterior's precision and mean are a quadratic and a linear
        # function of the fraction f within the proposal's table cell (exact, from cq)
        flat = cq.reshape(-1)  # (M, G1 - 1, 5) -> offsets (m (G1 - 1) + g) 5 + k
        for i in range(n):
            x = min(max(Up[0, i], 0.0), 1.0) * (G1 - 1)
            i0 = min(int(x), G1 - 2)
            f = x - i0
            o = ((m2 if jf[i] > 0.5 else m) * (G1 - 1) + i0) * 5
            kp0[i] = flat[o] + f * (flat[o + 1] + f * flat[o + 2])  # precision of k
            ek[i] = flat[o + 3] + f * flat[o + 4]
    else:
        # tabulated coefficients of the proposals (bilinear in the box, either medium)
        for i in range(n):
            x = min(max(Up[0, i], 0.0), 1.0) * (G1 - 1)
            i0 = min(int(x), G1 - 2)
            f0 = x - i0
            y = min(max(Up[1, i], 0.0), 1.0) * (G2 - 1)
            i1 = min(int(y), G2 - 2)
            f1 = y - i1
            mn = m2 if jf[i] > 0.5 else m
            for p in range(P):
                Zp[p, i] = ((1 - f0) * ((1 - f1) * tables[mn, i0, i1, p] + f1 * tables[mn, i0, i1 + 1, p])
                            + f0 * ((1 - f1) * tables[mn, i0 + 1, i1, p] + f1 * tables[mn, i0 + 1, i1 + 1, p]))
        # the k posterior's precision a = pk + z qe z and a E[k] = pk mk + re . z (all channels
        # at once, see :func:`_effective`); the running sums for the accepted proposals only
        for i in range(n):
            kp0[i] = pk
            ek[i] = pk * mk
        t = kp1
        for p in range(P):
            for i in range(n):
                t[i] = 0.0
            for p2 in range(P):
                a = qe[m, p, p2]
                d = qe[m2, p, p2] - a
                zp2 = Zp[p2]
                for i in range(n):
                    t[i] += (a + d * jf[i]) * zp2[i]
            ra, rd = re[m, p], re[m2, p] - re[m, p]
            zp = Zp[p]
            for i in range(n):
                z = zp[i]
                kp0[i] += z * t[i]
                ek[i] += (ra + rd * jf[i]) * z
    ca, cd = der[m, 2 * nch], der[m2, 2 * nch] - der[m, 2 * nch]
    seed2 = np.uint32(seed ^ np.uint32(0x5BD1E995))
    for i in range(n):  # k posterior; ar <- 1 / (a / pk) (>= 1 clamped; 0 marks out of the box)
        a = kp0[i]
        xk = ek[i] / a
        kp1[i] = 1.0 / a
        lmp[i] = ca + cd * jf[i] + 0.5 * ek[i] * xk
        kp0[i] = xk
        ar[i] = np.float64(np.float32(1.0) / np.float32(min(max(a / pk, 1.0), 1e30))) if ar[i] > 0.0 else 0.0
    for i in range(n):  # log marginal likelihood and the MH test (uniform prior: the likelihood ratio)
        v = ar[i]
        ok = v > 0.0
        lm = lmp[i] + 0.5 * np.float64(_log01(np.float32(v) if ok else np.float32(1.0)))
        lmp[i] = lm
        d = np.float32(min(max(lm - logml[i], -80.0), 0.0))
        acc[i] = np.uint8(ok and _u01(np.uint32(base + i), seed2) < _exp_neg(d))
    n_acc = 0
    for i in range(n):
        if acc[i]:
            n_acc += 1
            mn = m2 if jf[i] > 0.5 else m
            mi[i] = mn
            for j in range(q):
                U[i, j] = Up[j, i]
            if G2 == 1:
                x = min(max(Up[0, i], 0.0), 1.0) * (G1 - 1)
                i0 = min(int(x), G1 - 2)
                f0 = x - i0
                h = 1.0 - f0
                for p in range(P):
                    Zt[p, i] = h * tables[mn, i0, 0, p] + f0 * tables[mn, i0 + 1, 0, p]
                for c in range(nch):
                    S[0, c, i] = h * h * nodes[mn, c, i0, 0] + 2.0 * f0 * h * nodes[mn, c, i0, 1] \
                        + f0 * f0 * nodes[mn, c, i0 + 1, 0]
                    S[1, c, i] = h * nodes[mn, c, i0, 2] + f0 * nodes[mn, c, i0 + 1, 2]
                    S[2, c, i] = h * nodes[mn, c, i0, 3] + f0 * nodes[mn, c, i0 + 1, 3]
            else:
                for p in range(P):
                    Zt[p, i] = Zp[p, i]
                cidx[n_acc - 1] = i
            _take(i, lmp, logml, kp, kpost)
    if G2 > 1 and n_acc > 0:
        # running sums of the accepted proposals: compacted (k <= i, in order), then
        # vectorised over them channel by channel, and scattered back
        for k in range(n_acc):
            i = cidx[k]
            jf[k] = jf[i]
            for p in range(P):
                Zp[p, k] = Zp[p, i]
        t = kp[0]
        s0 = kp[1]
        s1 = ar
        s2 = lmp
        for c in range(nch):
            for k in range(n_acc):
                s0[k] = 0.0
                s1[k] = 0.0
                s2[k] = 0.0
            for p in range(P):
                for k in range(n_acc):
                    t[k] = 0.0
                for p2 in range(P):
                    a = Q[m, c, p, p2]
                    d = Q[m2, c, p, p2] - a
                    zp2 = Zp[p2]
                    for k in range(n_acc):
                        t[k] += (a + d * jf[k]) * zp2[k]
                qa, qd = q1[m, c, p], q1[m2, c, p] - q1[m, c, p]
                ra, rd = r[m, c, p], r[m2, c, p] - r[m, c, p]
                zp = Zp[p]
                for k in range(n_acc):
                    z = zp[k]
                    s0[k] += z * t[k]
                    s1[k] += (qa + qd * jf[k]) * z
                    s2[k] += (ra + rd * jf[k]) * z
            for k in range(n_acc):
                i = cidx[k]
                S[0, c, i] = s0[k]
                S[1, c, i] = s1[k]
                S[2, c, i] = s2[k]
    return n_acc


@njit(cache=True)
def _nb_move(mi, U, Zt, S, logml, ref, kpost, tables, Q, q1, r, der, pk, mk, step, p_jump, shift, seed,
             mi0, jf, nodes, cq, qe, re, Up, Zp, kp, buf2, acc):  # pragma: no cover - compiled
    """One random-walk Metropolis-Hastings sweep on (medium, u in [0, 1]^q) targeting the
    posterior given all samples so far (uniform prior on the box and the media), vectorised
    over runs of equal medium. Proposals move u by a uniform step of std ``step`` per input
    and, with probability p_jump, switch medium by the reflection m -> (shift - m) mod M, an
    involution (so the proposal is symmetric; ``shift`` is drawn uniformly in 0..M-1 per
    sweep, which makes the target uniform over the media). Random numbers from the counter
    hash seeded by ``seed``. The full-history likelihood comes from the sufficient
    statistics Q (M, nch, P, P), q1 and r (M, nch, P). mi0, jf, nodes, cq, qe, re, Up, Zp, kp,
    buf2, acc: scratch. Returns the acceptance rate; the weights become equal (ref = logml)."""
    N, q = U.shape
    M = tables.shape[0]
    if tables.shape[2] == 1:
        _node_stats(tables, Q, q1, r, der, pk, mk, nodes, cq)
    else:
        _effective(Q, q1, r, der, qe, re)
    amp = np.empty(q)
    for j in range(q):
        amp[j] = step[j] * math.sqrt(12.0)
    for i in range(N):
        mi0[i] = mi[i]
    n_acc = 0
    s = 0
    while s < N:
        m = mi0[s]
        e = _run_end(mi0, s)
        m2 = (shift - m) % M
        n_acc += _run_move(m, m2, s, seed, U[s:e], Zt[:, s:e], S[:, :, s:e], logml[s:e], kpost[:, s:e], tables,
                           Q, q1, r, der, pk, mk, amp, p_jump, nodes, cq, qe, re, jf[s:e], Up[:, s:e], Zp[:, s:e],
                           kp[:, s:e], buf2[0, s:e], buf2[1, s:e], acc[s:e], mi[s:e], mi0[s:e])
        s = e
    for i in range(N):
        ref[i] = logml[i]
    return n_acc / N


# ------------------------------------------------------------------------------ the filter
class TerrainFilter:
    """Posterior over the terrain (medium, strength k, continuous conditions) and the
    channels' biases, from streamed samples; forecasts of the rest of the stroke.

    model: a :class:`TerrainModel`; channels: a list of :class:`Channel` (names unique);
    k_std: prior std of the strength factor k (mean 1); n_particles; ess_threshold: resample
    (and move) when ESS < ess_threshold x N; move_sweeps: Metropolis-Hastings sweeps per
    resampling (0: a plain bootstrap filter over static parameters, which degenerates);
    step: the largest random-walk std in box units (the step follows the particles'
    spread); p_jump: probability that a move proposes another medium; seed; model_error:
    add the surrogates' representation error to the sensor noise; move_kernel: ``"vector"``
    (default: runs of equal medium, branch-free loops over particles, medium jumps by a
    random reflection of the media) or ``"per-particle"`` (the previous scalar kernel, jumps
    to a uniform other medium; the benchmark's reference).
    """

    def __init__(self, model: TerrainModel, channels: Sequence[Channel], k_std: float = 0.1,
                 n_particles: int = 5000, ess_threshold: float = 0.5, move_sweeps: int = 1,
                 step: float = 0.05, p_jump: float = 0.2, seed: int = 0, model_error: bool = True,
                 move_kernel: str = "vector"):
        self.model = model
        self.channels = list(channels)
        if not self.channels:
            raise InputError("channels", "need at least one sensor channel")
        names = [c.name for c in self.channels]
        if len(set(names)) != len(names):
            raise InputError("channels", f"names must be unique, got {names}")
        self.names = names
        self.n = N = integer("particles", n_particles, 2)
        if N > 10_000_000:
            raise InputError("particles", f"must be <= 10000000, got {N}")
        self.k_std = positive("k-std", k_std)
        self.ess_threshold = in_range("ess-threshold", ess_threshold, 0.0, 1.0)
        self.move_sweeps = integer("move-sweeps", move_sweeps, 0)
        if self.move_sweeps > 100:
            raise InputError("move-sweeps", f"must be <= 100, got {move_sweeps}")
        self.p_jump = in_range("p-jump", p_jump, 0.0, 1.0)
        self.model_error = bool(model_error)
        self.move_kernel = choice("move-kernel", move_kernel, MOVE_KERNELS)
        q = len(model.inputs)
        self.step = np.full(q, in_range("step", step, 1e-6, 1.0))
        self.seed = seed
        self.rng = np.random.default_rng(seed)
        _nb_seed(int(self.rng.integers(0, 2 ** 31)))
        M, P, nch = len(model.media), model.P, len(self.channels)
        self.mi = self.rng.integers(0, M, N).astype(np.int64)
        self.U = self.rng.random((N, q))
        self.mi.sort()  # runs of equal medium (see _nb_assimilate)
        self.Zt = np.empty((P, N))
        _nb_table(model.table, self.mi, self.U, self.Z)
        self.S = np.zeros((3, nch, N))
        self.logml = np.zeros(N)
        self.ref = np.zeros(N)
        self.kpost = np.empty((2, N))
        self.kpost[0] = 1.0
        self.kpost[1] = self.k_std ** 2
        self.pk, self.mk = 1.0 / self.k_std ** 2, 1.0
        self.pb = np.array([1.0 / max(c.bias_std, 1e-9 * c.noise) ** 2 for c in self.channels])
        self.n1 = np.zeros((M, nch))
        self.y1 = np.zeros((M, nch))
        self.yy = np.zeros(M)
        self.logc = np.zeros(M)
        self.der = np.zeros((M, 2 * nch + 1))
        self.Q = np.zeros((M, nch, P, P))
        self.q1 = np.zeros((M, nch, P))
        self.r = np.zeros((M, nch, P))
        rows = [model.channel_rows(c) for c in self.channels]
        self._R = np.ascontiguousarray(np.stack([a for a, _ in rows]))           # (nch, M, S, P)
        self._RES2 = np.ascontiguousarray(np.stack([e ** 2 for _, e in rows])) if self.model_error \
            else np.zeros((nch, M, len(model.theta)))
        self._noise2 = np.array([c.noise ** 2 for c in self.channels])
        self._ys = np.empty(nch)
        self._rows = np.empty((nch, M, P))
        self._wts = np.empty((nch, M))
        self._idx = np.empty(N, np.int64)
        self._buf = np.empty(N)
        self._buf2 = np.empty((2, N))
        # proposals of the Metropolis-Hastings move
        if self.move_kernel == "vector":
            G1, G2 = model.table.shape[1:3]
            G1 = G1 if G2 == 1 else 2  # (node tables only for one condition)
            self._mv = (np.empty(N, np.int64), np.empty(N), np.empty((M, nch, G1, 4)), np.empty((M, G1 - 1, 5)),
                        np.empty((M, P, P)), np.empty((M, P)), np.empty((q, N)), np.empty((P, N)), np.empty((2, N)),
                        self._buf2, np.empty(N, np.uint8))
        else:
            self._mv = (np.empty(N, np.int64), np.empty((N, q)), np.empty((N, P)), np.empty((3, nch, N)),
                        np.empty((2, N)), self._buf2, np.empty(N, np.uint8))
        g = model.theta
        self._asc = bool(g[-1] > g[0])
        self._g = g if self._asc else g[::-1]
        self._dir = 1.0 if self._asc else -1.0
        self.ess = float(N)
        self._spare_arrays = None  # gathers write there, then swap (allocated at the first)
        self._unsorted = False
        self._step = np.empty(q)
        self.n_samples = 0
        self.n_resamples = 0
        self.acceptance: list[float] = []
        self.last_theta = None

    @classmethod
    def on_grid(cls, model: TerrainModel, channels: Sequence[Channel], points: int = 201, k_std: float = 0.1,
                model_error: bool = True) -> "TerrainFilter":
        """The exact Bayesian posterior by quadrature instead of sampling: one fixed, equally
        weighted particle per medium and node of a regular grid of ``points`` per condition
        (``points`` x ``points`` // 4 for two), no resampling. The reference the particle
        filter is checked against (its marginal likelihoods are exact)."""
        q = len(model.inputs)
        pts = integer("points", points, 2)
        axes = [np.linspace(0, 1, pts)] + ([np.linspace(0, 1, max(pts // 4, 2))] if q > 1 else [])
        U = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, q)
        M = len(model.media)
        f = cls(model, channels, k_std=k_std, n_particles=M * len(U), ess_threshold=0.0, move_sweeps=0,
                model_error=model_error)
        f.mi[:] = np.repeat(np.arange(M), len(U))
        f.U[:] = np.tile(U, (M, 1))
        _nb_table(model.table, f.mi, f.U, f.Z)
        return f

    def check_theta(self, theta) -> float:
        """Validate a sample's angle (deg): finite, inside the model's stroke, and past the
        previous sample in the stroke's direction."""
        t = finite("theta", theta, "deg")
        g = self._g
        if not g[0] - 1e-9 <= t <= g[-1] + 1e-9:
            raise InputError("theta", f"must be in [{g[0]:g}, {g[-1]:g}] deg (the model's stroke), got {theta!r}")
        if self.last_theta is not None and (t - self.last_theta) * self._dir <= 0:
            raise InputError("theta", f"must move on along the stroke ({'increasing' if self._dir > 0 else 'decreasing'}); "
                                      f"got {t:g} deg after {self.last_theta:g} deg")
        return t

    def update(self, theta: float, values: dict) -> float:
        """Assimilate one sample at angle ``theta`` (deg): ``values`` channel name -> reading
        in the channel's units (None or NaN: missing). Returns the ESS before any resampling."""
        t = self.check_theta(theta)
        ys = self._ys
        ys[:] = np.nan
        for name, y in values.items():
            try:
                j = self.names.index(name)
            except ValueError:
                raise InputError("channel", f"unknown channel {name!r}; this filter has {self.names}") from None
            if y is None or y != y:
                continue
            yv = finite(name, y, self.channels[j].units)
            if abs(yv) > MAX_READING:
                raise InputError(name, f"reading must be within +-{MAX_READING:g} {self.channels[j].units}, got {y!r}")
            ys[j] = yv
        g = self._g
        k0 = min(max(int(np.searchsorted(g, t, side="right")) - 1, 0), len(g) - 2)
        f = (t - g[k0]) / (g[k0 + 1] - g[k0])
        if not self._asc:  # the model's grid runs backwards: index from its start
            k0, f = len(g) - 2 - k0, 1.0 - f
        self.last_theta = t
        self.n_samples += 1
        if self._unsorted:
            self._sort()
        ess = _nb_assimilate(k0, f, ys, self._noise2, self._R, self._RES2, self.Q, self.q1, self.r, self.n1,
                             self.y1, self.yy, self.logc, self.der, self.pk, self.mk, self.pb, self.mi, self.Zt,
                             self.S, self.logml, self.ref, self.kpost, self._rows, self._wts, self._buf2)
        if ess < 0:  # nothing observed
            return self.ess
        self.ess = ess
        if ess < self.ess_threshold * self.n:
            self.resample()
        return ess

    def resample(self) -> None:
        """Resample and (``move_sweeps`` > 0) rejuvenate by Metropolis-Hastings moves."""
        self.n_resamples += 1
        _nb_resample(self._state, self._spare, self.ref, self._idx, self._buf)
        self._swap()
        if self.move_sweeps:
            # random-walk scale from the spread of the (now equally weighted) conditions
            step = self._step
            _nb_step(self.U, self.step, step)
            for sweep in range(self.move_sweeps):
                if sweep and self.move_kernel == "vector" and self._unsorted:
                    self._sort()  # (the vectorised sweep works on runs of equal medium)
                self._unsorted = self.p_jump > 0 and len(self.model.media) > 1
                seed = np.uint32(self.rng.integers(0, 2 ** 32, dtype=np.uint64))
                args = (self.mi, self.U, self.Zt, self.S, self.logml, self.ref, self.kpost, self.model.table,
                        self.Q, self.q1, self.r, self.der, self.pk, self.mk, step, self.p_jump)
                if self.move_kernel == "vector":
                    shift = int(self.rng.integers(0, len(self.model.media)))
                    acc = _nb_move(*args, shift, seed, *self._mv)
                else:
                    acc = _nb_move_per_particle(*args, seed, *self._mv)
                self.acceptance.append(float(acc))
            # medium jumps break the runs of equal medium: sorted again before the next update
            # (deferred, so that a step that resamples does not also pay for the sort)
        self.ess = float(self.n)

    def _sort(self) -> None:
        """Sort the particles by medium if the runs of equal medium got short."""
        self._unsorted = False
        if _nb_runs(self.mi) > 4 * len(self.model.media):
            _nb_sort(self._state, self._spare, self._idx, len(self.model.media))
            self._swap()
            self.ref[:] = self.logml  # (the weights are equal after a move)

    @property
    def _state(self) -> tuple:
        """The per-particle arrays (reordered together by resampling and sorting)."""
        return self.mi, self.U, self.Zt, self.S, self.logml, self.kpost

    @property
    def _spare(self) -> tuple:
        if self._spare_arrays is None:
            self._spare_arrays = tuple(np.empty_like(a) for a in self._state)
        return self._spare_arrays

    def _swap(self) -> None:
        """Make the spare arrays (just written by a gather) the state, and the state spare."""
        spare = self._state
        self.mi, self.U, self.Zt, self.S, self.logml, self.kpost = self._spare
        self._spare_arrays = spare

    # -------------------------------------------------------------- posterior summaries
    @property
    def Z(self) -> np.ndarray:
        """(N, P) the particles' surrogate coefficients [c, 1] (a view)."""
        return self.Zt.T

    @property
    def weights(self) -> np.ndarray:
        lw = self.logml - self.ref
        w = np.exp(lw - lw.max())
        return w / w.sum()

    def medium_probabilities(self) -> dict[str, float]:
        p = np.bincount(self.mi, weights=self.weights, minlength=len(self.model.media))
        return {m: float(v) for m, v in zip(self.model.media, p)}

    def zeta_posterior(self, level: float = 0.95, draws: int = 4000) -> dict:
        """zeta = k x zeta_medium: posterior mean and central credible interval (draws from
        the mixture over particles of each particle's Gaussian k posterior)."""
        w = self.weights
        z0 = self.model.zeta[self.mi]
        mean = float(w @ (z0 * self.kpost[0]))
        rng = np.random.default_rng([self.seed, self.n_samples])  # summaries do not disturb the filter's stream
        i = rng.choice(self.n, size=draws, p=w)
        zs = z0[i] * (self.kpost[0, i] + np.sqrt(self.kpost[1, i]) * rng.standard_normal(draws))
        a = (1 - level) / 2
        return {"mean": mean, "lo": float(np.quantile(zs, a)), "hi": float(np.quantile(zs, 1 - a)), "level": level}

    def conditions_posterior(self) -> dict:
        """Posterior mean and std of each continuous condition (field units)."""
        w = self.weights
        X = self.model.lo + self.U * (self.model.hi - self.model.lo)
        mu = w @ X
        sd = np.sqrt(np.maximum(w @ (X - mu) ** 2, 0.0))
        return {n: {"mean": float(mu[j]), "std": float(sd[j])} for j, n in enumerate(self.model.inputs)}

    def forecast(self) -> np.ndarray:
        """Posterior mean force (S, C) over the whole stroke (bias-free): the sum over
        particles of w E[k] A_m z."""
        w = self.weights * self.kpost[0]
        v = np.zeros((len(self.model.media), self.model.P))
        np.add.at(v, self.mi, w[:, None] * self.Z)
        return np.einsum("mcsp,mp->sc", self.model.A, v)

    def summary(self) -> dict:
        p = self.medium_probabilities()
        return {"samples": self.n_samples, "theta_deg": self.last_theta, "ess": self.ess,
                "medium_probabilities": p, "medium": max(p, key=p.get), "zeta": self.zeta_posterior(),
                "conditions": self.conditions_posterior(), "resamples": self.n_resamples}


def stream(filt: TerrainFilter, samples: Iterable, forecast: bool = True):
    """Generator for a controller: for each sample ``(theta_deg, {channel: value})`` assimilate
    it and yield a dict with the terrain posterior (:meth:`TerrainFilter.summary`) and, with
    ``forecast``, the posterior-mean forecast of each component over the rest of the stroke
    (``forecast_theta_deg`` and lists per component)."""
    g = filt.model.theta
    for theta, values in samples:
        filt.update(theta, values)
        out = filt.summary()
        if forecast:
            rest = (g - filt.last_theta) * filt._dir > 0
            F = filt.forecast()[rest]
            out["forecast_theta_deg"] = g[rest].tolist()
            out["forecast"] = {c: F[:, j].tolist() for j, c in enumerate(COMPONENTS)}
        yield out


# ------------------------------------------------------------------------------ sensor files and streams
#: CSV columns of each sensor channel (name -> column) and the motion coordinate's column.
CHANNEL_COLUMNS = {"Fx": "Fx_N", "Fz": "Fz_N", "torque": "torque_Nm", "load_cell": "load_cell_N"}
THETA_COLUMN = "theta_deg"
#: Largest reading accepted (N, N m): a guard against unit slips and overflow.
MAX_READING = 1e6


def parse_header(line: str) -> tuple[int, dict[str, int]]:
    """Column of theta_deg and of each channel present, from a CSV header line."""
    cols = [c.strip() for c in line.strip().split(",")]
    if THETA_COLUMN not in cols:
        raise InputError("observations", f"header needs {THETA_COLUMN} and sensor columns "
                                         f"({', '.join(CHANNEL_COLUMNS.values())}); got {cols}")
    chans = {n: cols.index(c) for n, c in CHANNEL_COLUMNS.items() if c in cols}
    if not chans:
        raise InputError("observations", f"no sensor column; allowed: {', '.join(CHANNEL_COLUMNS.values())}; got {cols}")
    return cols.index(THETA_COLUMN), chans


def read_samples(lines: Iterable[str], where: str = "observations"):
    """Generator of ``(theta_deg, {channel: value or None})`` from CSV lines (a header, then
    one sample per line; '#' comments and blank lines skipped; empty cells missing). Each
    value is checked (a number, finite, |value| <= :data:`MAX_READING`) with its line number."""
    it = iter(lines)
    header = None
    lineno = 0
    for raw in it:
        lineno += 1
        if raw.strip() and not raw.lstrip().startswith("#"):
            header = raw
            break
    if header is None:
        raise InputError(where, "no header line")
    ic, chans = parse_header(header)

    def num(f, i, col):
        if i >= len(f) or f[i].strip() == "":
            return None
        try:
            v = float(f[i])
        except ValueError:
            raise InputError(where, f"line {lineno}: {col}: not a number: {f[i].strip()!r}") from None
        if not math.isfinite(v) or abs(v) > MAX_READING:
            raise InputError(where, f"line {lineno}: {col}: must be finite and within +-{MAX_READING:g}, got {f[i].strip()!r}")
        return v

    for raw in it:
        lineno += 1
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        f = line.split(",")
        t = num(f, ic, THETA_COLUMN)
        if t is None:
            raise InputError(where, f"line {lineno}: missing {THETA_COLUMN}")
        yield t, {n: num(f, i, CHANNEL_COLUMNS[n]) for n, i in chans.items()}


def channels_for(names: Sequence[str], noise: dict | None = None, bias_std: dict | None = None,
                 lever_arm_m: float = 0.1) -> list[Channel]:
    """Channels for the given names (``Fx``, ``Fz``, ``torque``, ``load_cell``) with noise and
    bias-prior std per channel (default 0.1 and 0; units of the channel)."""
    noise, bias_std = dict(noise or {}), dict(bias_std or {})
    for d, what in ((noise, "noise"), (bias_std, "bias-std")):
        bad = [k for k in d if k not in CHANNEL_COLUMNS]
        if bad:
            raise InputError(what, f"unknown channel(s) {bad}; allowed: {', '.join(CHANNEL_COLUMNS)}")
    out = []
    for n in names:
        if n == "load_cell":
            out.append(Channel.load_cell(lever_arm_m, noise.get(n, 0.1), bias_std.get(n, 0.0)))
        else:
            out.append(Channel(n, {n: 1.0}, noise.get(n, 0.1), bias_std.get(n, 0.0), COMPONENT_UNITS[n]))
    return out


def trace(filt: TerrainFilter, samples: Iterable) -> xr.Dataset:
    """Assimilate every sample and collect the terrain posterior after each: a Dataset on
    ``theta`` with p_medium (theta, medium), zeta_mean/lo/hi, each condition's mean and std,
    and the ESS. Uses :func:`stream`, so it equals the streamed output."""
    rows = list(stream(filt, samples, forecast=False))
    if not rows:
        raise InputError("observations", "no samples (only a header?)")
    th = np.array([r["theta_deg"] for r in rows])
    ds = xr.Dataset(
        {"p_medium": (("theta", "medium"), np.array([[r["medium_probabilities"][m] for m in filt.model.media]
                                                      for r in rows])),
         "zeta_mean": ("theta", np.array([r["zeta"]["mean"] for r in rows])),
         "zeta_lo": ("theta", np.array([r["zeta"]["lo"] for r in rows])),
         "zeta_hi": ("theta", np.array([r["zeta"]["hi"] for r in rows])),
         "ess": ("theta", np.array([r["ess"] for r in rows]))},
        coords={"theta": th, "medium": list(filt.model.media)})
    for n in filt.model.inputs:
        ds[f"{n}_mean"] = ("theta", np.array([r["conditions"][n]["mean"] for r in rows]))
        ds[f"{n}_std"] = ("theta", np.array([r["conditions"][n]["std"] for r in rows]))
    ds["theta"].attrs["units"] = "deg"
    ds["zeta_lo"].attrs["long_name"] = "lower end of the 95 % credible interval of zeta"
    ds["zeta_hi"].attrs["long_name"] = "upper end of the 95 % credible interval of zeta"
    ds.attrs.update(model="dddas-terrain", leg=filt.model.leg, particles=filt.n, channels=json_channels(filt),
                    medium_map=rows[-1]["medium"], resamples=filt.n_resamples)
    return ds


def json_channels(filt: TerrainFilter) -> str:
    import json

    return json.dumps([{"name": c.name, "weights": c.weights, "noise": c.noise, "bias_std": c.bias_std,
                        "units": c.units} for c in filt.channels])

# Cached kernels above use jitted code and constants of other modules: make their on-disk
# cache stale when those change too (terradyn._jitcache; Numba checks only this file).
_bind_cache(globals(), 'terradyn.dddas.filter')
