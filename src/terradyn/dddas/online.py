"""Streaming and batch assimilation of force samples into a surrogate's prediction.

:class:`Assimilation` holds the posterior over the surrogate's coefficients at one operating
condition. Feed it samples one at a time (:meth:`Assimilation.update` is the fast path;
:meth:`Assimilation.feed` also returns the current posterior force series with bands), or a
whole observation series (:func:`assimilate`). Observations may carry Fx, Fz or both, with NaN
for a missing value; the motion coordinate (theta in deg or time in s) must match the
surrogate's.
"""
from __future__ import annotations

import math

import numpy as np
import xarray as xr

from ..errors import InputError, choice, positive
from .filter import GaussianPosterior, ParticleFilter
from .surrogate import Surrogate

METHODS = ("pf", "exact")
#: Largest observation accepted (N, N m): a guard against unit slips and overflow.
MAX_OBS = 1e6


def _check_order(v: np.ndarray, coord: str, surrogate: Surrogate | None = None) -> None:
    """Samples must follow the motion: strictly monotonic, in the surrogate's direction."""
    if len(v) < 2:
        return
    g = surrogate.coord_values_ if surrogate is not None else None
    up = (g[-1] > g[0]) if g is not None else bool(v[1] > v[0])
    d = np.diff(v) if up else -np.diff(v)
    if (d <= 0).any():
        k = int(np.argmax(d <= 0)) + 1
        raise InputError("observations", f"{coord} must {'increase' if up else 'decrease'} from sample to sample "
                                         f"(the motion's direction); sample {k + 1} goes from {v[k - 1]:g} to {v[k]:g}")


class Assimilation:
    """Posterior of a surrogate's prediction at ``condition`` given streamed samples.

    obs_std: observation noise std per component, N (a float for all, or a dict such as
    {"Fz": 0.5}); method: "pf" (particle filter) or "exact" (Gaussian posterior);
    prior_inflation multiplies the GP's coefficient std; prior_floor (>= 0) sets a lower bound
    on it as a fraction of the spread (std) of the training cases' coefficients: the GP's std
    measures interpolation uncertainty between training conditions only, and a floor lets the
    data move the prediction when reality differs from every training case (a real trial vs
    RFT-trained surrogate); model_error adds the surrogate's representation error (what its
    truncated basis misses of the training data, per step) to the sensor noise variance, so
    the likelihood does not trust the truncated model more than it deserves (without it a
    particle filter collapses early onto a wrong value); the remaining keywords go to
    :class:`ParticleFilter` (n_particles, resample, ess_threshold, jitter, rng, backend).
    """

    def __init__(self, surrogate: Surrogate, condition, obs_std: float | dict = 0.1, method: str = "pf",
                 prior_inflation: float = 1.0, prior_floor: float = 0.0, model_error: bool = True,
                 **pf_options):
        self.surrogate = surrogate
        X = surrogate.conditions_array(condition)
        if len(X) != 1:
            raise InputError("condition", "assimilation needs exactly one condition")
        self.condition = {n: float(X[0, k]) for k, n in enumerate(surrogate.input_names_)}
        self.method = choice("method", method, METHODS)
        comps = surrogate.components_
        if isinstance(obs_std, dict):
            unknown = [c for c in obs_std if c not in comps]
            if unknown:
                raise InputError("obs-std", f"unknown component(s) {unknown}")
            self.obs_std = {c: positive(f"obs-std {c}", v, "N") for c, v in obs_std.items()}
        else:
            s = positive("obs-std", obs_std, "N")
            self.obs_std = {c: s for c in comps}
        infl = positive("prior-inflation", prior_inflation)
        floor = float(prior_floor)
        if not (math.isfinite(floor) and floor >= 0):
            raise InputError("prior-floor", f"must be >= 0, got {prior_floor!r}")
        mu, sd = surrogate.predict_coefficients(X)
        spread = surrogate.coef_train_.std(axis=0)
        self.prior_mean, self.prior_std = mu[0], np.maximum(sd[0] * infl, floor * spread)
        if self.method == "pf":
            self.post = ParticleFilter(self.prior_mean, prior_std=self.prior_std, **pf_options)
        else:
            if pf_options:
                raise InputError("method", f"options {sorted(pf_options)} apply only to method='pf'")
            self.post = GaussianPosterior(self.prior_mean, np.diag(self.prior_std ** 2))
        self.model_error = bool(model_error)
        self._rows: dict[tuple[str, float], tuple[np.ndarray, float, float]] = {}
        self._grid: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        self._index = {float(v): k for k, v in enumerate(surrogate.coord_values_)}
        self.n_samples = 0

    def _row(self, component: str, value: float):
        # Observation rows are computed lazily and cached: per grid point from one
        # vectorised call for the whole grid, off-grid values one by one.
        key = (component, value)
        r = self._rows.get(key)
        if r is None:
            grid = self._grid.get(component)
            if grid is None:
                sur = self.surrogate
                H, off, err = sur.observation_rows(sur.coord_values_, component, with_error=True)
                s = self.obs_std[component]
                sig = np.sqrt(s * s + err ** 2) if self.model_error else np.full(len(off), s)
                grid = self._grid[component] = (H, off, sig)
            k = self._index.get(value)
            if k is not None:
                r = (grid[0][k], float(grid[1][k]), float(grid[2][k]))
            else:
                H, off, err = self.surrogate.observation_rows(value, component, with_error=True)
                s = self.obs_std[component]
                sigma = math.sqrt(s * s + float(err[0]) ** 2) if self.model_error else s
                r = (H[0], float(off[0]), sigma)
            if len(self._rows) < 100_000:
                self._rows[key] = r
        return r

    def update(self, coord_value: float, Fx: float | None = None, Fz: float | None = None,
               torque: float | None = None) -> float:
        """Assimilate one sample at motion coordinate ``coord_value`` (deg or s); None or NaN
        components are missing. Returns the ESS (inf for the exact method, N when nothing was
        observed)."""
        ess = math.inf if self.method == "exact" else self.post.ess
        for comp, y in (("Fx", Fx), ("Fz", Fz), ("torque", torque)):
            if y is None or y != y:  # None or NaN: missing
                continue
            if comp not in self.obs_std:
                raise InputError(comp, "this surrogate does not model it")
            if not math.isfinite(y) or abs(y) > MAX_OBS:
                raise InputError(comp, f"observation must be finite and within +-{MAX_OBS:g}, got {y}")
            h, off, sigma = self._row(comp, float(coord_value))
            ess = self.post.update(h, off, float(y), sigma)
        self.n_samples += 1
        return ess

    def posterior(self) -> tuple[np.ndarray, np.ndarray]:
        """Posterior coefficient mean (D,) and covariance (D, D)."""
        return self.post.mean, self.post.cov

    def prediction(self) -> xr.Dataset:
        """The current posterior force series with Fx_std/Fz_std (N)."""
        m, P = self.posterior()
        mean, std = self.surrogate.forces_from_coefficients(m, P)
        extra = {"assimilation": {"method": self.method, "samples": self.n_samples,
                                  "obs_std_N": self.obs_std, "model_error": self.model_error,
                                  "particles": getattr(self.post, "n", None),
                                  "resamples": getattr(self.post, "n_resamples", None)}}
        return self.surrogate.series(mean, std, self.condition, f"dddas-{self.method}", extra)

    def feed(self, coord_value: float, Fx: float | None = None, Fz: float | None = None) -> xr.Dataset:
        """Assimilate one sample and return the updated posterior force series."""
        self.update(coord_value, Fx, Fz)
        return self.prediction()


def observations_arrays(obs: xr.Dataset, coord: str, surrogate: Surrogate | None = None
                        ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Coordinate values (m,) and component arrays (m,) with NaN for missing, from a series-like
    Dataset (Fx and/or Fz; the motion coordinate ``coord``). Checks: at least one sample,
    the coordinate strictly monotonic (in the ``surrogate``'s direction when given), values
    finite (or NaN: missing) and within +-:data:`MAX_OBS`."""
    if coord not in obs.coords and coord not in obs:
        raise InputError("observations", f"need the surrogate's motion coordinate {coord!r}")
    comps = {c: np.asarray(obs[c].values, float) for c in ("Fx", "Fz", "torque") if c in obs}
    if not comps:
        raise InputError("observations", "need an Fx and/or Fz variable")
    v = np.asarray(obs[coord].values, float)
    if not np.isfinite(v).all():
        raise InputError("observations", f"{coord} contains NaN or inf")
    if len(v) == 0:
        raise InputError("observations", "no samples (only a header?)")
    _check_order(v, coord, surrogate)
    for c, a in comps.items():
        if np.isinf(a).any():
            raise InputError("observations", f"{c} contains inf")
        big = np.abs(np.nan_to_num(a)) > MAX_OBS
        if big.any():
            k = int(np.argmax(big))
            raise InputError("observations", f"{c} sample {k + 1}: {a[k]:g} is beyond +-{MAX_OBS:g} N")
    return v, comps


def assimilate(surrogate: Surrogate, condition, observations: xr.Dataset, obs_std: float | dict = 0.1,
               method: str = "pf", **options) -> xr.Dataset:
    """Batch form: assimilate every sample of ``observations`` in order and return the
    posterior force series (with Fx_std, Fz_std); attrs ``ess_min`` and
    ``samples_assimilated``. ``options`` go to :class:`Assimilation`."""
    a = Assimilation(surrogate, condition, obs_std, method, **options)
    v, comps = observations_arrays(observations, surrogate.coord_, surrogate)
    ess = np.empty(len(v))
    for i in range(len(v)):
        ess[i] = a.update(v[i], *(float(comps[c][i]) if c in comps else None for c in ("Fx", "Fz", "torque")))
    out = a.prediction()
    out.attrs["ess_min"] = float(np.min(ess)) if len(ess) else float("nan")
    out.attrs["samples_assimilated"] = int(np.sum(np.any([np.isfinite(x) for x in comps.values()], 0)))
    return out


def read_observations(path, coord: str | None = None) -> xr.Dataset:
    """Observations from a file: .nc/.zarr (a Dataset with theta or time and Fx and/or Fz) or
    CSV with a ``theta_deg`` or ``time_s`` column and ``Fx_N`` and/or ``Fz_N`` (empty cells
    are missing samples)."""
    from pathlib import Path

    path = Path(path)
    if not path.is_file() and not path.is_dir():
        raise InputError("observations", f"file not found: {path}")
    if path.suffix.lower() in (".nc", ".zarr"):
        ds = xr.open_dataset(path, engine="h5netcdf").load() if path.suffix.lower() == ".nc" \
            else xr.open_zarr(path).load()
        return ds
    import pandas as pd

    try:
        df = pd.read_csv(path, comment="#")
    except Exception as e:  # pandas raises many kinds
        raise InputError("observations", f"{path}: not a readable CSV ({e})") from None
    return _obs_from_columns(df.columns, {c: df[c].to_numpy() for c in df.columns}, str(path))


def _obs_from_columns(columns, data, where: str) -> xr.Dataset:
    cols = list(columns)
    c = "theta" if "theta_deg" in cols else "time" if "time_s" in cols else None
    units = {"Fx": "N", "Fz": "N", "torque": "N_m"}
    comps = [k for k in ("Fx", "Fz", "torque") if f"{k}_{units[k]}" in cols]
    if c is None or not {"Fx", "Fz"} & set(comps):
        raise InputError("observations", f"{where}: need a theta_deg or time_s column and Fx_N and/or Fz_N; got {cols}")
    def numeric(col):
        import pandas as pd

        raw = pd.Series(np.asarray(data[col], dtype=object))
        vals = pd.to_numeric(raw, errors="coerce").to_numpy(float)
        bad = np.isnan(vals) & raw.notna().to_numpy() & (raw.astype(str).str.strip() != "").to_numpy()
        if bad.any():
            k = int(np.argmax(bad))
            raise InputError("observations", f"{where}: {col} row {k + 1}: not a number: {str(raw[k]).strip()!r}")
        return vals

    out = xr.Dataset(coords={c: numeric(f"{c}_deg" if c == "theta" else "time_s")})
    for k in comps:
        out[k] = (c, numeric(f"{k}_{units[k]}"))
    return out


def stream_csv(assim: Assimilation, lines, every: int = 0, report=None) -> int:
    """Assimilate CSV lines (a header with theta_deg or time_s and Fx_N and/or Fz_N, then one
    sample per line, empty cells missing) as they arrive, e.g. from standard input. Calls
    ``report(n, ess)`` every ``every`` samples. Returns the number of samples."""
    it = iter(lines)
    try:
        header = next(it).strip().split(",")
    except StopIteration:
        raise InputError("observations", "no header line on the stream") from None
    coord = "theta_deg" if "theta_deg" in header else "time_s" if "time_s" in header else None
    if coord is None or not any(f"{k}_N" in header for k in ("Fx", "Fz")):
        raise InputError("observations", f"stream header needs theta_deg or time_s and Fx_N and/or Fz_N; got {header}")
    want = "theta" if coord == "theta_deg" else "time"
    if want != assim.surrogate.coord_:
        raise InputError("observations", f"the surrogate's coordinate is {assim.surrogate.coord_!r}, the stream gives {want!r}")
    ic = header.index(coord)
    ix = header.index("Fx_N") if "Fx_N" in header else None
    iz = header.index("Fz_N") if "Fz_N" in header else None
    g = assim.surrogate.coord_values_
    up = 1.0 if g[-1] > g[0] else -1.0
    last = None
    n = 0
    for lineno, line in enumerate(it, start=2):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        f = line.split(",")

        def num(i):
            if i is None or i >= len(f) or f[i].strip() == "":
                return None
            try:
                return float(f[i])
            except ValueError:
                raise InputError("observations", f"line {lineno}: not a number: {f[i]!r}") from None

        x = num(ic)
        if x is None:
            raise InputError("observations", f"line {lineno}: missing {coord}")
        vals = (num(ix), num(iz))
        for name, y in zip(("Fx_N", "Fz_N"), vals):
            if y is not None and not abs(y) <= MAX_OBS:
                raise InputError("observations", f"line {lineno}: {name}: must be finite and within +-{MAX_OBS:g}, got {y!r}")
        if last is not None and (x - last) * up <= 0:
            raise InputError("observations", f"line {lineno}: {coord} must {'increase' if up > 0 else 'decrease'} "
                                             f"(the motion's direction); {x:g} after {last:g}")
        last = x
        ess = assim.update(x, *vals)
        n += 1
        if report and every and n % every == 0:
            report(n, ess)
    if n == 0:
        raise InputError("observations", "no samples on the stream (only a header?)")
    return n
