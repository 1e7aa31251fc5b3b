"""3D RFT (:mod:`terradyn.rft3d`: Agarwal, Goldman & Kamrin 2023, or Treers et al. 2021 from a
2D coefficient set) as a registered model of the 3D schema (Fx, Fy, Fz, Tx, Ty, Tz)."""
from __future__ import annotations

from ..units import CM
from . import Model, Option

OPTIONS = (
    Option("model", str, "agarwal", choices=("agarwal", "treers"),
           help="Force law: 3D-RFT of Agarwal et al. 2023, or Treers et al. 2021 over a 2D coefficient set."),
    Option("surface_cm", float, None, "cm", help="Height of the free surface (default 0)."),
    Option("dynamic_lambda", float, None, "", 0, 10,
           help="Dynamic RFT: the inertial coefficient lambda (Agarwal et al. 2021; unset: quasi-static)."),
)


def _simulate(body, motion, medium, *, model="agarwal", surface_cm=None, dynamic_lambda=None):
    from ..rft3d import simulate

    ds = simulate(body, motion, medium, model=model,
                  surface=0.0 if surface_cm is None else surface_cm * CM,
                  dynamic_lambda=dynamic_lambda)
    return ds.assign_attrs(schema="3d")


MODEL = Model("rft3d", _simulate, OPTIONS, schema="3d",
              description="3D resistive force theory for any meshed body in any 6-DoF motion.")
