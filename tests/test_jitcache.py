"""The on-disk Numba cache follows the code a kernel uses from other modules
(terradyn._jitcache): an edit of the physics must never run old machine code."""
from __future__ import annotations

import importlib
import os
import subprocess
import sys
import textwrap

import numba
import pytest

from terradyn._jitcache import bound_digest, source_digest

BOUND = {
    "terradyn.sph.cpu": ("terradyn.sph.physics", "terradyn.sph.neighbours", "terradyn.sph.source",
                         "terradyn.sph.state"),
    "terradyn.sph.neighbours": ("terradyn.sph.source", "terradyn.sph.state"),
    "terradyn.sph.plate3d": ("terradyn.sph.neighbours", "terradyn.sph.state"),
    "terradyn.rft3d.engine": ("terradyn.rft3d.model",),
    "terradyn.dddas.terrain": ("terradyn.dddas.filter",),
}


@pytest.mark.parametrize("name", sorted(BOUND))
def test_every_cached_kernel_is_bound_to_its_dependencies(name):
    mod = importlib.import_module(name)
    cached = [v for v in vars(mod).values()
              if isinstance(v, numba.core.registry.CPUDispatcher) and v.__module__ == name
              and getattr(getattr(v, "_cache", None), "_cache_file", None) is not None]
    assert cached
    want = source_digest((name, *BOUND[name]))
    assert all(bound_digest(d) == want for d in cached)


def test_a_change_in_a_dependency_recompiles_a_cached_kernel(tmp_path):
    """Two modules: ``kern`` caches a kernel that calls ``law`` of ``phys``. Edit only
    ``phys`` (``kern``'s file and timestamp untouched): the next process computes with the
    new law, not with the cached old one."""
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    phys = pkg / "phys.py"
    phys.write_text("from numba import njit\n\n@njit\ndef law(x):\n    return 2.0 * x\n")
    (pkg / "kern.py").write_text(textwrap.dedent("""\
        from numba import njit
        from terradyn._jitcache import bind_to_sources
        from .phys import law

        @njit(cache=True)
        def kernel(x):
            return law(x) + 1.0

        bind_to_sources(globals(), "pkg.phys")
        """))
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"),
               PYTHONPATH=os.pathsep.join([str(tmp_path), *sys.path]))
    run = [sys.executable, "-c", "from pkg.kern import kernel; print(kernel(3.0))"]

    def value():
        return float(subprocess.run(run, env=env, capture_output=True, text=True, check=True,
                                    cwd=tmp_path).stdout)

    assert value() == 7.0
    assert value() == 7.0  # from the cache
    assert list((tmp_path / "cache").rglob("*.nbi"))
    phys.write_text("from numba import njit\n\n@njit\ndef law(x):\n    return 10.0 * x\n")
    assert value() == 31.0
