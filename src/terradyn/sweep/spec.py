"""Sweep specifications: a TOML file -> a list of fully resolved cases with stable ids.

A spec names the model, the base parameters and the parameters to vary::

    [sweep]
    name = "rft-foot-lengths"        # label of the sweep (default: the file's stem)
    model = "rft"                    # a registered model: terradyn.models.names()

    [leg]                            # shape (flat, c, reverse-c, foot), length_cm, width_cm,
    shape = "foot"                   # elements, curvature
    width_cm = 8.5

    [motion]                         # kind = "rotation": omega_rad_s, hip_height_cm,
    kind = "foot"                    #   theta_start_deg, theta_end_deg, n_theta
    max_deg = 3.0                    # kind = "foot": max_deg, n_theta, omega_rad_s

    [model]                          # medium + the model's options (terradyn.models):
    medium = "poppy LP"              #   rft: alpha (fit|generic|table), zeta, interp, table_file
                                     #   sph: quick, dx_mm, hdx, cfl, av_alpha, av_beta,
                                     #   wall_layers, noslip, settle_time_s, lowpass_hz,
                                     #   thickness_cm, bed_width_cm, bed_depth_cm, ...

    [grid]                           # Cartesian product of every list here
    leg.length_cm = {start = 25, stop = 35, step = 1}

    [[zip]]                          # lists of equal length varied together; each [[zip]]
    leg.shape = ["flat", "c"]        # group is one axis of the product with [grid]
    leg.curvature = [0.0, 1.0]

A value to vary is a list, ``{start, stop, step}`` (stop included) or ``{start, stop, num}``
(numpy.linspace). Every case is resolved (defaults filled in, the foot motion written as the
rotation it is, numbers canonicalised) and its id is a hash of that resolved description, so
the same case always has the same id whichever way it was written.

Field units (cm, deg) are kept in the parameter names, as in the CLI; :func:`build` turns a
case into SI objects.
"""
from __future__ import annotations

import hashlib
import itertools
import json
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import InputError
from ..units import CM, DEG

from .. import models as _models

SECTIONS = ("sweep", "leg", "motion", "model", "grid", "zip")
SWEEP_KEYS = {"name": str, "model": str, "description": str}

_NUM = (int, float)
#: Allowed keys per parameter section and their types (float fields accept ints).
LEG_KEYS = {"shape": str, "length_cm": float, "width_cm": float, "elements": int, "curvature": float}
MOTION_KEYS = {
    "rotation": {"kind": str, "omega_rad_s": float, "hip_height_cm": float, "theta_start_deg": float,
                 "theta_end_deg": float, "n_theta": int},
    "foot": {"kind": str, "max_deg": float, "n_theta": int, "omega_rad_s": float},
}
#: Largest number of cases a spec may expand to (each case is a simulation and a file).
MAX_CASES = 100_000


def model_keys(model: str) -> dict:
    """The ``[model]`` keys of a registered model and their types: ``medium`` and its options."""
    return {"medium": str} | {o.name: o.kind for o in _models.get(model, "sweep.model").options}


ID_LENGTH = 12


@dataclass(frozen=True)
class Case:
    """One resolved case: ``id`` (hex), ``params`` (nested dict, field units, JSON-able) and
    ``varied`` (dotted parameter path -> value, for the parameters the sweep varies)."""

    id: str
    params: dict
    varied: dict

    def to_json(self) -> dict:
        return {"id": self.id, "params": self.params, "varied": self.varied}


@dataclass(frozen=True)
class SweepSpec:
    """A parsed spec: ``name``, ``model``, ``base`` params, the varied axes and the TOML text."""

    name: str
    model: str
    base: dict
    axes: list  # list of dicts: dotted path -> list of values (one dict per product axis)
    text: str = ""
    description: str = ""
    source: str = ""
    cases: list = field(default_factory=list)

    @property
    def varied(self) -> list[str]:
        """Dotted paths of the varied parameters, in spec order."""
        return [p for ax in self.axes for p in ax]


# ------------------------------------------------------------------------------------------
# parsing
# ------------------------------------------------------------------------------------------
def load(path: str | Path) -> SweepSpec:
    """Read and expand a sweep spec TOML file (raises :class:`InputError` naming the key)."""
    path = Path(path)
    if not path.is_file():
        raise InputError("spec", f"file not found: {path}")
    text = path.read_text()
    return parse(text, name=path.stem, source=str(path))


def parse(text: str, name: str = "sweep", source: str = "<string>") -> SweepSpec:
    """Parse a sweep spec from TOML text and expand it into cases."""
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise InputError("spec", f"{source}: not valid TOML ({e})") from None
    return from_dict(doc, name=name, source=source, text=text)


def from_dict(doc: dict, name: str = "sweep", source: str = "<dict>", text: str = "") -> SweepSpec:
    """Build a spec from an already-parsed TOML document (same layout as the file)."""
    for k in doc:
        if k not in SECTIONS:
            raise InputError(k, f"unknown section; allowed: {', '.join(SECTIONS)}")
    sw = _table(doc, "sweep")
    for k, v in sw.items():
        _check_type(f"sweep.{k}", v, SWEEP_KEYS.get(k), SWEEP_KEYS)
    model = sw.get("model")
    if model is None:
        raise InputError("sweep.model", f"missing; one of {', '.join(_models.names())}")
    _models.get(model, "sweep.model")
    name = check_name(sw["name"], "sweep.name") if "name" in sw else name
    base = {"leg": _table(doc, "leg"), "motion": _table(doc, "motion"), "model": _table(doc, "model")}
    axes = []
    grid = _table(doc, "grid")
    for p, vals in _flatten(grid, "grid"):
        axes.append({p: _values(f"grid.{p}", vals)})
    zips = doc.get("zip", [])
    if isinstance(zips, dict):
        zips = [zips]
    if not isinstance(zips, list) or not all(isinstance(z, dict) for z in zips):
        raise InputError("zip", "must be [[zip]] tables of equal-length lists")
    for i, z in enumerate(zips):
        group = {p: _values(f"zip[{i}].{p}", v) for p, v in _flatten(z, f"zip[{i}]")}
        if not group:
            raise InputError(f"zip[{i}]", "is empty")
        lens = {p: len(v) for p, v in group.items()}
        if len(set(lens.values())) > 1:
            raise InputError(f"zip[{i}]", f"lists must have equal lengths, got {lens}")
        axes.append(group)
    seen: set[str] = set()
    for ax in axes:
        for p in ax:
            if p in seen:
                raise InputError(p, "is varied twice (in [grid] and/or [[zip]])")
            seen.add(p)
            _check_path(p, model)
    n_cases = math.prod(len(next(iter(ax.values()))) for ax in axes) if axes else 1
    if n_cases > MAX_CASES:
        raise InputError("grid", f"expands to {n_cases:,} cases, more than the limit {MAX_CASES:,} "
                                 "(one simulation and one file each); split the sweep")
    spec = SweepSpec(name=name, model=model, base=base, axes=axes, text=text,
                     description=sw.get("description", ""), source=source)
    spec.cases.extend(expand(spec))
    return spec


def check_name(name: str, field: str = "sweep.name") -> str:
    """A sweep name usable as a directory name in the working folder: no path separators,
    no leading '.', no control characters, at most 100 characters."""
    if not isinstance(name, str) or not name.strip() or name.startswith(".") or len(name) > 100 \
            or any(c in name for c in "/\\") or any(ord(c) < 32 for c in name):
        raise InputError(field, f"{name!r} is not a plain name (it names the store folder): "
                                "no '/' or '\\', no leading '.', 1-100 characters")
    return name


def _table(doc: dict, key: str) -> dict:
    v = doc.get(key, {})
    if not isinstance(v, dict):
        raise InputError(key, f"must be a table [{key}], got {type(v).__name__}")
    return v


def _is_range(v) -> bool:
    return isinstance(v, dict) and "start" in v and "stop" in v


def _flatten(d: dict, prefix: str, path: str = ""):
    for k, v in d.items():
        p = f"{path}.{k}" if path else k
        if isinstance(v, dict) and not _is_range(v):
            yield from _flatten(v, prefix, p)
        else:
            yield p, v


def _values(key: str, v) -> list:
    if _is_range(v):
        extra = set(v) - {"start", "stop", "step", "num"}
        if extra:
            raise InputError(f"{key}.{sorted(extra)[0]}", "unknown key; a range has start, stop and step or num")
        if ("step" in v) == ("num" in v):
            raise InputError(key, "a range needs exactly one of step or num")
        if "num" in v and isinstance(v["num"], int) and v["num"] > MAX_CASES:
            raise InputError(f"{key}.num", f"must be <= {MAX_CASES:,} (the case limit), got {v['num']!r}")
        for k in v:
            if not isinstance(v[k], _NUM) or isinstance(v[k], bool):
                raise InputError(f"{key}.{k}", f"must be a number, got {v[k]!r}")
        a, b = float(v["start"]), float(v["stop"])
        if "num" in v:
            n = v["num"]
            if not isinstance(n, int) or n < 1:
                raise InputError(f"{key}.num", f"must be an integer >= 1, got {n!r}")
            vals = [a + (b - a) * i / (n - 1) for i in range(n)] if n > 1 else [a]
        else:
            s = float(v["step"])
            if s == 0 or not math.isfinite(s) or (b - a) * s < 0:
                raise InputError(f"{key}.step", f"must be non-zero and point from start to stop, got {v['step']!r}")
            n = int(math.floor((b - a) / s + 1e-9)) + 1
            if n > MAX_CASES:
                raise InputError(key, f"expands to {n:,} values, more than the case limit {MAX_CASES:,}")
            vals = [a + i * s for i in range(n)]
        return [_canon(x) for x in vals]
    if not isinstance(v, list):
        raise InputError(key, f"must be a list of values or a range {{start, stop, step|num}}, got {v!r}")
    if not v:
        raise InputError(key, "is empty: nothing to sweep over")
    return list(v)


def _check_path(p: str, model: str) -> None:
    sec, _, key = p.partition(".")
    allowed = {"leg": LEG_KEYS, "motion": {k for m in MOTION_KEYS.values() for k in m},
               "model": model_keys(model)}
    if sec not in allowed:
        raise InputError(p, "only leg.*, motion.* and model.* parameters can be varied")
    if key not in allowed[sec] or key == "kind":
        raise InputError(p, f"unknown parameter; {sec} has {', '.join(k for k in allowed[sec] if k != 'kind')}")


def _check_type(key: str, v, typ, allowed: dict) -> None:
    if typ is None:
        raise InputError(key, f"unknown key; allowed: {', '.join(allowed)}")
    ok = (isinstance(v, _NUM) and not isinstance(v, bool)) if typ is float else \
        (isinstance(v, int) and not isinstance(v, bool)) or (isinstance(v, float) and v.is_integer()) \
        if typ is int else isinstance(v, typ)
    if not ok:
        raise InputError(key, f"must be {_TYPE_NAMES[typ]}, got {v!r}")


_TYPE_NAMES = {float: "a number", int: "an integer", str: "a string", bool: "true or false"}


def _canon(x: float) -> float:
    """Round to 12 significant digits so 0.1 + 0.2 and 0.3 are the same parameter."""
    return float(f"{float(x):.12g}")


# ------------------------------------------------------------------------------------------
# expansion and resolution
# ------------------------------------------------------------------------------------------
def expand(spec: SweepSpec) -> list[Case]:
    """All cases of the spec (product over the axes, zipped within an axis), resolved."""
    axes = [[{p: vals[i] for p, vals in ax.items()} for i in range(len(next(iter(ax.values()))))]
            for ax in spec.axes]
    cases, ids = [], {}
    for combo in itertools.product(*axes) if axes else [()]:
        varied: dict[str, Any] = {}
        for d in combo:
            varied.update(d)
        raw = json.loads(json.dumps(spec.base))  # deep copy
        for p, v in varied.items():
            sec, _, key = p.partition(".")
            raw[sec][key] = v
        params = resolve(spec.model, raw)
        cid = case_id(params)
        flat = _flat_params(params)
        varied = {p: flat.get(p, v) for p, v in varied.items()}
        if cid in ids:
            raise InputError("grid", f"cases {ids[cid]} and {varied} resolve to the same parameters")
        ids[cid] = varied
        cases.append(Case(cid, params, varied))
    return cases


def _flat_params(params: dict) -> dict:
    return {f"{s}.{k}": v for s, d in params.items() if isinstance(d, dict) for k, v in d.items()}


def case_id(params: dict) -> str:
    """Stable id of a resolved case: the first 12 hex digits of SHA-256 of its sorted JSON."""
    blob = json.dumps(params, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(blob.encode()).hexdigest()[:ID_LENGTH]


def _typed(sec: str, d: dict, keys: dict) -> dict:
    out = {}
    for k, v in d.items():
        _check_type(f"{sec}.{k}", v, keys.get(k), keys)
        t = keys[k]
        out[k] = _canon(v) if t is float else int(v) if t is int else v
    return out


def resolve(model: str, raw: dict) -> dict:
    """Fill defaults and canonicalise one case's parameters (field units); raises
    :class:`InputError` naming the key of any bad value."""
    from .. import geometry, motion as mo

    leg = _typed("leg", raw.get("leg", {}), LEG_KEYS)
    shape = leg.get("shape")
    if shape is None:
        raise InputError("leg.shape", f"missing; one of {', '.join(geometry.LEG_SHAPES)}")
    if shape not in geometry.LEG_SHAPES:
        raise InputError("leg.shape", f"unknown leg {shape!r}; allowed: {', '.join(geometry.LEG_SHAPES)}")
    try:
        obj = geometry.make_leg(shape, length=leg["length_cm"] * CM if "length_cm" in leg else None,
                                width=leg["width_cm"] * CM if "width_cm" in leg else None,
                                n=leg.get("elements", 100), curvature=leg.get("curvature"))
    except InputError as e:
        raise InputError(f"leg.{_FIELD_ALIASES.get(e.field, e.field)}", str(e).split(": ", 1)[-1]) from None
    leg_r = {"shape": shape, "length_cm": _canon(obj.chord / CM), "width_cm": _canon(obj.width / CM),
             "elements": int(obj.n_elements), "curvature": _canon(obj.curvature)}

    m = dict(raw.get("motion", {}))
    kind = m.get("kind", "rotation")
    if kind not in MOTION_KEYS:
        raise InputError("motion.kind", f"unknown motion {kind!r}; allowed: {', '.join(MOTION_KEYS)}")
    m = _typed("motion", m, MOTION_KEYS[kind])
    try:
        if kind == "foot":
            rot = mo.foot_rotation(m.get("max_deg", 3.0), m.get("n_theta", 61), m.get("omega_rad_s", 0.2))
        else:
            std = mo.standard_rotation()
            rot = mo.Rotation(omega=m.get("omega_rad_s", std.omega),
                              hip_height=m.get("hip_height_cm", std.hip_height / CM) * CM,
                              theta_start=m.get("theta_start_deg", std.theta_start / DEG) * DEG,
                              theta_end=m.get("theta_end_deg", std.theta_end / DEG) * DEG,
                              n_theta=m.get("n_theta", std.n_theta))
    except InputError as e:
        raise InputError(f"motion.{_FIELD_ALIASES.get(e.field, e.field)}", str(e).split(": ", 1)[-1]) from None
    motion_r = {"kind": "rotation", "omega_rad_s": _canon(rot.omega),
                "hip_height_cm": _canon(rot.hip_height / CM),
                "theta_start_deg": _canon(rot.theta_start / DEG), "theta_end_deg": _canon(rot.theta_end / DEG),
                "n_theta": int(rot.n_theta)}

    opts = _typed("model", raw.get("model", {}), model_keys(model))
    model_r = _models.get(model, "sweep.model").resolve(opts)
    return {"leg": leg_r, "motion": motion_r, "model": model_r}


_FIELD_ALIASES = {"length": "length_cm", "width": "width_cm", "elements": "elements",
                  "omega": "omega_rad_s", "hip-height": "hip_height_cm", "theta-start": "theta_start_deg",
                  "theta-end": "theta_end_deg", "n-theta": "n_theta", "theta range": "theta_end_deg"}


def build(params: dict):
    """SI objects of a resolved case: (leg, motion)."""
    from .. import geometry, motion as mo

    lg, m = params["leg"], params["motion"]
    leg = geometry.make_leg(lg["shape"], length=lg["length_cm"] * CM, width=lg["width_cm"] * CM,
                            n=lg["elements"], curvature=lg["curvature"])
    rot = mo.Rotation(omega=m["omega_rad_s"], hip_height=m["hip_height_cm"] * CM,
                      theta_start=m["theta_start_deg"] * DEG, theta_end=m["theta_end_deg"] * DEG,
                      n_theta=m["n_theta"])
    return leg, rot
