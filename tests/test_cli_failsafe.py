"""Fail-safe outputs: atomic writes never leave half a file or a temporary behind, a store
takes no folder it did not make, observation files keep every component."""
import errno

import numpy as np
import pytest
import xarray as xr

import terradyn as td
from terradyn import io
from terradyn.errors import InputError


def _series():
    return td.force_series("theta", [0.0, 1.0, 2.0], [1, 2, 3], [4, 5, 6], [0.1, 0.2, 0.3],
                           model="test", inputs={})


@pytest.mark.parametrize("name", ["s.nc", "s.csv", "s.zarr"])
def test_a_failed_write_keeps_the_old_file_and_leaves_no_temporary(name, tmp_path, monkeypatch):
    path = tmp_path / name
    io.write(_series(), path)
    before = io.read(path)

    def full(self, *a, **k):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(xr.Dataset, "to_netcdf", full)
    monkeypatch.setattr(xr.Dataset, "to_zarr", full)
    monkeypatch.setattr(io.os, "fsync", lambda fd: full(None))  # the CSV's flush to disk
    with pytest.raises(OSError) as e:
        io.write(_series() * 2, path)
    assert e.value.filename == str(path)  # the user's name, not the temporary's
    xr.testing.assert_allclose(io.read(path)[["Fx", "Fz"]], before[["Fx", "Fz"]])
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]


def test_zarr_store_is_replaced_whole(tmp_path):
    path = tmp_path / "s.zarr"
    io.write(_series(), path)
    io.write(_series() * 3, path)
    assert float(io.read(path).Fz[0]) == 12.0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.zarr"]


def test_a_store_takes_no_folder_it_did_not_make(tmp_path):
    from terradyn import sweep

    spec = sweep.parse('[sweep]\nname = "s"\nmodel = "rft"\n[leg]\nshape = "c"\n[model]\nmedium = "poppy LP"\n')
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "thesis.tex").write_text("years of work")
    with pytest.raises(InputError, match="not a sweep store"):
        sweep.run(spec, mine, workers=0)
    assert sorted(p.name for p in mine.iterdir()) == ["thesis.tex"]


def test_observation_files_keep_torque(tmp_path):
    from terradyn.dddas.online import read_observations

    p = tmp_path / "obs.csv"
    p.write_text("theta_deg,Fx_N,Fz_N,torque_N_m\n0,1,2,0.1\n1,,3,0.2\n")
    obs = read_observations(p)
    assert set(obs.data_vars) == {"Fx", "Fz", "torque"}
    np.testing.assert_array_equal(obs.torque.values, [0.1, 0.2])
