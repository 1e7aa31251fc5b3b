"""A toy force model: the whole of what adding a model to terradyn takes (this file, and one
``models.register(MODEL)`` or one line in ``terradyn.models.BUILTIN``).

Its force is hydrostatic-like: Fz = gain * (depth of the leg's lowest point) * chord, Fx =
-drag * Fz, no torque; ``dims = 3`` gives a 3D series with a lateral force Fy = 0.
"""
import numpy as np

from terradyn.models import Model, Option
from terradyn.series import make_series
from terradyn.units import DEG


def simulate(body, motion, medium, *, gain=1000.0, drag=0.1, dims=2):
    traj = motion.trajectory()
    depth = np.clip(body.chord * np.cos(traj.angle) - traj.hip_z, 0.0, None)
    fz = gain * depth * body.chord
    comps = {"Fx": -drag * fz, "Fz": fz}
    if dims == 3:
        comps["Fy"] = np.zeros_like(fz)
    coord, values = ("theta", traj.angle / DEG) if traj.coord == "theta" else ("time", traj.time)
    return make_series(coord, values, comps, schema="3d" if dims == 3 else "2d", model="toy",
                       inputs={"leg": body.describe(), "medium": str(medium), "gain": gain})


MODEL = Model("toy", simulate, options=(
    Option("gain", float, 1000.0, "N/m^3", lo=0, lo_open=True, help="Stress per depth."),
    Option("drag", float, 0.1, "", lo=0, hi=1, help="Fx / Fz."),
    Option("dims", int, 2, choices=(2, 3), help="Series schema: 2 or 3 dimensions."),
), description="A toy model for the registry's tests.")

MODEL_3D = Model("toy3d", lambda b, m, med, **o: simulate(b, m, med, dims=3, **o), options=MODEL.options[:2],
                 schema="3d", description="The toy model's 3D form.")
