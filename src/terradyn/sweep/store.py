"""Resumable, labelled storage of a sweep: one directory per sweep, one NetCDF per case.

Layout of a store ``NAME.sweep/``::

    sweep.json         the spec and its plan (every case: id, resolved params, varied values)
    cases/<id>.nc      one finished case: its force series + provenance attributes
    failed/<id>.json   the last error of a case that failed (removed once it succeeds)
    events.jsonl       append-only log: runs started/ended, cases done/failed (run, host, time)
    .lock              held (flock) by the driver of a running sweep

Invariant: a case is finished exactly when ``cases/<id>.nc`` exists, and that file only ever
appears complete: it is written to a temporary name in the same directory, flushed to disk
and renamed (``os.replace`` is atomic on POSIX), so a crash or SIGKILL at any moment leaves
either no file or the whole file, never a half-written case that looks finished. Only the
driver writes the store (workers return results to it), so a Dask cluster needs no shared
filesystem, and results are never written twice for one run.
"""
from __future__ import annotations

import datetime as _dt
import fcntl
import json
import os
import socket
from pathlib import Path

import numpy as np
import xarray as xr

from ..errors import InputError

PLAN = "sweep.json"
CASES = "cases"
FAILED = "failed"
EVENTS = "events.jsonl"
LOCK = ".lock"


def spec_identity(name: str, model: str, base: dict) -> str:
    """What binds a store to its spec: a hash of the sweep's name, model and fixed (base)
    parameters; the varied grid may grow or shrink."""
    import hashlib

    blob = json.dumps([name, model, base], sort_keys=True, default=str)
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


def _old_identity(plan: dict) -> str:
    """The identity of a store written before stores recorded one (from its spec text)."""
    from .spec import parse

    try:
        base = parse(plan.get("spec_toml", ""), name=plan.get("name", "")).base
    except InputError:
        base = None
    return spec_identity(plan.get("name", ""), plan.get("model", ""), base)


def now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="milliseconds")


def _atomic_bytes(path: Path, data: bytes) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    with open(tmp, "wb") as fh:
        fh.write(data)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, path)


class Store:
    """A sweep store directory (see the module docstring for the layout)."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self._lock_fh = None

    # -- creation and the plan -------------------------------------------------------------
    @classmethod
    def open(cls, path: str | Path) -> "Store":
        """An existing store (raises :class:`InputError` if ``path`` is not one)."""
        s = cls(path)
        if not (s.path / PLAN).is_file():
            raise InputError("store", f"{s.path} is not a sweep store (no {PLAN})")
        return s

    def claim(self, spec) -> None:
        """Refuse (:class:`InputError` on ``store``) a path that this spec must not write: a
        file, a folder with other content that is not a sweep store, or the store of
        another spec (another name, model or fixed parameters; the same spec with a grown or
        shrunk grid is the same sweep). Nothing is created or removed."""
        p = self.path
        if p.exists() and not p.is_dir():
            raise InputError("store", f"{p} is a file, not a sweep store; give another --store")
        if p.is_dir() and not (p / PLAN).is_file():
            if any(x.name != LOCK for x in p.iterdir()):
                raise InputError("store", f"{p} exists and is not a sweep store (no {PLAN}); "
                                          "it is left alone: give another --store")
            return
        if (p / PLAN).is_file():
            plan = self.plan()
            ours = spec_identity(spec.name, spec.model, spec.base)
            theirs = plan.get("spec_id") or _old_identity(plan)
            if ours != theirs:
                raise InputError("store", f"{p} belongs to another spec ({plan.get('name')!r}, model "
                                          f"{plan.get('model')!r}, from {plan.get('source') or 'a spec'}; this "
                                          f"spec: {spec.name!r}, {spec.model!r}, other fixed parameters or "
                                          "name); give another --store")

    def write_plan(self, spec) -> None:
        """Create the store if needed and record ``spec`` and its cases as the plan."""
        for d in (self.path, self.path / CASES, self.path / FAILED):
            d.mkdir(parents=True, exist_ok=True)
        from .. import __version__

        plan = {"name": spec.name, "model": spec.model, "description": spec.description,
                "source": spec.source, "spec_toml": spec.text, "varied": spec.varied,
                "terradyn_version": __version__, "cases": [c.to_json() for c in spec.cases],
                "spec_id": spec_identity(spec.name, spec.model, spec.base)}
        _atomic_bytes(self.path / PLAN, json.dumps(plan, indent=1, sort_keys=True).encode())

    def plan(self) -> dict:
        try:
            return json.loads((self.path / PLAN).read_text())
        except FileNotFoundError:
            raise InputError("store", f"{self.path} is not a sweep store (no {PLAN})") from None

    # -- locking ---------------------------------------------------------------------------
    def lock(self) -> None:
        """Take the store's lock for this process (released by the kernel if it dies)."""
        self.path.mkdir(parents=True, exist_ok=True)
        fh = open(self.path / LOCK, "a+")
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            fh.close()
            raise InputError("store", f"{self.path} is in use by another running sweep") from None
        self._lock_fh = fh

    def unlock(self) -> None:
        if self._lock_fh is not None:
            fcntl.flock(self._lock_fh, fcntl.LOCK_UN)
            self._lock_fh.close()
            self._lock_fh = None

    # -- cases -----------------------------------------------------------------------------
    def case_path(self, cid: str) -> Path:
        return self.path / CASES / f"{cid}.nc"

    def done_ids(self) -> set[str]:
        d = self.path / CASES
        if not d.is_dir():
            return set()
        return {p.name[:-3] for p in d.iterdir() if p.name.endswith(".nc") and not p.name.startswith(".")}

    def failed(self) -> dict[str, dict]:
        d = self.path / FAILED
        out = {}
        for p in sorted(d.glob("*.json")) if d.is_dir() else []:
            try:
                out[p.stem] = json.loads(p.read_text())
            except (OSError, ValueError):
                continue
        return out

    def write_case(self, cid: str, ds: xr.Dataset) -> Path:
        """Write one finished case atomically (temp file, fsync, rename)."""
        final = self.case_path(cid)
        tmp = final.with_name(f".{final.name}.{os.getpid()}.tmp")
        try:
            _write_nc3(tmp, ds)
        except (TypeError, ValueError, UnicodeError, OverflowError):
            # NetCDF3 cannot hold it (e.g. non-ASCII text, int64 data): NetCDF4 via xarray.
            tmp.unlink(missing_ok=True)
            ds.to_netcdf(tmp, engine="h5netcdf")
        fd = os.open(tmp, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, final)
        (self.path / FAILED / f"{cid}.json").unlink(missing_ok=True)
        return final

    def write_failure(self, cid: str, info: dict) -> None:
        _atomic_bytes(self.path / FAILED / f"{cid}.json", json.dumps(info, indent=1).encode())

    def read_case(self, cid: str) -> xr.Dataset:
        return read_case_file(self.case_path(cid))

    def clean_temporaries(self) -> int:
        """Remove temporary files left by a killed run; returns how many."""
        n = 0
        for d in (self.path, self.path / CASES, self.path / FAILED):
            for p in d.glob(".*.tmp") if d.is_dir() else []:
                p.unlink(missing_ok=True)
                n += 1
        return n

    # -- events ----------------------------------------------------------------------------
    def log(self, event: str, **fields) -> None:
        """Append one event line (a single write of < 4 KiB: whole or absent after a kill)."""
        line = json.dumps({"t": now(), "event": event, **fields}, default=str) + "\n"
        fd = os.open(self.path / EVENTS, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        try:
            os.write(fd, line.encode())
        finally:
            os.close(fd)

    def events(self) -> list[dict]:
        p = self.path / EVENTS
        if not p.is_file():
            return []
        out = []
        for line in p.read_text().splitlines():
            try:
                out.append(json.loads(line))
            except ValueError:  # a torn last line after a power cut
                continue
        return out


# A force series is a handful of 1-D float arrays: NetCDF3 written directly with scipy takes
# ~1 ms where xarray's NetCDF4 writer takes ~50-100 ms, which would cap the driver at a
# dozen small cases per second. Both are NetCDF; read_case_file reads either.
def _nc3_attr(v):
    if isinstance(v, (bool, np.bool_)):
        return int(v)
    if isinstance(v, (str, int, float, np.integer, np.floating)):
        if isinstance(v, str):
            v.encode("ascii")  # UnicodeError -> NetCDF4 fallback
        if isinstance(v, (int, np.integer)) and not -2**31 <= int(v) < 2**31:
            raise OverflowError(v)
        return v
    if isinstance(v, (list, tuple, np.ndarray)):
        a = np.asarray(v)
        if a.dtype.kind in "fi":
            return a.astype(float) if a.dtype.kind == "f" else a.astype(np.int32)
    return json.dumps(v, default=str)


def _write_nc3(path: Path, ds: xr.Dataset) -> None:
    from scipy.io import netcdf_file

    with netcdf_file(path, "w", version=2) as f:
        for k, v in ds.attrs.items():
            setattr(f, k, _nc3_attr(v))
        for dim, n in ds.sizes.items():
            f.createDimension(dim, n)
        aux = [c for c in ds.coords if c not in ds.dims]
        for name, var in ds.variables.items():
            a = np.asarray(var.values)
            if a.dtype.kind == "f":
                a = a.astype(np.float64)
            elif a.dtype.kind in "iub" and a.size and np.abs(a).max() < 2**31:
                a = a.astype(np.int32)
            else:
                raise TypeError(f"{name}: {a.dtype} does not fit NetCDF3")
            x = f.createVariable(name, a.dtype.char, var.dims)
            x[...] = a
            for k, v in var.attrs.items():
                setattr(x, k, _nc3_attr(v))
            if name in ds.data_vars and aux:  # CF: how readers know the auxiliary coordinates
                x.coordinates = " ".join(aux)


def read_case_file(path: str | Path) -> xr.Dataset:
    """One case file (NetCDF3 as written by the store, or NetCDF4) as a Dataset."""
    path = Path(path)
    with open(path, "rb") as fh:
        magic = fh.read(4)
    if not magic.startswith(b"CDF"):
        with xr.open_dataset(path, engine="h5netcdf") as f:
            return f.load()
    from scipy.io import netcdf_file

    def attrs(obj):
        out = {}
        for k, v in obj._attributes.items():
            if isinstance(v, bytes):
                v = v.decode()
            elif isinstance(v, np.ndarray) and v.size == 1:
                v = v.item()
            out[k] = v
        return out

    with netcdf_file(path, "r", mmap=False) as f:
        variables = {name: (v.dimensions, np.array(v.data).astype(v.data.dtype.newbyteorder("=")), attrs(v))
                     for name, v in f.variables.items()}
        gattrs = attrs(f)
    aux = set()
    for _, _, a in variables.values():
        aux.update(str(a.pop("coordinates", "")).split())
    dims = {d for dims, _, _ in variables.values() for d in dims}
    coords = {k: v for k, v in variables.items() if k in dims or k in aux}
    data = {k: v for k, v in variables.items() if k not in coords}
    return xr.Dataset(data, coords=coords, attrs=gattrs)


def status(path: str | Path) -> dict:
    """Progress of a store: counts of cases total/done/failed/pending, the failed cases with
    their errors, and finished cases that are no longer in the plan (``orphans``)."""
    s = Store.open(path)
    plan = s.plan()
    ids = [c["id"] for c in plan["cases"]]
    done = s.done_ids()
    failed = {k: v for k, v in s.failed().items() if k not in done and k in set(ids)}
    n_done = sum(1 for i in ids if i in done)
    return {"store": str(s.path), "name": plan["name"], "model": plan["model"], "total": len(ids),
            "done": n_done, "failed": len(failed), "pending": len(ids) - n_done - len(failed),
            "failures": failed, "orphans": sorted(done - set(ids))}


def _coord_names(varied: list[str]) -> dict[str, str]:
    last = [p.split(".")[-1] for p in varied]
    return {p: (l if last.count(l) == 1 and l not in _RESERVED else p.replace(".", "_"))
            for p, l in zip(varied, last)}


def _reserved() -> set:
    from ..series import SCHEMAS

    comps = {c for s in SCHEMAS.values() for c in s.components}
    return comps | {f"{c}_std" for c in comps} | {"case", "case_id", "theta", "time", "host",
                                                  "wall_time_s", "terradyn_version", "input", "params"}


_RESERVED = _reserved()


def collect(path: str | Path, out: str | Path | None = None, partial: bool = False) -> xr.Dataset:
    """Stack the finished cases of a store, in plan order, into one Dataset along ``case``:
    Fx, Fz, torque (case, theta); the varied parameters as coordinates along ``case`` (named by
    their last key, e.g. ``length_cm``; ``leg_length_cm`` if ambiguous); ``case_id``; and per
    case provenance (``host``, ``wall_time_s``, ``terradyn_version``, ``params`` JSON). Writes
    ``out`` (.nc) when given. Raises unless every case is done, or ``partial`` is true."""
    s = Store.open(path)
    plan = s.plan()
    done = s.done_ids()
    cases = [c for c in plan["cases"] if c["id"] in done]
    missing = len(plan["cases"]) - len(cases)
    if missing and not partial:
        raise InputError("store", f"{missing} of {len(plan['cases'])} cases are not finished; "
                                  "run the sweep again, or collect with --partial")
    if not cases:
        raise InputError("store", "no finished cases to collect")
    series = [s.read_case(c["id"]) for c in cases]
    from ..series import coord_of

    dim = coord_of(series[0])
    ref = series[0][dim].values
    for c, ds in zip(cases, series):
        if coord_of(ds) != dim or ds[dim].shape != ref.shape or not np.allclose(ds[dim].values, ref):
            raise InputError("store", f"case {c['id']} is not on the same {dim} grid as case {cases[0]['id']}; "
                                      "cases on different grids cannot be stacked")
    prov = [{k: ds.attrs.get(k, "") for k in ("sweep_host", "sweep_wall_time_s", "terradyn_version", "input")}
            for ds in series]
    stripped = [ds.drop_attrs() for ds in series]
    ds = xr.concat(stripped, dim="case", coords="different", compat="equals", join="override",
                   combine_attrs="drop")
    names = _coord_names(plan["varied"])
    coords = {"case": np.arange(len(cases)), "case_id": ("case", [c["id"] for c in cases])}
    for p, name in names.items():
        coords[name] = ("case", [c["varied"][p] for c in cases])
    ds = ds.assign_coords(coords)
    ds["host"] = ("case", [str(p["sweep_host"]) for p in prov])
    ds["wall_time_s"] = ("case", np.array([float(p["sweep_wall_time_s"] or np.nan) for p in prov]))
    ds["wall_time_s"].attrs["units"] = "s"
    ds["terradyn_version"] = ("case", [str(p["terradyn_version"]) for p in prov])
    ds["params"] = ("case", [json.dumps(c["params"], sort_keys=True) for c in cases])
    ds["input"] = ("case", [str(p["input"]) for p in prov])
    from ..series import components

    for v in components(series[0], torques=True) + (dim, "time"):
        if v in ds.variables and v in series[0].variables:
            ds[v].attrs.update(series[0][v].attrs)
    from .. import __version__

    ds.attrs.update(
        title=f"terradyn sweep {plan['name']}", sweep=plan["name"], model=plan["model"],
        varied=json.dumps({names[p]: p for p in plan["varied"]}), n_cases=len(cases),
        complete=int(not missing), spec_toml=plan.get("spec_toml", ""), terradyn_version=__version__,
        created=now(), Conventions="CF-1.10",
        history=f"terradyn sweep collect {s.path} ({len(cases)} cases) on {socket.gethostname()}")
    if out is not None:
        from ..io import write

        out = Path(out)
        if out.suffix.lower() != ".nc":
            raise InputError("out", f"collect writes NetCDF (.nc), got {out.name!r}")
        write(ds, out)
    return ds
