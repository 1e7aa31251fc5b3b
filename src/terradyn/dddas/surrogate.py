"""The offline surrogate: HOSVD tensor basis + Gaussian-process regression.

:class:`Surrogate` follows the scikit-learn estimator contract: hyperparameters in
``__init__``, :meth:`Surrogate.fit` returns ``self`` and sets trailing-underscore attributes,
:meth:`Surrogate.predict` returns force series with standard deviations.

Model (shapes): training stack with n cases, S steps of the motion coordinate, C components.
Tensor A (n, S, C) in scaled units (component j divided by ``scale_[j]``); HOSVD basis
B (D, S, C) and mean M (S, C); case i ~ M + c_i @ B with coefficients c_i (D,). One GP per
coefficient maps the (standardised) condition x (q,) to c_d with a ConstantKernel x RBF
(one length scale per input) + WhiteKernel; predictions give a mean and a standard deviation
per coefficient, which propagate linearly to the forces (coefficients treated independent).
"""
from __future__ import annotations

import json
import warnings
from typing import Any, Sequence

import numpy as np
import xarray as xr
from sklearn.base import BaseEstimator

from ..errors import InputError, finite_array, in_range, integer
from ..series import coord_of
from .hosvd import hosvd

FORMAT = "terradyn-dddas-surrogate"
FORMAT_VERSION = 1
#: GP optimizer restarts allowed (each one refits every coefficient's GP).
MAX_RESTARTS = 100
#: Largest training force accepted (N, N m): squares must stay finite in float64.
MAX_FORCE = 1e12


def _component_units() -> dict:
    from ..series import SCHEMAS, UNITS

    return {c: UNITS[c] for s in SCHEMAS.values() for c in s.components}


#: Components a surrogate can model (those of every schema) and their units.
COMPONENT_UNITS = _component_units()


class ExtrapolationWarning(UserWarning):
    """A prediction at a condition outside the range the surrogate was trained on."""


def condition_names(data: xr.Dataset) -> list[str]:
    """Numeric coordinates along ``case`` (other than ``case`` itself): candidate inputs."""
    if "case" not in data.dims:
        raise InputError("data", "must be a stack of force series along 'case' (see terradyn.series.stack)")
    out = []
    for name, c in data.coords.items():
        if name != "case" and c.dims == ("case",) and np.issubdtype(c.dtype, np.number):
            out.append(str(name))
    return out


def training_arrays(data: xr.Dataset, inputs: Sequence[str] | None, components: Sequence[str]):
    """(X (n, q), Y (n, S, C), coord name, coord values (S,), input names) from a stack."""
    avail = condition_names(data)
    names = list(inputs) if inputs else avail
    if not names:
        raise InputError("inputs", "the dataset has no numeric condition coordinate along 'case' "
                                   "(e.g. omega); add one or name it")
    for n in names:
        if n not in avail:
            raise InputError("inputs", f"{n!r} is not a numeric coordinate along 'case'; available: {avail or 'none'}")
    coord = coord_of(data)
    for comp in components:
        if comp not in data:
            raise InputError("components", f"the dataset has no variable {comp!r}")
    X = finite_array("conditions", np.stack([data[n].values.astype(float) for n in names], -1), ndim=2)
    Y = finite_array("training forces", np.stack(
        [data[c].transpose("case", coord).values for c in components], -1), ndim=3)
    return X, Y, coord, data[coord].values.astype(float), names


class Surrogate(BaseEstimator):
    """Operating condition -> force series, with uncertainty.

    Parameters
    ----------
    inputs: names of the condition coordinates along ``case`` (None: all numeric ones).
    components: force components modelled; must include "Fx" and "Fz" ("torque" optional).
    energy: cumulative explained variance kept in the condition mode (thesis: 0.95); this
    sets D, the number of coefficients (the filter's dimension).
    step_energy: the same for the step and component modes (default 0.9999). Truncating them
    saves nothing online (the basis is D x steps x components either way) but blends the Fx
    and Fz shapes into one; then the model cannot fit data it was trained on, and a particle
    filter commits early to a wrong value. ``step_energy=energy`` is the thesis's uniform rule.
    ranks: fixed HOSVD ranks (r1, r2, r3) instead of ``energy`` (None entries use energy).
    center: subtract the mean trajectory before the HOSVD (see :func:`hosvd.hosvd`).
    scaling: "rms" (divide each component by its RMS) or "none".
    length_scale_bounds, constant_bounds, noise_level, noise_bounds: GP kernel settings, in
    standardised input units and normalised coefficient units.
    n_restarts: optimizer restarts per GP (deterministic through ``random_state``).
    """

    def __init__(self, inputs: Sequence[str] | None = None, components: Sequence[str] | None = None,
                 energy: float = 0.95, step_energy: float = 0.9999,
                 ranks: Sequence[int | None] | None = None, center: bool = True,
                 scaling: str = "rms", length_scale_bounds: tuple[float, float] = (0.05, 100.0),
                 constant_bounds: tuple[float, float] = (1e-3, 1e3), noise_level: float = 1e-3,
                 noise_bounds: tuple[float, float] = (1e-8, 1.0), n_restarts: int = 2,
                 random_state: int = 0):
        self.inputs = inputs
        self.components = components
        self.energy = energy
        self.step_energy = step_energy
        self.ranks = ranks
        self.center = center
        self.scaling = scaling
        self.length_scale_bounds = length_scale_bounds
        self.constant_bounds = constant_bounds
        self.noise_level = noise_level
        self.noise_bounds = noise_bounds
        self.n_restarts = n_restarts
        self.random_state = random_state

    # ------------------------------------------------------------------ fitting
    def _check_params(self, comps=None):
        comps = list(comps if comps is not None else self.components if self.components is not None
                     else ("Fx", "Fz"))
        for c in comps:
            if c not in COMPONENT_UNITS:
                raise InputError("components", f"unknown component {c!r}; allowed: {', '.join(COMPONENT_UNITS)}")
        if "Fx" not in comps or "Fz" not in comps or len(set(comps)) != len(comps):
            raise InputError("components", f"must include Fx and Fz once each, got {comps}")
        in_range("energy", self.energy, 1e-6, 1.0)
        in_range("step_energy", self.step_energy, 1e-6, 1.0)
        if self.scaling not in ("rms", "none"):
            raise InputError("scaling", f"must be 'rms' or 'none', got {self.scaling!r}")
        if integer("restarts", self.n_restarts, 0) > MAX_RESTARTS:
            raise InputError("restarts", f"must be an integer in [0, {MAX_RESTARTS}], got {self.n_restarts!r}")
        return comps

    def _kernel(self, q: int):
        from sklearn.gaussian_process.kernels import RBF, ConstantKernel, WhiteKernel

        return (ConstantKernel(1.0, tuple(self.constant_bounds))
                * RBF(np.ones(q), tuple(self.length_scale_bounds))
                + WhiteKernel(self.noise_level, tuple(self.noise_bounds)))

    def fit(self, data: xr.Dataset, y=None) -> "Surrogate":
        """Fit to a stack of force series along ``case`` whose condition coordinates are
        named by ``inputs``. Returns self."""
        from ..series import components

        comps = self._check_params(self.components if self.components is not None else components(data))
        X, Y, coord, values, names = training_arrays(data, self.inputs, comps)
        trained_on = {"model": data.attrs.get("model", "unknown"), "medium": data.attrs.get("medium", ""),
                      "leg": data.attrs.get("leg", ""), "n_cases": int(X.shape[0]),
                      "conditions": {n: X[:, i].tolist() for i, n in enumerate(names)},
                      "note": data.attrs.get("dddas_note", "")}
        return self.fit_arrays(X, Y, coord, values, names, trained_on, components=comps)

    def fit_arrays(self, X, Y, coord: str, coord_values, input_names: Sequence[str],
                   trained_on: dict[str, Any] | None = None, components=None) -> "Surrogate":
        """Fit from arrays: X (n, q) conditions, Y (n, S, C) forces in N (N m for torque);
        ``components`` names the C components (default: the estimator's, else Fx, Fz)."""
        comps = self._check_params(components)
        X = finite_array("conditions", X, ndim=2)
        Y = finite_array("training forces", Y, ndim=3)
        if Y.shape[0] != X.shape[0] or Y.shape[2] != len(comps):
            raise InputError("training forces", f"shape {Y.shape} does not match {X.shape[0]} cases x {len(comps)} components")
        if X.shape[0] < 3:
            raise InputError("data", f"need at least 3 training cases, got {X.shape[0]}")
        if np.abs(Y).max() > MAX_FORCE:
            raise InputError("training forces", f"|force| must be <= {MAX_FORCE:g} N (N m), got up to {np.abs(Y).max():g}")
        if X.shape[1] != len(input_names):
            raise InputError("inputs", f"{len(input_names)} names for {X.shape[1]} condition columns")
        x_scale = X.std(axis=0)
        if (x_scale <= 0).any():
            bad = [n for n, s in zip(input_names, x_scale) if s <= 0]
            raise InputError("inputs", f"condition(s) {bad} do not vary across the training cases")
        self.input_names_ = list(input_names)
        self.components_ = comps
        self.coord_ = coord
        self.coord_values_ = finite_array("coordinate", coord_values, ndim=1)
        if len(self.coord_values_) != Y.shape[1]:
            raise InputError("coordinate", f"{len(self.coord_values_)} values for {Y.shape[1]} steps")
        if self.scaling == "rms":
            scale = np.sqrt((Y ** 2).mean(axis=(0, 1)))
            scale = np.where(scale > 0, scale, 1.0)
        else:
            scale = np.ones(Y.shape[2])
        self.scale_ = scale
        h = hosvd(Y / scale, energy=(self.energy, self.step_energy, self.step_energy), ranks=self.ranks,
                  center=self.center)
        self.hosvd_ = h
        self.basis_ = h.basis                      # (D, S, C), scaled units
        self.mean_ = h.mean                        # (S, C), scaled units
        self.ranks_ = h.ranks
        self.explained_variance_ = [cv.copy() for cv in h.cumvar]
        self.x_mean_ = X.mean(axis=0)
        self.x_scale_ = x_scale
        self.X_train_ = X
        self.Y_train_ = Y
        self.coef_train_ = h.coefficients.copy()   # (n, D)
        self.trained_on_ = dict(trained_on or {})
        self._set_residual()
        self._fit_gps(optimize=True)
        return self

    def _set_residual(self):
        # Representation error: what the truncated basis cannot reproduce of the training
        # cases, RMS over cases at each step, in N (N m). The online filter adds it to the
        # sensor noise, otherwise the likelihood trusts the truncated model too much.
        rec = (np.tensordot(self.coef_train_, self.basis_, axes=(1, 0)) + self.mean_) * self.scale_
        self.residual_std_ = np.sqrt(((self.Y_train_ - rec) ** 2).mean(axis=0))

    def _fit_gps(self, optimize: bool, thetas: np.ndarray | None = None):
        from sklearn.gaussian_process import GaussianProcessRegressor

        Xs = (self.X_train_ - self.x_mean_) / self.x_scale_
        self.gps_ = []
        for d in range(self.coef_train_.shape[1]):
            kernel = self._kernel(Xs.shape[1])
            if thetas is not None:
                kernel = kernel.clone_with_theta(thetas[d])
            gp = GaussianProcessRegressor(kernel, normalize_y=True,
                                          optimizer="fmin_l_bfgs_b" if optimize else None,
                                          n_restarts_optimizer=int(self.n_restarts) if optimize else 0,
                                          random_state=np.random.RandomState(int(self.random_state) + d))
            with warnings.catch_warnings():
                # Bound warnings on 10-point data sets are expected and not actionable here.
                warnings.simplefilter("ignore")
                gp.fit(Xs, self.coef_train_[:, d])
            self.gps_.append(gp)
        self.gp_theta_ = np.array([gp.kernel_.theta for gp in self.gps_])

    # ------------------------------------------------------------------ prediction
    def _check_fitted(self):
        if not hasattr(self, "gps_"):
            raise InputError("surrogate", "is not fitted; call fit() or load a model file")

    def conditions_array(self, condition) -> np.ndarray:
        """(m, q) conditions from a dict name -> value(s), a scalar (one input) or an array."""
        self._check_fitted()
        q = len(self.input_names_)
        if isinstance(condition, dict):
            missing = [n for n in self.input_names_ if n not in condition]
            extra = [n for n in condition if n not in self.input_names_]
            if missing or extra:
                raise InputError("condition", f"need exactly {self.input_names_}; missing {missing}, unknown {extra}")
            cols = [np.atleast_1d(np.asarray(condition[n], float)) for n in self.input_names_]
            X = np.stack(np.broadcast_arrays(*cols), -1)
        else:
            X = np.asarray(condition, float)
            X = X.reshape(-1, q) if X.ndim < 2 else X
        X = finite_array("condition", X, ndim=2)
        if X.shape[1] != q:
            raise InputError("condition", f"need {q} value(s) per condition ({self.input_names_}), got {X.shape[1]}")
        return X

    def outside_training(self, condition) -> list[str]:
        """One line per input of ``condition`` outside the training range (empty if none)."""
        X = self.conditions_array(condition)
        lo, hi = self.X_train_.min(axis=0), self.X_train_.max(axis=0)
        out = []
        for k, n in enumerate(self.input_names_):
            bad = (X[:, k] < lo[k]) | (X[:, k] > hi[k])
            if bad.any():
                out.append(f"{n}={X[bad, k][0]:g} is outside the training range [{lo[k]:g}, {hi[k]:g}]")
        return out

    def warn_extrapolation(self, condition) -> None:
        """Warn (:class:`ExtrapolationWarning`) for a condition outside the training range."""
        import warnings

        for line in self.outside_training(condition):
            warnings.warn(f"at: {line}: the surrogate extrapolates", ExtrapolationWarning, stacklevel=3)

    def predict_coefficients(self, condition) -> tuple[np.ndarray, np.ndarray]:
        """GP mean and standard deviation of the coefficients, each (m, D)."""
        X = self.conditions_array(condition)
        Xs = (X - self.x_mean_) / self.x_scale_
        mu, sd = zip(*(gp.predict(Xs, return_std=True) for gp in self.gps_))
        return np.stack(mu, -1), np.stack(sd, -1)

    def predict_arrays(self, condition) -> tuple[np.ndarray, np.ndarray]:
        """Predicted forces and their standard deviations, each (m, S, C) in N (N m)."""
        mu, sd = self.predict_coefficients(condition)
        B = self.basis_
        mean = (np.tensordot(mu, B, axes=(1, 0)) + self.mean_) * self.scale_
        std = np.sqrt(np.tensordot(sd ** 2, B ** 2, axes=(1, 0))) * self.scale_
        return mean, std

    def series(self, mean: np.ndarray, std: np.ndarray, condition: dict, model: str,
               extra_inputs: dict | None = None) -> xr.Dataset:
        """A force series (S,) from component arrays mean/std (S, C)."""
        from ..series import make_series

        inputs = {"condition": condition, "surrogate": self.describe(), **(extra_inputs or {})}
        comps = self.components_
        ds = make_series(self.coord_, self.coord_values_, {c: mean[:, i] for i, c in enumerate(comps)},
                         schema="3d" if "Fy" in comps else "2d", model=model, inputs=inputs,
                         extra={f"{c}_std": std[:, i] for i, c in enumerate(comps)})
        ds.attrs["leg"] = str(self.trained_on_.get("leg", ""))
        ds.attrs["medium"] = str(self.trained_on_.get("medium", ""))
        return ds

    def predict(self, condition, return_std: bool = True) -> xr.Dataset:
        """Force series at ``condition`` (dict name -> value, or a scalar for one input).
        One condition: a force series with Fx_std/Fz_std (N); several: a stack along ``case``.
        ``return_std=False`` drops the std variables. A condition outside the training range
        warns (:class:`ExtrapolationWarning`): the GP there returns towards its prior."""
        X = self.conditions_array(condition)
        self.warn_extrapolation(X)
        mean, std = self.predict_arrays(X)
        out = []
        for i in range(len(X)):
            cond = {n: float(X[i, k]) for k, n in enumerate(self.input_names_)}
            ds = self.series(mean[i], std[i], cond, "dddas-surrogate")
            if not return_std:
                ds = ds.drop_vars([v for v in ds.data_vars if v.endswith("_std")])
            out.append(ds)
        if len(out) == 1:
            return out[0]
        from ..series import stack

        return stack(out, {n: X[:, k] for k, n in enumerate(self.input_names_)})

    # ------------------------------------------------------------------ observation model
    def observation_rows(self, coord_values, component: str, with_error: bool = False):
        """Linear observation model at motion-coordinate values (m,) for ``component``:
        y = H @ c + offset with H (m, D), offset (m,) in N (N m). Values between grid points
        interpolate linearly; outside the grid raises. ``with_error`` also returns the
        representation error std (m,) there (see ``residual_std_``)."""
        self._check_fitted()
        if component not in self.components_:
            raise InputError("component", f"the surrogate models {self.components_}, not {component!r}")
        v = np.atleast_1d(np.asarray(coord_values, float))
        g = self.coord_values_
        lo, hi = min(g[0], g[-1]), max(g[0], g[-1])
        tol = 1e-9 * max(1.0, abs(hi - lo))
        if not np.isfinite(v).all() or (v < lo - tol).any() or (v > hi + tol).any():
            raise InputError(self.coord_, f"observation outside the surrogate's range [{lo:g}, {hi:g}]")
        idx = np.interp(v, g, np.arange(len(g))) if g[-1] > g[0] else \
            np.interp(v, g[::-1], np.arange(len(g))[::-1])
        k0 = np.clip(np.floor(idx).astype(int), 0, len(g) - 2)
        w = (idx - k0)[:, None]
        j = self.components_.index(component)
        s = self.scale_[j]
        B = self.basis_[:, :, j]
        H = ((1 - w) * B[:, k0].T + w * B[:, k0 + 1].T) * s
        off = ((1 - w[:, 0]) * self.mean_[k0, j] + w[:, 0] * self.mean_[k0 + 1, j]) * s
        if with_error:
            r = self.residual_std_[:, j]
            return np.ascontiguousarray(H), off, (1 - w[:, 0]) * r[k0] + w[:, 0] * r[k0 + 1]
        return np.ascontiguousarray(H), off

    def forces_from_coefficients(self, mean_c: np.ndarray, cov_c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Force mean and std (S, C) for a Gaussian over coefficients: mean (D,), cov (D, D)."""
        B = self.basis_
        mean = (np.tensordot(mean_c, B, axes=(0, 0)) + self.mean_) * self.scale_
        var = np.einsum("dsc,de,esc->sc", B, cov_c, B)
        return mean, np.sqrt(np.clip(var, 0, None)) * self.scale_

    # ------------------------------------------------------------------ description and files
    def describe(self) -> dict:
        self._check_fitted()
        return {"kind": "hosvd-gp", "inputs": self.input_names_, "components": self.components_,
                "ranks": list(map(int, self.ranks_)), "energy": float(self.energy),
                "center": bool(self.center), "trained_on": self.trained_on_}

    def to_dataset(self) -> xr.Dataset:
        """The fitted model as an xarray Dataset (what :meth:`save` writes)."""
        self._check_fitted()
        c = self.coord_
        ds = xr.Dataset(
            {"basis": (("mode", c, "component"), self.basis_),
             "mean": ((c, "component"), self.mean_),
             "scale": ("component", self.scale_),
             "x_mean": ("input", self.x_mean_), "x_scale": ("input", self.x_scale_),
             "train_X": (("case", "input"), self.X_train_),
             "train_Y": (("case", c, "component"), self.Y_train_),
             "train_coef": (("case", "mode"), self.coef_train_),
             "gp_theta": (("mode", "hyper"), self.gp_theta_),
             "explained_variance_1": ("sv1", self.explained_variance_[0]),
             "explained_variance_2": ("sv2", self.explained_variance_[1]),
             "explained_variance_3": ("sv3", self.explained_variance_[2])},
            coords={c: self.coord_values_, "component": self.components_, "input": self.input_names_})
        from .. import __version__
        import datetime as _dt

        params = self.get_params()
        params["inputs"] = list(params["inputs"]) if params["inputs"] is not None else None
        params["components"] = list(params["components"]) if params["components"] is not None else None
        ds.attrs.update(format=FORMAT, format_version=FORMAT_VERSION, coord=c,
                        params=json.dumps(params, default=list), ranks=json.dumps(list(map(int, self.ranks_))),
                        trained_on=json.dumps(self.trained_on_, default=str),
                        terradyn_version=__version__,
                        created=_dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"))
        ds["train_Y"].attrs["units"] = "N (N m for torque)"
        ds["basis"].attrs["long_name"] = "HOSVD tensor basis S x2 U2 x3 U3 in scaled units"
        ds["gp_theta"].attrs["long_name"] = "log-hyperparameters of each coefficient's GP kernel"
        return ds

    def save(self, path):
        """Write the model to a NetCDF file (.nc). No pickle: arrays and JSON attributes."""
        from pathlib import Path

        path = Path(path)
        if path.suffix.lower() != ".nc":
            raise InputError("model file", f"must end in .nc, got {path.name}")
        from ..io import write_netcdf

        return write_netcdf(self.to_dataset(), path)

    @classmethod
    def from_dataset(cls, ds: xr.Dataset) -> "Surrogate":
        """Rebuild a fitted surrogate from :meth:`to_dataset`, validating it. The GPs are refit
        deterministically on the stored training coefficients with the stored kernel
        hyperparameters (no optimisation), so predictions match the saved model."""
        def bad(msg):
            return InputError("model file", msg)

        if ds.attrs.get("format") != FORMAT:
            raise bad(f"not a terradyn surrogate (format {ds.attrs.get('format')!r})")
        ver = int(ds.attrs.get("format_version", -1))
        if ver != FORMAT_VERSION:
            raise bad(f"format version {ver} is not supported (this terradyn reads {FORMAT_VERSION})")
        need = ["basis", "mean", "scale", "x_mean", "x_scale", "train_X", "train_Y", "train_coef", "gp_theta"]
        missing = [v for v in need if v not in ds]
        if missing:
            raise bad(f"missing variable(s) {missing}")
        try:
            params = json.loads(ds.attrs["params"])
            trained_on = json.loads(ds.attrs.get("trained_on", "{}"))
            coord = ds.attrs["coord"]
        except (KeyError, ValueError) as e:
            raise bad(f"damaged attributes ({e})") from None
        if coord not in ("theta", "time") or coord not in ds.coords:
            raise bad(f"bad motion coordinate {coord!r}")
        est = cls(**params)
        comps = est._check_params()
        arr = {v: np.asarray(ds[v].values, float) for v in need}
        for v, a in arr.items():
            if not np.isfinite(a).all():
                raise bad(f"{v} contains NaN or inf")
        D, S, C = arr["basis"].shape
        n, q = arr["train_X"].shape
        if C != len(comps) or list(ds["component"].values) != comps:
            raise bad("component list does not match the basis")
        if arr["mean"].shape != (S, C) or arr["scale"].shape != (C,) or arr["train_Y"].shape != (n, S, C) \
                or arr["train_coef"].shape != (n, D) or arr["gp_theta"].shape[0] != D \
                or arr["x_mean"].shape != (q,) or arr["x_scale"].shape != (q,) or ds[coord].size != S:
            raise bad("inconsistent array shapes")
        if (arr["scale"] <= 0).any() or (arr["x_scale"] <= 0).any():
            raise bad("scales must be positive")
        est.input_names_ = [str(x) for x in ds["input"].values]
        est.components_ = comps
        est.coord_ = coord
        est.coord_values_ = np.asarray(ds[coord].values, float)
        est.scale_ = arr["scale"]
        est.basis_ = arr["basis"]
        est.mean_ = arr["mean"]
        est.ranks_ = tuple(json.loads(ds.attrs.get("ranks", "[]"))) or (D, None, None)
        est.explained_variance_ = [np.asarray(ds[f"explained_variance_{k}"].values, float) for k in (1, 2, 3)]
        est.x_mean_ = arr["x_mean"]
        est.x_scale_ = arr["x_scale"]
        est.X_train_ = arr["train_X"]
        est.Y_train_ = arr["train_Y"]
        est.coef_train_ = arr["train_coef"]
        est.trained_on_ = trained_on
        est._set_residual()
        if arr["gp_theta"].shape[1] != est._kernel(q).n_dims:
            raise bad("GP hyperparameter count does not match the kernel")
        est._fit_gps(optimize=False, thetas=arr["gp_theta"])
        return est

    @classmethod
    def load(cls, path) -> "Surrogate":
        """Read a model written by :meth:`save`, validated."""
        from pathlib import Path

        path = Path(path)
        if not path.is_file():
            raise InputError("model file", f"not found: {path}")
        try:
            with xr.open_dataset(path, engine="h5netcdf") as f:
                ds = f.load()
        except (OSError, ValueError) as e:
            raise InputError("model file", f"{path}: not a readable NetCDF file ({e})") from None
        return cls.from_dataset(ds)
