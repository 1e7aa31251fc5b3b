"""Finished SPH runs kept on disk, so that a long study (a validation's leg runs, a
calibration's plate tests) that is interrupted and started again loses at most the run in
progress.

A run is stored as ``PREFIX-KEY.nc`` in a directory, KEY a hash of everything that defines it
(its ``spec``: scene, material, numerical settings and a digest of the code that computes it,
:func:`code_digest`), so a run made with other inputs or other code is recomputed, never
reused. A file under that name that is not the run it claims to be is refused, never
overwritten: the store only ever writes files it names itself.
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Callable

from ..errors import InputError

#: The modules that define an SPH run's forces (the GPU loops are left out: a run's key does
#: not depend on the backend, as for checkpoints).
RUN_MODULES = ("terradyn.geometry", "terradyn.motion", "terradyn.sph.api", "terradyn.sph.scenes",
               "terradyn.sph.solver", "terradyn.sph.cpu", "terradyn.sph.physics",
               "terradyn.sph.kernels", "terradyn.sph.neighbours", "terradyn.sph.materials",
               "terradyn.sph.state", "terradyn.sph.source")


def code_digest(modules=RUN_MODULES) -> str:
    """Digest of the sources of ``modules`` (part of a stored run's key)."""
    import importlib

    from .._jitcache import source_digest

    for m in modules:
        importlib.import_module(m)
    return source_digest(modules)


def run_key(spec: dict) -> str:
    """The 16-hex-digit key of a run's ``spec`` (any JSON-able dict)."""
    return hashlib.sha256(json.dumps(spec, sort_keys=True, default=str).encode()).hexdigest()[:16]


def stored(store, prefix: str, spec: dict, compute: Callable):
    """The run ``spec`` from the directory ``store``, or computed and kept there.

    ``compute(checkpoint)`` makes the run (an xarray Dataset); ``checkpoint`` is a path
    beside the stored file (``.PREFIX-KEY.ckpt.npz``) a long run may use to resume. Returns
    (dataset, True if it was read from the store). A file ``PREFIX-KEY.nc`` that is not this
    run is an :class:`InputError` on ``store``."""
    import xarray as xr

    from .. import io

    store = Path(store)
    key = run_key(spec)
    path = store / f"{prefix}-{key}.nc"
    if path.exists():
        try:
            ds = xr.load_dataset(path, engine="h5netcdf")
        except Exception:  # noqa: BLE001 - any unreadable file is "not ours"
            ds = None
        if ds is None or ds.attrs.get("terradyn_run_key") != key:
            raise InputError("store", f"{path} exists and is not a stored run of this test: "
                                      "remove it or choose another directory")
        return ds, True
    io.check_writable(store, "store", directory=True)
    ds = compute(store / f".{prefix}-{key}.ckpt.npz")
    ds = ds.assign_attrs(terradyn_run_key=key, terradyn_run_spec=json.dumps(spec, sort_keys=True, default=str))
    io.write_netcdf(ds, path)
    return ds, False
