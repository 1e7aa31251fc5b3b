"""3D RFT as force series (the 3D schema: Fx, Fy, Fz in N, Tx, Ty, Tz in N m along ``time``)."""
from __future__ import annotations

import numpy as np
import xarray as xr

from ..errors import InputError, choice
from ..series import force_series
from ..units import DEG
from .body import Body
from .engine import element_tractions, wrench_batch
from .model import Medium3D, medium3d

MODELS = ("agarwal", "treers")
UNITS3D = {"Fx": "N", "Fy": "N", "Fz": "N", "Tx": "N m", "Ty": "N m", "Tz": "N m", "angle": "deg"}
LONG3D = {"Fx": "force along x (+ forward)", "Fy": "force along y (+ left)",
          "Fz": "force along z (+ up)", "Tx": "torque about x", "Ty": "torque about y",
          "Tz": "torque about z", "angle": "rotation angle about the motion's axis"}


def _resolve_medium(medium) -> Medium3D:
    if isinstance(medium, str):
        return medium3d(medium)
    return medium


def compute(body: Body, motion, medium, model: str = "agarwal", surface: float = 0.0,
            point=None, dynamic_lambda: float | None = None, stress_model=None,
            surface_correction=None, elements: bool = False, parallel: bool | None = None):
    """Wrenches (S, 6) of ``body`` following ``motion`` (anything with ``poses()``), and the
    poses; with ``elements=True`` also the per-element dict of
    :func:`terradyn.rft3d.engine.element_tractions` (NumPy path)."""
    choice("model", model, MODELS)
    p = motion.poses()
    med = None
    if model == "agarwal":
        med = _resolve_medium(medium)
        if elements or surface_correction is not None:
            el = element_tractions(body, p.position, p.quaternion, p.velocity, p.angular_velocity,
                                   med, surface, point, dynamic_lambda, surface_correction)
            return el["wrench"], p, el
        w = wrench_batch(body, p.position, p.quaternion, p.velocity, p.angular_velocity, med,
                         surface, point, dynamic_lambda, parallel=parallel)
        return w, p, None
    from .treers import treers_elements

    from ..media import MEDIA

    rho = (MEDIA[medium].bulk_density if isinstance(medium, str) and medium in MEDIA
           else getattr(medium, "bulk_density", None))
    el = treers_elements(body, p, stress_model if stress_model is not None else medium, surface,
                         point, dynamic_lambda, surface_correction, bulk_density=rho)
    return el["wrench"], p, (el if elements else None)


def simulate(body: Body, motion, medium, *, model: str = "agarwal", surface: float = 0.0,
             point=None, dynamic_lambda: float | None = None, stress_model=None,
             surface_correction=None, parallel: bool | None = None) -> xr.Dataset:
    """3D-RFT force series of ``body`` following ``motion`` in ``medium``.

    body: :class:`~terradyn.rft3d.body.Body`; motion: :class:`RigidMotion`,
    :class:`AxisRotation`, :class:`PlanarAs3D` (anything with ``poses()``); medium: a
    :class:`Medium3D` or a Li 2013 medium name (model ``agarwal``), or for ``treers`` a medium
    name / 2D stress model (``stress_model`` overrides). Options: ``surface`` (m),
    ``point`` torque reference (3,) m world (default: body-frame origin), ``dynamic_lambda``
    (dynamic RFT), ``surface_correction`` hook (see ``element_tractions``).

    Returns an xarray Dataset along ``time`` (s) with Fx, Fy, Fz (N) and Tx, Ty, Tz (N m)
    (and ``angle`` in deg for rotations); attrs record the full input.
    """
    w, p, _ = compute(body, motion, medium, model, surface, point, dynamic_lambda, stress_model,
                      surface_correction, parallel=parallel)
    return wrench_series(w, p, body, motion, medium, model, surface, point, dynamic_lambda,
                         stress_model)


def wrench_series(w, p, body, motion, medium, model, surface, point, dynamic_lambda,
                  stress_model=None) -> xr.Dataset:
    """A 3D force series from wrenches (S, 6) and poses."""
    med = medium
    if model == "agarwal":
        med = _resolve_medium(medium)
    mdesc = med.describe() if hasattr(med, "describe") else str(med)
    inputs = {"body": body.describe(), "motion": motion.describe(), "medium": mdesc,
              "model": model, "surface_m": float(np.mean(surface)),
              "point_m": None if point is None else np.asarray(point, float).tolist(),
              "dynamic_lambda": dynamic_lambda,
              "stress_model": (stress_model.describe() if hasattr(stress_model, "describe")
                               else None if stress_model is None else str(stress_model))}
    extra = {"Fy": w[:, 1], "Tx": w[:, 3], "Ty": w[:, 4], "Tz": w[:, 5]}
    ds = force_series("time", p.time, w[:, 0], w[:, 2], None, model=f"rft3d-{model}",
                      inputs=inputs, extra=extra)
    ds = ds[["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]].assign_attrs(ds.attrs)
    if p.angle is not None:
        ds = ds.assign_coords(angle=("time", p.angle / DEG))
    for v in list(ds.data_vars) + ["angle"]:
        if v in ds.variables:
            ds[v].attrs.update(units=UNITS3D[v], long_name=LONG3D[v])
    ds.attrs["medium"] = getattr(med, "name", str(med))
    ds.attrs["leg"] = body.name
    ds.attrs["body"] = body.name
    return ds


def element_dataset(el: dict, p, body: Body, series: xr.Dataset) -> xr.Dataset:
    """Per-element results as an xarray Dataset along (time, element): traction_x/y/z
    (N/m^2), force_x/y/z (N), depth (m), centroid x/y/z (m, world) and ``active``; element
    coordinates area (m^2) and body-frame centroid; attrs of the force series ``series``."""
    data = {}
    for k, name, unit in (("traction", "traction", "N/m^2"), ("force", "force", "N"),
                          ("r", "centroid", "m")):
        for i, c in enumerate("xyz"):
            data[f"{name}_{c}"] = (("time", "element"), el[k][..., i], {"units": unit})
    data["depth"] = (("time", "element"), el["depth"], {"units": "m"})
    data["active"] = (("time", "element"), el["active"].astype(np.int8),
                      {"long_name": "submerged, moving and leading (1) or not (0)"})
    ds = xr.Dataset(data, coords={"time": ("time", p.time, {"units": "s"}),
                                  "element": np.arange(len(body)),
                                  "area": ("element", body.areas, {"units": "m^2"})})
    ds.attrs.update(series.attrs)
    ds.attrs["content"] = "per-element 3D-RFT tractions (force of the medium on the body per area)"
    return ds


def element_frame(body: Body, motion, medium, index: int, **options) -> dict:
    """Per-element result at one sample of ``motion`` (for figures): the dict of
    ``element_tractions`` reduced to sample ``index``."""
    w, p, el = compute(body, motion, medium, elements=True, **options)
    if not -len(p) <= index < len(p):
        raise InputError("frame", f"must be in [0, {len(p) - 1}], got {index}")
    return {k: v[index] for k, v in el.items()}
