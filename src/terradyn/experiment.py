"""Experimental time series of a foot pushed into a granular bed (thesis ch. 3).

A *trial* is an :class:`xarray.Dataset` on a ``time`` dimension (s) with the variables
``angle_cmd``, ``angle`` (deg), ``speed_cmd``, ``speed`` (deg/s), ``torque`` (N m) and
``normal_force`` (N); those the file lacks are absent. Attributes record the source file and
whether the data are **synthetic** (no real trials are public: :func:`synthetic_trial` makes
them from the project's own RFT model plus noise, bias and lag, and says so in the attributes
and in the CSV header).

Functions: :func:`read_trial` / :func:`write_trial` (CSV, configurable column names and
units), :func:`lowpass` (zero-phase Butterworth, ``scipy.signal.sosfiltfilt``),
:func:`rft_foot_forces` (RFT normal force and torque of the foot at the trial's actual
angles), :func:`compare` (raw, filtered and model on one time base, with errors),
:func:`calibrate` (least squares for nominal length, zeta and offset, with standard errors
from the Jacobian), :func:`to_force_series` (the normal force as a force series on theta, for
assimilation).
"""
from __future__ import annotations

import datetime as _dt
import json
import math
from pathlib import Path
from typing import Sequence

import numpy as np
import xarray as xr

from .compare import mse_values, peak_of
from .errors import InputError, open_text, choice, finite_array, in_range, positive
from .units import CM, DEG

#: Trial variables, the default CSV column for each and its unit.
DEFAULT_COLUMNS = {"time": "time_ms", "angle_cmd": "angle_cmd_deg", "angle": "angle_deg",
                   "speed_cmd": "speed_cmd_deg_s", "speed": "speed_deg_s", "torque": "torque_Nm",
                   "normal_force": "normal_force_N"}
DEFAULT_UNITS = {"time": "ms", "angle_cmd": "deg", "angle": "deg", "speed_cmd": "deg/s",
                 "speed": "deg/s", "torque": "N m", "normal_force": "N"}
#: Internal units and the factors from the units a file may use.
INTERNAL_UNITS = {"time": "s", "angle_cmd": "deg", "angle": "deg", "speed_cmd": "deg/s",
                  "speed": "deg/s", "torque": "N m", "normal_force": "N"}
_FACTORS = {
    "time": {"ms": 1e-3, "s": 1.0, "us": 1e-6},
    "angle": {"deg": 1.0, "rad": 180.0 / math.pi},
    "speed": {"deg/s": 1.0, "rad/s": 180.0 / math.pi},
    "torque": {"N m": 1.0, "N mm": 1e-3, "N cm": 1e-2},
    "normal_force": {"N": 1.0, "kN": 1e3, "lbf": 4.4482216152605, "kgf": 9.80665},
}
_KIND = {"time": "time", "angle_cmd": "angle", "angle": "angle", "speed_cmd": "speed",
         "speed": "speed", "torque": "torque", "normal_force": "normal_force"}
LONG_NAMES = {"angle_cmd": "commanded angle", "angle": "actual angle", "speed_cmd": "commanded angular speed",
              "speed": "actual angular speed", "torque": "input torque", "normal_force": "normal force"}
#: Thesis ch. 3: commanded angles 3, 7, 12 deg reached 0.84, 1.7 and about 2.6 deg.
THESIS_REACHED = ((3.0, 7.0, 12.0), (0.84, 1.7, 2.6))


# ------------------------------------------------------------------------------ files
def read_trial(path: str | Path, columns: dict[str, str] | None = None,
               units: dict[str, str] | None = None,
               required: Sequence[str] = ("time", "angle", "normal_force")) -> xr.Dataset:
    """Read a trial CSV. ``columns`` maps trial variables to the file's column names and
    ``units`` to their units (defaults :data:`DEFAULT_COLUMNS`, :data:`DEFAULT_UNITS`; only
    the entries you change are needed). Lines starting with '#' are header comments; a header
    containing "synthetic" marks the trial synthetic. Raises :class:`InputError` for a missing
    required column, a non-numeric or empty value, or time that does not increase."""
    import pandas as pd

    path = Path(path)
    if not path.is_file():
        raise InputError("trial", f"file not found: {path}")
    cols = dict(DEFAULT_COLUMNS)
    for k, v in (columns or {}).items():
        choice("columns", k, list(DEFAULT_COLUMNS))
        cols[k] = v
    uns = dict(DEFAULT_UNITS)
    for k, v in (units or {}).items():
        choice("units", k, list(DEFAULT_UNITS))
        choice(f"units[{k}]", v, list(_FACTORS[_KIND[k]]))
        uns[k] = v
    header = []
    with open_text(path, "trial") as fh:
        for line in fh:
            if line.startswith("#"):
                header.append(line[1:].strip())
            else:
                break
    try:
        df = pd.read_csv(path, comment="#")
    except Exception as e:  # pandas raises many kinds
        raise InputError("trial", f"{path}: not a readable CSV ({e})") from None
    for k, v in (columns or {}).items():
        if v not in df.columns:
            raise InputError("column", f"{k}={v}: {path} has no column {v!r}; it has {list(df.columns)}")
    missing = [f"{cols[k]} ({k})" for k in required if cols[k] not in df.columns]
    if missing:
        raise InputError("trial", f"{path}: missing column(s) {', '.join(missing)}; got {list(df.columns)} "
                                  "(set the names with columns=... / --column VAR=NAME)")
    data = {}
    for k, c in cols.items():
        if c not in df.columns:
            continue
        v = pd.to_numeric(df[c], errors="coerce").to_numpy(float)
        bad = ~np.isfinite(v)
        if bad.any():
            i = int(np.argmax(bad))
            raise InputError("trial", f"{path}: column {c!r} has a missing or non-numeric value at data row {i + 1}")
        data[k] = v * _FACTORS[_KIND[k]][uns[k]]
    if len(data["time"]) < 10:
        raise InputError("trial", f"{path}: need at least 10 samples, got {len(data['time'])}")
    dt = np.diff(data["time"])
    if (dt <= 0).any():
        i = int(np.argmax(dt <= 0))
        raise InputError("trial", f"{path}: time must increase (data row {i + 2} is not after row {i + 1})")
    synthetic = any("synthetic" in h.lower() for h in header)
    return _trial(data, {"source": str(path), "synthetic": int(synthetic), "header": "\n".join(header)})


def _trial(data: dict[str, np.ndarray], attrs: dict) -> xr.Dataset:
    t = data["time"]
    ds = xr.Dataset({k: ("time", np.asarray(v, float)) for k, v in data.items() if k != "time"},
                    coords={"time": t})
    ds["time"].attrs.update(units="s", long_name="time")
    for k in ds.data_vars:
        ds[k].attrs.update(units=INTERNAL_UNITS[k], long_name=LONG_NAMES[k])
    ds.attrs.update(attrs)
    ds.attrs.setdefault("synthetic", 0)
    return ds


def write_trial(trial: xr.Dataset, path: str | Path) -> Path:
    """Write a trial as CSV with the default column names and units (atomically); synthetic
    trials get a '# SYNTHETIC ...' header line."""
    from .io import atomic_write_text

    return atomic_write_text(path, trial_csv_text(trial))


def trial_csv_text(trial: xr.Dataset) -> str:
    """A trial as the CSV text :func:`write_trial` writes."""
    import io as _io

    lines = []
    if int(trial.attrs.get("synthetic", 0)):
        lines.append("# SYNTHETIC trial generated by terradyn (not a measurement): "
                     + trial.attrs.get("generator", ""))
    for h in (trial.attrs.get("header") or "").splitlines():
        if h and "SYNTHETIC" not in h:
            lines.append("# " + h)
    cols = {"time": trial["time"].values / _FACTORS["time"][DEFAULT_UNITS["time"]]}
    for k in DEFAULT_COLUMNS:
        if k != "time" and k in trial:
            cols[k] = trial[k].values / _FACTORS[_KIND[k]][DEFAULT_UNITS[k]]
    import pandas as pd

    df = pd.DataFrame({DEFAULT_COLUMNS[k]: v for k, v in cols.items()})
    fh = _io.StringIO()
    for line in lines:
        fh.write(line + "\n")
    df.to_csv(fh, index=False, float_format="%.8g")
    return fh.getvalue()


# ------------------------------------------------------------------------------ filtering
def sampling_rate(trial: xr.Dataset, tolerance: float = 0.05) -> float:
    """Sampling rate (Hz) from the median time step; raises if the steps vary by more than
    ``tolerance`` (relative) - a Butterworth filter needs uniform sampling."""
    t = np.asarray(trial["time"].values, float)
    dt = np.diff(t)
    med = float(np.median(dt))
    if med <= 0:
        raise InputError("trial", "time must increase")
    if np.max(np.abs(dt - med)) > tolerance * med:
        raise InputError("trial", f"sampling is not uniform (steps {dt.min():.4g}..{dt.max():.4g} s); "
                                  "resample it before filtering")
    return 1.0 / med


def butter_lowpass(x, fs: float, cutoff_hz: float, order: int = 4) -> np.ndarray:
    """Zero-phase Butterworth low-pass of x (n,) sampled at fs (Hz): :func:`terradyn.signal.lowpass`."""
    from .signal import lowpass as _lowpass

    return _lowpass(x, fs, cutoff_hz, order)


def lowpass(trial: xr.Dataset, cutoff_hz: float = 10.0, order: int = 4,
            variables: Sequence[str] | None = None) -> xr.Dataset:
    """A copy of ``trial`` with ``variables`` (default: torque and normal force, those
    present) low-pass filtered (zero-phase Butterworth; sampling rate from the data)."""
    fs = sampling_rate(trial)
    names = list(variables) if variables else [v for v in ("torque", "normal_force") if v in trial]
    out = trial.copy()
    for v in names:
        if v not in trial:
            raise InputError("variables", f"the trial has no {v!r}")
        out[v] = ("time", butter_lowpass(trial[v].values, fs, cutoff_hz, order), trial[v].attrs)
    out.attrs["filter"] = json.dumps({"type": "butterworth low-pass, zero-phase (sosfiltfilt)",
                                      "order": int(order), "cutoff_hz": float(cutoff_hz),
                                      "sampling_hz": fs, "variables": names})
    return out


# ------------------------------------------------------------------------------ RFT model
def rft_foot_forces(angle_deg, length: float, zeta: float = 1.0, medium: str = "poppy LP",
                    width: float = 8.5 * CM, n_elements: int = 100, grid: int = 400):
    """RFT normal force (N, = vertical force Fz on the foot) and torque about the ankle (N m)
    of the foot preset (``geometry.foot``: ankle at the surface) at rotation angles
    ``angle_deg`` (m,). Stresses: generic Li 2013 fit x ``zeta`` (forces are linear in zeta).
    ``medium`` only labels the result. The force depends on the angle alone (quasi-static),
    so it is computed on a grid and interpolated."""
    from . import geometry
    from .media import generic
    from .motion import Rotation
    from .rft.engine import net_forces

    a = finite_array("angle", angle_deg, ndim=1)
    length = positive("length", length, "m")
    zeta = positive("zeta", zeta)
    lo, hi = min(float(a.min()), 0.0) - 1e-3, max(float(a.max()), 0.0) + 1e-3
    rot = Rotation(omega=0.2, hip_height=0.0, theta_start=lo * DEG, theta_end=hi * DEG, n_theta=grid)
    _, fz, tq = net_forces(geometry.foot(length, width, n_elements), rot.trajectory(), generic(1.0))
    g = np.linspace(lo, hi, grid)
    return zeta * np.interp(a, g, fz), zeta * np.interp(a, g, tq)


def _zeta_of(medium: str) -> float:
    from .media import ZETA

    if medium not in ZETA:
        raise InputError("medium", f"no tabulated zeta for {medium!r}; give zeta")
    return float(ZETA[medium])


# ------------------------------------------------------------------------------ synthetic
def synthetic_trial(commanded_deg: float = 3.0, reached_deg: float | None = None,
                    length: float = 27.0 * CM, zeta: float | None = None, medium: str = "poppy LP",
                    offset: float = -0.5, lag: float = 0.02, noise: float = 0.3,
                    torque_noise: float = 0.03, angle_noise: float = 0.005, rate: float = 200.0,
                    duration: float = 6.0, speed_cmd: float = 2.0, tau: float = 0.15,
                    seed: int | np.random.Generator = 0) -> xr.Dataset:
    """A SYNTHETIC trial (no real trials are public): the commanded angle ramps from 0 to
    ``commanded_deg`` at ``speed_cmd`` deg/s starting at 0.5 s; the foot follows with a
    first-order lag ``tau`` (s) and only reaches ``reached_deg`` (default: interpolated from
    the thesis's 3/7/12 -> 0.84/1.7/2.6 deg); the normal force is the RFT force of a foot of
    nominal ``length`` (m) in ``medium`` (generic fit x ``zeta``, default the medium's),
    delayed by ``lag`` (s), plus ``offset`` (N, the sensor bias that makes early samples
    negative) and Gaussian noise ``noise`` (N); the torque is the RFT ankle torque plus noise
    ``torque_noise`` (N m). Sampling ``rate`` Hz for ``duration`` s. Attributes record all of
    it and ``synthetic = 1``."""
    commanded_deg = positive("commanded", commanded_deg, "deg")
    if reached_deg is None:
        reached_deg = float(np.interp(commanded_deg, *THESIS_REACHED))
    reached_deg = in_range("reached", reached_deg, 1e-6, commanded_deg, "deg")
    zeta = _zeta_of(medium) if zeta is None else positive("zeta", zeta)
    rate = positive("rate", rate, "Hz")
    duration = positive("duration", duration, "s")
    for name, v in (("lag", lag), ("noise", noise), ("torque-noise", torque_noise),
                    ("angle-noise", angle_noise)):
        if not (math.isfinite(v) and v >= 0):
            raise InputError(name, f"must be >= 0, got {v!r}")
    from .errors import check_memory

    n_est = duration * rate + 1
    check_memory("rate", n_est * 8 * 40, f"{n_est:,.0f} samples ({duration:g} s at {rate:g} Hz)")
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    n = int(round(duration * rate)) + 1
    if n < 20:
        raise InputError("duration", "gives fewer than 20 samples")
    t = np.arange(n) / rate
    t0 = 0.5
    cmd = np.clip((t - t0) * positive("speed", speed_cmd, "deg/s"), 0.0, commanded_deg)
    speed_c = np.where((t > t0) & (cmd < commanded_deg), speed_cmd, 0.0)
    # First-order response (exact discretisation), scaled to the angle actually reached.
    a = np.exp(-1.0 / (rate * positive("tau", tau, "s")))
    resp = np.empty(n)
    resp[0] = 0.0
    for i in range(1, n):  # n ~ 1e3: a scalar recursion is clearer than lfilter here
        resp[i] = a * resp[i - 1] + (1 - a) * cmd[i]
    angle = resp * (reached_deg / commanded_deg)
    speed = np.gradient(angle, t)
    fz, tq = rft_foot_forces(np.interp(t - lag, t, angle), length, zeta)
    data = {"time": t, "angle_cmd": cmd, "angle": angle + angle_noise * rng.standard_normal(n),
            "speed_cmd": speed_c, "speed": speed, "torque": tq + torque_noise * rng.standard_normal(n),
            "normal_force": fz + offset + noise * rng.standard_normal(n)}
    truth = {"length_m": length, "zeta": zeta, "offset_N": offset, "lag_s": lag, "noise_N": noise,
             "torque_noise_Nm": torque_noise, "medium": medium, "commanded_deg": commanded_deg,
             "reached_deg": reached_deg, "rate_hz": rate, "seed": seed if isinstance(seed, int) else None}
    gen = "RFT foot model + noise, bias and lag; truth: " + json.dumps(truth)
    return _trial(data, {"synthetic": 1, "generator": gen, "truth": json.dumps(truth),
                         "source": "terradyn.experiment.synthetic_trial",
                         "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")})


# ------------------------------------------------------------------------------ comparison
def compare(trial: xr.Dataset, length: float = 27.0 * CM, zeta: float | None = None,
            medium: str = "poppy LP", offset: float = 0.0, cutoff_hz: float = 10.0,
            order: int = 4) -> xr.Dataset:
    """Raw, filtered and RFT model (at the trial's actual angles) normal force - and torque
    when the trial has it - on the trial's time base. attrs: mean square error and peak
    difference of filtered vs model (N^2, N; N^2 m^2, N m)."""
    if "angle" not in trial or "normal_force" not in trial:
        raise InputError("trial", "needs the actual angle and the normal force")
    zeta = _zeta_of(medium) if zeta is None else positive("zeta", zeta)
    filt = lowpass(trial, cutoff_hz, order)
    fz, tq = rft_foot_forces(trial["angle"].values, length, zeta, medium)
    out = xr.Dataset(coords={"time": trial["time"].values})
    out["angle"] = ("time", trial["angle"].values, {"units": "deg"})
    stats = {}
    for v, model in (("normal_force", fz + offset), ("torque", tq)):
        if v not in trial:
            continue
        out[f"{v}_raw"] = ("time", trial[v].values, trial[v].attrs)
        out[f"{v}_filtered"] = ("time", filt[v].values, trial[v].attrs)
        out[f"{v}_model"] = ("time", model, trial[v].attrs)
        stats[f"{v}_mse"] = mse_values(filt[v].values, model)
        stats[f"{v}_peak_difference"] = peak_of(filt[v].values)[0] - peak_of(model)[0]
    out.attrs.update(stats)
    out.attrs.update(model=json.dumps({"length_m": length, "zeta": zeta, "offset_N": offset, "medium": medium}),
                     filter=filt.attrs["filter"], synthetic=int(trial.attrs.get("synthetic", 0)),
                     source=trial.attrs.get("source", ""))
    return out


CAL_PARAMS = ("length", "zeta", "offset")


def calibrate(trial: xr.Dataset, params: Sequence[str] = ("length", "offset"),
              use: Sequence[str] = ("normal_force",), initial: dict[str, float] | None = None,
              medium: str = "poppy LP", bounds: dict[str, tuple[float, float]] | None = None) -> dict:
    """Least-squares calibration of the RFT foot model to a trial (raw samples).

    ``params``: which of length (m), zeta and offset (N, added to the normal force) to fit;
    the others stay at ``initial`` (defaults: 25 cm, the medium's zeta, 0 N). ``use``: the
    channels fitted ("normal_force", "torque"), each residual divided by that channel's noise
    level (estimated from the raw - low-passed signal). The normal force alone scales as
    zeta L^2, so it cannot separate length from zeta: fitting both needs the torque too
    (~ zeta L^3). Returns a dict: ``values``, ``std`` (standard errors from the Jacobian at the
    optimum, s^2 (J^T J)^-1), ``correlation``, ``rms`` (weighted residual), ``n``,
    ``success``, ``message``."""
    from scipy.optimize import least_squares

    params = list(dict.fromkeys(params))
    if not params:
        raise InputError("params", "name at least one of length, zeta, offset")
    for p in params:
        choice("params", p, list(CAL_PARAMS))
    use = list(dict.fromkeys(use))
    for u in use:
        choice("use", u, ["normal_force", "torque"])
        if u not in trial:
            raise InputError("use", f"the trial has no {u!r}")
    if "length" in params and "zeta" in params and "torque" not in use:
        raise InputError("params", "length and zeta are not separately identifiable from the normal force "
                                   "alone (it scales as zeta L^2): fit one of them, or add the torque to `use`")
    if "offset" in params and "normal_force" not in use:
        raise InputError("params", "the offset applies to the normal force: add it to `use`")
    x0 = {"length": 25.0 * CM, "zeta": _zeta_of(medium) if medium in _zetas() else 1.0, "offset": 0.0}
    for k, v in (initial or {}).items():
        choice("initial", k, list(CAL_PARAMS))
        x0[k] = float(v)
    bnd = {"length": (5 * CM, 100 * CM), "zeta": (1e-3, 10.0), "offset": (-1e3, 1e3)}
    bnd.update(bounds or {})
    angle = np.asarray(trial["angle"].values, float)
    fs = sampling_rate(trial)
    sig = {}
    for u in use:
        raw = trial[u].values
        hp = raw - butter_lowpass(raw, fs, min(fs / 20, 0.45 * fs))
        sig[u] = max(float(np.std(hp)), 1e-9 * max(1.0, float(np.abs(raw).max())))
    obs = {u: np.asarray(trial[u].values, float) for u in use}

    def unpack(x):
        v = dict(x0)
        v.update(zip(params, x))
        return v

    def resid(x):
        v = unpack(x)
        fz, tq = rft_foot_forces(angle, v["length"], v["zeta"], medium)
        r = []
        if "normal_force" in use:
            r.append((fz + v["offset"] - obs["normal_force"]) / sig["normal_force"])
        if "torque" in use:
            r.append((tq - obs["torque"]) / sig["torque"])
        return np.concatenate(r)

    start = np.array([x0[p] for p in params])
    lo = np.array([bnd[p][0] for p in params])
    hi = np.array([bnd[p][1] for p in params])
    if ((start < lo) | (start > hi)).any():
        raise InputError("initial", f"initial values {dict(zip(params, start))} outside the bounds")
    res = least_squares(resid, start, bounds=(lo, hi), x_scale="jac", diff_step=1e-4)
    J = res.jac
    n, p = J.shape
    s2 = float(2 * res.cost / max(n - p, 1))
    try:
        cov = np.linalg.inv(J.T @ J) * s2
    except np.linalg.LinAlgError:
        cov = np.full((p, p), np.nan)
    std = np.sqrt(np.clip(np.diag(cov), 0, None))
    corr = cov / np.outer(std, std) if np.all(std > 0) else np.full((p, p), np.nan)
    v = unpack(res.x)
    return {"values": {k: float(v[k]) for k in CAL_PARAMS},
            "fitted": params, "std": {k: float(s) for k, s in zip(params, std)},
            "correlation": corr.tolist(), "rms": float(math.sqrt(s2)), "n": int(n),
            "noise_estimate": sig, "success": bool(res.success), "message": str(res.message),
            "medium": medium, "synthetic": int(trial.attrs.get("synthetic", 0))}


def _zetas():
    from .media import ZETA

    return ZETA


def to_force_series(trial: xr.Dataset, variable: str = "normal_force", monotonic: bool = True) -> xr.Dataset:
    """The trial's normal force as an observation set on the foot's ``theta`` (deg, the actual
    angle): a Dataset with coordinate ``theta`` and ``Fz`` (N) (NaN where missing), plus
    ``time``. Samples before the angle first rises (and, with ``monotonic``, any that do not
    advance the angle) are dropped, so theta increases."""
    if variable not in trial or "angle" not in trial:
        raise InputError("trial", f"needs the angle and {variable!r}")
    a = np.asarray(trial["angle"].values, float)
    y = np.asarray(trial[variable].values, float)
    t = np.asarray(trial["time"].values, float)
    keep = np.zeros(len(a), bool)
    last = -np.inf
    for i in range(len(a)):  # running maximum: a few thousand samples
        if a[i] > last:
            keep[i] = True
            last = a[i]
    if not monotonic:
        keep[:] = True
    if keep.sum() < 2:
        raise InputError("trial", "the angle never increases")
    ds = xr.Dataset({"Fz": ("theta", y[keep], {"units": "N"})},
                    coords={"theta": ("theta", a[keep], {"units": "deg"}), "time": ("theta", t[keep], {"units": "s"})})
    ds.attrs.update(synthetic=int(trial.attrs.get("synthetic", 0)), source=trial.attrs.get("source", ""))
    return ds
