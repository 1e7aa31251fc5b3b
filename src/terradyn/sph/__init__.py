"""SPH model of a dry granular bed (elastic-perfectly plastic Drucker-Prager, Bui et al. 2008)
with a rigid leg moving through it: :func:`simulate` (any leg, any motion -> force series),
the scenes in :mod:`terradyn.sph.scenes` and the validation cases in
:mod:`terradyn.sph.validation`.

Kernels: Numba, multi-threaded. Numba's OpenMP layer busy-waits at every parallel region;
on a small shared machine that made a step 10x slower than the work-queue layer in our
measurements, so unless NUMBA_THREADING_LAYER is set the work-queue layer is chosen here
(effective only if no parallel Numba code ran earlier in the process).
"""
import os as _os

if "NUMBA_THREADING_LAYER" not in _os.environ:
    import numba as _numba

    _numba.config.THREADING_LAYER = "workqueue"

from .api import FULL_DX, QUICK_DX, simulate, simulate_speeds, snapshots_dataset  # noqa: E402
from .materials import MATERIALS, GranularMaterial, from_medium, material  # noqa: E402
from .solver import SPHConfig, SPHInstabilityError, Scene, Solver, run  # noqa: E402

__all__ = ["simulate", "simulate_speeds", "snapshots_dataset", "FULL_DX", "QUICK_DX",
           "MATERIALS", "GranularMaterial", "from_medium", "material", "SPHConfig",
           "SPHInstabilityError", "Scene", "Solver", "run"]
