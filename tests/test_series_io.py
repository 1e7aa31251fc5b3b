import numpy as np
import pytest
import xarray as xr

import terradyn as td
from terradyn import compare, io
from terradyn.errors import InputError
from terradyn.series import force_series, stack, validate


@pytest.fixture(scope="module")
def series():
    return td.rft.simulate(td.c_leg(n=30), td.standard_rotation(37), td.FITS["poppy LP"], "poppy LP")


@pytest.mark.parametrize("suffix", [".nc", ".csv", ".zarr"])
def test_round_trip(tmp_path, series, suffix):
    p = io.write(series, tmp_path / f"s{suffix}")
    back = io.read(p)
    for v in ("Fx", "Fz", "torque"):
        np.testing.assert_allclose(back[v].values, series[v].values, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(back.theta.values, series.theta.values)
    if suffix != ".csv":
        assert td.series.inputs_of(back) == td.series.inputs_of(series)
    assert not list(tmp_path.glob(".*.tmp"))  # atomic write leaves no temporary behind


def test_csv_has_named_units(series):
    header = io.to_csv_text(series).splitlines()[0]
    assert header.split(",")[:4] == ["theta_deg", "Fx_N", "Fz_N", "torque_N_m"]


def test_validation_rejects_nan_and_bad_shapes(tmp_path):
    with pytest.raises(InputError, match="NaN"):
        force_series("theta", [0, 1], [0, np.nan], [0, 0], model="x", inputs={})
    with pytest.raises(InputError, match="coord"):
        force_series("angle", [0, 1], [0, 0], [0, 0], model="x", inputs={})
    with pytest.raises(InputError, match="monotonic"):
        force_series("theta", [0, 2, 1], [0, 0, 0], [0, 0, 0], model="x", inputs={})
    with pytest.raises(InputError, match="Fz"):
        validate(xr.Dataset({"Fx": ("theta", [0.0])}, coords={"theta": [0.0]}))
    with pytest.raises(InputError, match="unsupported"):
        io.write(xr.Dataset(), tmp_path / "x.txt")
    with pytest.raises(InputError, match="not found"):
        io.read(tmp_path / "missing.nc")
    (tmp_path / "bad.csv").write_text("a,b\n1,2\n")
    with pytest.raises(InputError, match="theta_deg"):
        io.read(tmp_path / "bad.csv")


def test_stack_and_compare(series):
    other = td.rft.simulate(td.c_leg(n=30), td.standard_rotation(37), td.FITS["poppy CP"])
    st = stack([series, other], {"medium": ["poppy LP", "poppy CP"]})
    assert st.Fz.dims == ("case", "theta") and list(st.medium.values) == ["poppy LP", "poppy CP"]
    assert compare.mse(series, series) == {"Fx": 0.0, "Fz": 0.0}
    # MSE of a scaled copy is known exactly: (k - 1)^2 <F^2>
    k = other.Fz.max() / series.Fz.max()
    twice = series.copy()
    twice["Fz"] = 2 * series["Fz"]
    assert compare.mse(series, twice)["Fz"] == pytest.approx(float((series.Fz ** 2).mean()))
    pk = compare.peak_difference(series, twice)
    assert pk["Fz"]["rel_diff"] == pytest.approx(1.0)
    tab = compare.table({"a": series, "b": twice}, reference="a")
    assert float(tab.peak_rel_diff.sel(source="b", component="Fz")) == pytest.approx(1.0)
    with pytest.raises(InputError, match="stack"):
        stack([])
    with pytest.raises(InputError, match="grid"):
        stack([series, td.rft.simulate(td.c_leg(n=30), td.standard_rotation(11), td.FITS["poppy LP"])])
    assert k > 1
