"""terradyn: forces on legs and feet moving through granular media.

The public API::

    import terradyn as td
    leg = td.c_leg()
    series = td.rft.simulate(leg, td.standard_rotation(), td.stress_model("3 mm glass CP"))
"""
__version__ = "0.1.0"

from .errors import InputError
from .geometry import ArcLeg, PolylineLeg, c_leg, flat_leg, foot, make_leg, read_leg_csv, reverse_c_leg
from .media import FITS, MEDIA, FourierFit, StressTable, generic, packaged_tables, stress_model
from .motion import PlanarMotion, Rotation, foot_rotation, read_motion_csv, standard_rotation
from .series import force_series, stack

__all__ = [
    "__version__", "InputError", "ArcLeg", "PolylineLeg", "c_leg", "flat_leg", "foot", "make_leg",
    "read_leg_csv", "reverse_c_leg", "FITS", "MEDIA", "FourierFit", "StressTable", "generic",
    "packaged_tables", "stress_model", "PlanarMotion", "Rotation", "foot_rotation",
    "read_motion_csv", "standard_rotation", "force_series", "stack",
]


def __getattr__(name):  # lazy subpackages keep `import terradyn` fast
    import importlib

    if name in ("rft", "sph", "dddas", "experiment", "compare", "io", "sweep", "plots", "studies"):
        return importlib.import_module(f".{name}", __name__)
    raise AttributeError(name)
