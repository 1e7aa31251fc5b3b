"""Compatibility module: the SPH kernels now live in layers of their own, and this module
re-exports their names for code written against the old single module
(``from terradyn.sph import kernels as K``; ``K.SOIL``, ``K.cpu_steps``, ``K._pair_fdw``, ...).

* :mod:`terradyn.sph.state`: particle kinds (SOIL, WALL, LEG, LOST), config and state types;
* :mod:`terradyn.sph.source`: the one-source registry (SOURCES);
* :mod:`terradyn.sph.neighbours`: cells, Verlet lists, binning, pair chunks (SKIN, REACH);
* :mod:`terradyn.sph.physics`: the per-particle and per-pair physics (kernel, Drucker-Prager
  update, boundary extrapolation, pair terms, kick, leg placement and sides);
* :mod:`terradyn.sph.cpu`: the CPU's prange loops, :func:`cpu_steps`, the CPU backend.

New code should import from those modules.
"""
from __future__ import annotations

from . import cpu as _cpu
from . import neighbours as _neighbours
from . import physics as _physics
from . import source as _source_mod
from . import state as _state

_FM = _source_mod.FM
_source = _source_mod.source
SOURCES = _source_mod.SOURCES
for _m in (_state, _neighbours, _physics, _cpu):
    globals().update({k: v for k, v in vars(_m).items()
                      if not k.startswith("__") and k not in ("annotations", "math", "np",
                                                              "numba", "prange")})
del _m


def warmup():
    """Compile every kernel on a tiny problem (for benchmarks: keeps JIT out of timings)."""
    from .solver import warmup as _w

    _w()
