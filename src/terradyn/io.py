"""Reading and writing force series: NetCDF (.nc), Zarr (.zarr) and CSV (.csv)."""
from __future__ import annotations

import io as _io
import os
import sys
from pathlib import Path

import numpy as np
import xarray as xr

from .errors import InputError
from .series import coord_of, validate

FORMATS = (".nc", ".zarr", ".csv")


def _fmt(path: Path, field: str = "out", formats: tuple[str, ...] = FORMATS) -> str:
    suf = Path(path).suffix.lower()
    if suf not in formats:
        raise InputError(field, f"unsupported file type {suf or '(none)'!r} for {path}; use one of {', '.join(formats)}")
    return suf


def check_writable(path: str | Path, field: str = "out", directory: bool = False) -> Path:
    """Raise :class:`InputError` on ``field`` unless ``path`` can be written (a file, or with
    ``directory`` a folder such as a .zarr store), without creating anything: it must not be
    a folder (a file, if ``directory``), and the nearest folder that exists on its way must be
    writable (files are written to a temporary name there and renamed)."""
    path = Path(path)
    if path.exists():
        if directory and not path.is_dir():
            raise InputError(field, f"{path} exists and is not a directory")
        if not directory and path.is_dir():
            raise InputError(field, f"{path} is a directory; give a file name")
        if not os.access(path, os.W_OK):
            raise InputError(field, f"{path} is not writable")
    anc = path.parent
    while not anc.exists() and anc != anc.parent:
        anc = anc.parent
    if not anc.is_dir():
        raise InputError(field, f"cannot create {path}: {anc} is not a directory")
    if not os.access(anc, os.W_OK | os.X_OK):
        raise InputError(field, f"cannot write {path}: directory {anc} is not writable")
    _probe(anc, path, field)
    return path


def _probe(folder: Path, path: Path, field: str) -> None:
    """Create and remove a file in ``folder``: the one sure test that it takes files
    (permissions as root, read-only or pseudo file systems)."""
    import tempfile

    try:
        fd, name = tempfile.mkstemp(prefix=".terradyn-probe-", dir=folder)
        os.close(fd)
        os.unlink(name)
    except OSError as e:
        raise InputError(field, f"cannot write {path}: {e.strerror or e} in {folder}") from None


def check_output(path: str | Path | None, field: str = "out",
                 formats: tuple[str, ...] = FORMATS) -> None:
    """Check an output path before any work: a known file type (``formats``, by suffix) in a
    place that can be written. None and '-' (stdout) pass."""
    if path is None or str(path) == "-":
        return
    path = Path(path)
    if path.is_dir() and path.suffix.lower() != ".zarr":
        raise InputError(field, f"{path} is a directory; give a file name ({', '.join(formats)})")
    suf = _fmt(path, field, formats)
    check_writable(path, field, directory=suf == ".zarr")


def check_input(path: str | Path | None, field: str = "file") -> Path | None:
    """Raise :class:`InputError` on ``field`` unless ``path`` (None passes) is a readable
    file."""
    if path is None:
        return None
    path = Path(path)
    if not path.exists():
        raise InputError(field, f"file not found: {path}")
    if path.is_dir() and path.suffix.lower() != ".zarr":
        raise InputError(field, f"{path} is a directory; give a file")
    if not os.access(path, os.R_OK):
        raise InputError(field, f"{path} is not readable (permission denied)")
    return path


def tmp_name(path: Path) -> Path:
    """A temporary name of this process beside ``path`` (same suffix, hidden)."""
    return path.with_name(f".{path.stem}.{os.getpid()}.tmp{path.suffix}")


def atomic_save(path: str | Path, save) -> Path:
    """Call ``save(tmp)`` for a temporary path beside ``path`` (same suffix) and rename it
    over ``path``: a crash or a full disk never leaves a half-written file under the final
    name (the temporary is removed on failure)."""
    import shutil

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = tmp_name(path)
    try:
        try:
            save(tmp)
        except OSError as e:  # name the file the user asked for, not the temporary
            raise type(e)(e.errno, e.strerror or str(e), str(path)) from None
        if tmp.is_dir():  # a directory store (.zarr): move the old one aside, then swap
            old = path.with_name(f".{path.name}.{os.getpid()}.old")
            if path.exists():
                path.rename(old)
            tmp.rename(path)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(tmp, path)
    finally:
        if tmp.is_dir():
            shutil.rmtree(tmp, ignore_errors=True)
        else:
            tmp.unlink(missing_ok=True)
    return path


def plot_formats() -> tuple[str, ...]:
    """File types that the figures can be saved as (matplotlib's, by suffix)."""
    from matplotlib.backend_bases import FigureCanvasBase

    return tuple(f".{k}" for k in FigureCanvasBase.get_supported_filetypes())


def check_plot(path: str | Path | None, field: str = "plot") -> None:
    """:func:`check_output` for a figure (.png, .pdf, .svg, ...)."""
    if path is not None:
        check_output(path, field, plot_formats())


def to_csv_text(ds: xr.Dataset) -> str:
    """A force series (or a stack along ``case``) as CSV text, one row per sample."""
    df = ds.drop_vars([v for v in ds.data_vars if ds[v].ndim == 0]).to_dataframe().reset_index()
    buf = _io.StringIO()
    units = {n: ds[n].attrs.get("units") for n in list(ds.variables)}
    df.columns = [f"{c}_{units[c].replace(' ', '_')}" if units.get(c) else c for c in df.columns]
    df.to_csv(buf, index=False, float_format="%.10g")
    return buf.getvalue()


def write(ds: xr.Dataset, path: str | Path) -> Path:
    """Write ``ds`` to ``path`` (.nc, .zarr or .csv), atomically: a crash or a full disk
    never leaves a half-written file under the final name."""
    path = Path(path)
    suf = _fmt(path)
    if suf == ".zarr":
        return atomic_save(path, lambda t: ds.to_zarr(t, mode="w", consolidated=False))
    if suf == ".nc":
        return atomic_save(path, lambda t: ds.to_netcdf(t, engine="h5netcdf"))
    return atomic_write_text(path, to_csv_text(ds))


def write_netcdf(ds: xr.Dataset, path: str | Path) -> Path:
    """Any Dataset (not only a force series) to NetCDF, atomically."""
    return atomic_save(path, lambda t: ds.to_netcdf(t, engine="h5netcdf"))


def read(path: str | Path, field: str = "file") -> xr.Dataset:
    """Read a force series written by :func:`write` (.nc, .zarr, or .csv with a theta_deg or
    time_s column and Fx_N, Fz_N); a file that is not one is an :class:`InputError` on
    ``field``."""
    path = Path(path)
    suf = _fmt(path, field)
    check_input(path, field)
    try:
        if suf == ".nc":
            with xr.open_dataset(path, engine="h5netcdf") as f:
                return f.load()
        if suf == ".zarr":
            return xr.open_zarr(path, consolidated=False).load()
    except (OSError, ValueError, KeyError) as e:
        raise InputError(field, f"{path}: not a readable {suf[1:]} dataset ({e})") from None
    try:
        return read_csv(path)
    except InputError as e:
        if e.field == "file" and field != "file":
            raise InputError(field, str(e).split(": ", 1)[-1]) from None
        raise


def read_csv(path: Path) -> xr.Dataset:
    import pandas as pd

    try:
        df = pd.read_csv(path, encoding="utf-8")
    except Exception as e:  # pandas raises many kinds (UnicodeDecodeError for a binary file)
        raise InputError("file", f"{path}: not a readable CSV ({e})") from None
    coord = "theta" if "theta_deg" in df else "time" if "time_s" in df else None
    if coord is None or not {"Fx_N", "Fz_N"} <= set(df.columns):
        raise InputError("file", f"{path}: need a theta_deg or time_s column and Fx_N, Fz_N; got {list(df.columns)}")
    ren = {c: c.rsplit("_", 1)[0] for c in df.columns if c.endswith(("_N", "_deg", "_s", "_N_m"))}
    ren.update({c: c[: -len("_N_m")] for c in df.columns if c.endswith("_N_m")})
    df = df.rename(columns=ren)
    ds = xr.Dataset.from_dataframe(df.set_index(coord))
    for v in ds.data_vars:
        ds[v] = ds[v].astype(float)
    if not np.isfinite(ds["Fx"]).all() or not np.isfinite(ds["Fz"]).all():
        raise InputError("file", f"{path}: Fx_N/Fz_N contain empty or non-finite values")
    coord_of(ds)
    return validate(ds)


def emit(ds: xr.Dataset, out: str | None) -> None:
    """Write to ``out`` or, when it is None or '-', CSV on stdout."""
    if out in (None, "-"):
        sys.stdout.write(to_csv_text(ds))
    else:
        write(ds, out)


def atomic_write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` to ``path`` through a temporary file of this process, flushed to disk
    and renamed over it."""
    def save(tmp):
        with open(tmp, "w") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())

    return atomic_save(path, save)
