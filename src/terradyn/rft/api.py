"""RFT as force series: the functions users call."""
from __future__ import annotations

import numpy as np
import xarray as xr

from ..geometry import Leg
from ..media import StressModel
from ..motion import PlanarMotion, Rotation
from ..series import force_series
from ..units import DEG
from .engine import batch_forces, net_forces


def _inputs(leg: Leg, motion, model: StressModel, medium: str | None) -> dict:
    return {"leg": leg.describe(), "motion": motion.describe(),
            "stress_model": model.describe() if hasattr(model, "describe") else repr(model),
            "medium": medium or getattr(model, "name", "custom")}


def simulate(leg: Leg, motion: Rotation | PlanarMotion, model: StressModel,
             medium: str | None = None, dynamic: tuple[float, float] | None = None) -> xr.Dataset:
    """Quasi-static RFT forces on ``leg`` following ``motion`` in a medium described by
    ``model``; a force series (coordinate ``theta`` in deg for rotations, ``time`` in s for
    planar motions) with Fx, Fz (N) and torque (N m) about the hip. ``dynamic=(lambda, rho)``
    adds the dynamic-RFT inertial term (Agarwal et al. 2021; rho bulk density, kg/m^3)."""
    traj = motion.trajectory()
    fx, fz, tq = net_forces(leg, traj, model, dynamic=dynamic)
    coord, values = ("theta", traj.angle / DEG) if traj.coord == "theta" else ("time", traj.time)
    inputs = _inputs(leg, motion, model, medium)
    if dynamic is not None:
        inputs["dynamic"] = {"lambda": float(dynamic[0]), "bulk_density_kg_per_m3": float(dynamic[1])}
    return force_series(coord, values, fx, fz, tq, model="rft",
                        inputs=inputs,
                        time=traj.time if coord == "theta" else None)


def simulate_many(legs: list[Leg], motion: Rotation | PlanarMotion, model: StressModel,
                  medium: str | None = None, labels: list[str] | None = None,
                  dtype=np.float64) -> xr.Dataset:
    """Many designs under one motion in one vectorised call: a stack of force series along
    ``case`` (labelled by ``labels`` or the legs' names)."""
    traj = motion.trajectory()
    out = batch_forces(legs, traj, model, dtype=dtype).astype(float)
    coord, values = ("theta", traj.angle / DEG) if traj.coord == "theta" else ("time", traj.time)
    import json

    ds = xr.Dataset(
        {"Fx": (("case", coord), out[..., 0]), "Fz": (("case", coord), out[..., 1]),
         "torque": (("case", coord), out[..., 2])},
        coords={coord: values, "case": np.arange(len(legs)),
                "label": ("case", labels or [getattr(leg, "name", str(i)) for i, leg in enumerate(legs)])})
    template = force_series(coord, values, out[0, :, 0], out[0, :, 1], out[0, :, 2], model="rft",
                            inputs=_inputs(legs[0], motion, model, medium))
    for v in ds.variables:
        if v in template.variables:
            ds[v].attrs.update(template[v].attrs)
    ds.attrs.update(template.attrs)
    ds.attrs["inputs"] = json.dumps([_inputs(leg, motion, model, medium) for leg in legs], default=str)
    return ds
