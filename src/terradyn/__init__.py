"""terradyn: forces on legs and feet moving through granular media.

The public API::

    import terradyn as td
    leg = td.c_leg()
    series = td.rft.simulate(leg, td.standard_rotation(), td.stress_model("3 mm glass CP"))
"""
__version__ = "0.1.0"

import os as _os

# Numba's parallel kernels (SPH, RFT batches) run on its OpenMP layer (its default when TBB is
# absent). GNU OpenMP's threads spin for ~300k iterations after each parallel region: on a
# busy machine they burn the cores other work needs (with two other busy processes on two
# cores an SPH step went 11-15x slower than with a short spin), while Numba's work-queue
# layer costs ~75 us per kernel launch (half of a small bed's step). A short spin keeps the
# OpenMP launch at ~5 us idle and ~10 us loaded (benchmarks/bench_threading.py). Set before
# any OpenMP runtime starts; a user's own GOMP_SPINCOUNT or OMP_WAIT_POLICY wins.
if "GOMP_SPINCOUNT" not in _os.environ and "OMP_WAIT_POLICY" not in _os.environ:
    _os.environ["GOMP_SPINCOUNT"] = "10000"

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

    if name in ("rft", "rft3d", "sph", "dddas", "experiment", "compare", "io", "sweep", "plots", "studies"):
        return importlib.import_module(f".{name}", __name__)
    raise AttributeError(name)
