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
    suf = path.suffix.lower()
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
    return path


def check_output(path: str | Path | None, field: str = "out",
                 formats: tuple[str, ...] = FORMATS) -> None:
    """Check an output path before any work: a known file type (``formats``, by suffix) in a
    place that can be written. None and '-' (stdout) pass."""
    if path is None or str(path) == "-":
        return
    path = Path(path)
    suf = _fmt(path, field, formats)
    check_writable(path, field, directory=suf == ".zarr")


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
    """Write ``ds`` to ``path`` (.nc, .zarr or .csv), atomically for files: a crash never
    leaves a half-written file under the final name."""
    path = Path(path)
    suf = _fmt(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if suf == ".zarr":
        ds.to_zarr(path, mode="w", consolidated=False)
        return path
    tmp = path.with_name(f".{path.name}.tmp")
    if suf == ".nc":
        ds.to_netcdf(tmp, engine="h5netcdf")
    else:
        tmp.write_text(to_csv_text(ds))
    tmp.replace(path)
    return path


def read(path: str | Path) -> xr.Dataset:
    """Read a force series written by :func:`write` (.nc, .zarr, or .csv with a theta_deg or
    time_s column and Fx_N, Fz_N)."""
    path = Path(path)
    suf = _fmt(path)
    if not path.exists():
        raise InputError("file", f"not found: {path}")
    if suf == ".nc":
        with xr.open_dataset(path, engine="h5netcdf") as f:
            return f.load()
    if suf == ".zarr":
        return xr.open_zarr(path, consolidated=False).load()
    return read_csv(path)


def read_csv(path: Path) -> xr.Dataset:
    import pandas as pd

    try:
        df = pd.read_csv(path)
    except Exception as e:  # pandas raises many kinds
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
    """Write ``text`` to ``path`` through a temporary file of this process, renamed over it."""
    import os

    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    tmp = p.with_name(f".{p.name}.{os.getpid()}.tmp")
    try:
        tmp.write_text(text)
        tmp.replace(p)
    finally:
        tmp.unlink(missing_ok=True)
    return p
