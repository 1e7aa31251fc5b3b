"""SPH model of a dry granular bed (elastic-perfectly plastic Drucker-Prager, Bui et al. 2008)
with a rigid leg moving through it: :func:`simulate` (any leg, any motion -> force series),
the scenes in :mod:`terradyn.sph.scenes` and the validation cases in
:mod:`terradyn.sph.validation`.

Kernels: Numba, multi-threaded (the threading layer and its spin policy: see
:mod:`terradyn`).
"""
from .api import FULL_DX, QUICK_DX, simulate, simulate_run, simulate_speeds, snapshots_dataset
from .materials import MATERIALS, GranularMaterial, from_medium, material
from .solver import Solver, run
from .state import SPHConfig, SPHInstabilityError, Scene

__all__ = ["simulate", "simulate_run", "simulate_speeds", "snapshots_dataset", "FULL_DX", "QUICK_DX",
           "MATERIALS", "GranularMaterial", "from_medium", "material", "SPHConfig",
           "SPHInstabilityError", "Scene", "Solver", "run"]
