"""RFT (Li, Zhang & Goldman 2013) as a registered model: quasi-static, rate-independent."""
from __future__ import annotations

import json
from functools import lru_cache

from ..errors import InputError
from ..media import ALPHA_SOURCES, INTERPOLATORS, ZETA
from . import Model, Option, ignored

OPTIONS = (
    Option("alpha", str, "fit", choices=ALPHA_SOURCES,
           help="Stress coefficients: the medium's Fourier fit, the generic fit x zeta, or the measured table."),
    Option("zeta", float, None, lo=0, lo_open=True, help="Scale of the generic fit (alpha generic)."),
    Option("interp", str, None, choices=INTERPOLATORS, help="Interpolator of the table (alpha table; default linear)."),
    Option("table_file", str, None, help="Your own measured grid (Table S5 CSV format; alpha table)."),
    Option("dynamic_lambda", float, None, lo=0, hi=10,
           help="Dynamic-RFT lambda: adds lambda rho (v.n)^2 per area (Agarwal et al. 2021; rho the "
                "medium's bulk density, Li 2013 Table S1). Unset: quasi-static."),
)


@lru_cache(maxsize=64)
def _model(key: str):
    from ..media import stress_model

    o = json.loads(key)
    return stress_model(o["medium"], alpha=o["alpha"], zeta=o.get("zeta"),
                        interp=o.get("interp") or "linear", table_file=o.get("table_file"))


def stress_model_of(medium: str, alpha: str = "fit", zeta=None, interp=None, table_file=None):
    """The stress model of the options (cached); options that have no effect are warned about."""
    if alpha != "table":
        for name, v in (("interp", interp), ("table-file", table_file)):
            if v is not None:
                ignored(name, f"has no effect without alpha 'table' (alpha is {alpha!r})")
        interp = table_file = None
    key = {"medium": medium, "alpha": alpha, "zeta": zeta, "interp": interp,
           "table_file": None if table_file is None else str(table_file)}
    return _model(json.dumps(key, sort_keys=True))


def _dynamic(medium: str, lam):
    """``(lambda, bulk density)`` for the dynamic term of a named medium (None: quasi-static)."""
    if lam is None:
        return None
    from ..media import MEDIA

    if medium not in MEDIA:
        raise InputError("dynamic-lambda", f"needs a medium with a measured bulk density ({', '.join(MEDIA)}), "
                                           f"got {medium!r}")
    return float(lam), MEDIA[medium].bulk_density


def _simulate(body, motion, medium, *, alpha="fit", zeta=None, interp=None, table_file=None,
              dynamic_lambda=None):
    from ..rft import simulate

    if not isinstance(medium, str):  # a stress model object: the options do not apply
        for name, v in (("alpha", alpha if alpha != "fit" else None), ("zeta", zeta), ("interp", interp),
                        ("table-file", table_file), ("dynamic-lambda", dynamic_lambda)):
            if v is not None:
                ignored(name, "has no effect when the medium is given as a stress model")
        return simulate(body, motion, medium, getattr(medium, "name", None))
    dyn = _dynamic(medium, dynamic_lambda)
    return simulate(body, motion, stress_model_of(medium, alpha, zeta, interp, table_file), medium,
                    dynamic=dyn)


def _resolve(opts: dict) -> dict:
    """The sweep form: medium, alpha and only the options that apply (errors for others)."""
    medium = opts.pop("medium", None)
    if medium is None:
        raise InputError("model.medium", "missing; name the granular medium")
    o = MODEL.check_options(opts, field=lambda k: f"model.{k}")
    alpha = o.get("alpha", "fit")
    out = {"medium": medium, "alpha": alpha}
    if alpha == "generic":
        out["zeta"] = o.get("zeta", ZETA.get(medium))
    elif "zeta" in o:
        raise InputError("model.zeta", "only applies with alpha = 'generic'")
    if alpha == "table":
        out["interp"] = o.get("interp", "linear")
        if "table_file" in o:
            out["table_file"] = o["table_file"]
    else:
        for k in ("interp", "table_file"):
            if k in o:
                raise InputError(f"model.{k}", "only applies with alpha = 'table'")
    if "dynamic_lambda" in o:
        out["dynamic_lambda"] = o["dynamic_lambda"]
        try:
            _dynamic(medium, o["dynamic_lambda"])
        except InputError as e:
            raise InputError("model.dynamic_lambda", str(e).split(": ", 1)[-1]) from None
    try:
        stress_model_of(medium, **{k: v for k, v in out.items() if k not in ("medium", "dynamic_lambda")})
    except InputError as e:
        raise InputError(f"model.{e.field}", str(e).split(": ", 1)[-1]) from None
    return out


MODEL = Model("rft", _simulate, OPTIONS, resolve_fn=_resolve,
              description="Resistive force theory: quasi-static stress per depth from measured coefficients.")
