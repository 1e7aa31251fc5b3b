"""Numba's on-disk cache, made safe for kernels built from code in other modules.

Numba keys a cached kernel to *its own* source file (mtime, size): a kernel that inlines or
calls jitted functions of another module keeps its stale machine code when only that other
module changes (numba issue #6845). terradyn's kernels do that by design (the SPH loops of
``sph/cpu.py`` inline the physics of ``sph/physics.py``; the MuJoCo terrain calls the 3D RFT
element law), so an edit of the physics, or an upgrade that rewrote only that file with its
old timestamp, would silently run the old physics.

:func:`bind_to_sources` fixes that for one module: every cached dispatcher in it gets, as its
cache stamp, numba's own stamp *and* a digest of the files of the modules it depends on, so
any change to them makes the cached code stale and numba compiles afresh (once). The stamp is
attached right after the module has defined its dispatchers, before any is compiled or loaded.
"""
from __future__ import annotations

import hashlib
import sys
from pathlib import Path


def source_digest(modules) -> str:
    """SHA-1 of the source files of ``modules`` (names of imported modules), in name order."""
    h = hashlib.sha1()
    for name in sorted(set(modules)):
        path = Path(sys.modules[name].__file__)
        h.update(name.encode())
        h.update(path.read_bytes())
    return h.hexdigest()


def bind_to_sources(namespace: dict, *depends_on: str) -> int:
    """Tie the on-disk cache of every cached Numba dispatcher in ``namespace`` (a module's
    ``globals()``) to the source of its own module and of ``depends_on`` (module names).
    Returns how many dispatchers were bound. A Numba without the cache attributes this relies
    on is left as it is (the cache then behaves as Numba's own)."""
    digest = source_digest((namespace["__name__"], *depends_on))
    bound = 0
    for obj in list(namespace.values()):
        cache_file = getattr(getattr(obj, "_cache", None), "_cache_file", None)
        if cache_file is None or not hasattr(cache_file, "_source_stamp"):
            continue
        stamp = cache_file._source_stamp
        if isinstance(stamp, tuple) and len(stamp) == 2 and stamp[0] == "terradyn":
            continue  # already bound (a module re-executed)
        cache_file._source_stamp = ("terradyn", (stamp, digest))
        bound += 1
    return bound


def bound_digest(dispatcher) -> str | None:
    """The dependency digest a dispatcher's cache is bound to (None: not bound)."""
    cache_file = getattr(getattr(dispatcher, "_cache", None), "_cache_file", None)
    stamp = getattr(cache_file, "_source_stamp", None)
    if isinstance(stamp, tuple) and len(stamp) == 2 and stamp[0] == "terradyn":
        return stamp[1][1]
    return None
