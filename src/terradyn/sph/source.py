"""The one-source registry of the SPH kernels: the per-particle and per-pair functions that the
CPU and the GPU backends both compile.

A source is a plain Python function of (index, arrays..., scalars) that allocates nothing.
:func:`source` registers it in :data:`SOURCES` and returns its CPU form, an inlined
``numba.njit`` function that the ``prange`` loops of :mod:`terradyn.sph.cpu` call;
:mod:`terradyn.sph.gpu` compiles the very same plain functions again as CUDA device
functions (their global names re-bound to the device versions). The sources live in
:mod:`terradyn.sph.neighbours` (cells, Verlet lists, the cell-ordered copy) and
:mod:`terradyn.sph.physics` (kernel, constitutive law, boundary, pair terms, kick).
"""
from __future__ import annotations

import numba

#: name -> plain Python function, for every registered source.
SOURCES: dict = {}
#: Modules that define sources (their namespaces make the GPU's device namespace).
SOURCE_MODULES: list = []
#: fastmath flags that keep NaN/inf checks (the loops that test for non-finite values).
FM = {"nsz", "arcp", "contract", "afn", "reassoc"}


def source(fn):
    """Register ``fn`` as one-source kernel code; returns its CPU (inlined njit) form. The
    fastmath flags are those of the calling kernel (Numba inlines at the IR level)."""
    SOURCES[fn.__name__] = fn
    mod = fn.__module__
    if mod not in SOURCE_MODULES:
        SOURCE_MODULES.append(mod)
    return numba.njit(inline="always", fastmath=True)(fn)
