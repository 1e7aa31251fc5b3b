"""The model registry (terradyn.models) and the schema's components (terradyn.series): a new
model is its own file plus one registration; sweeps, studies and the CLI dispatch by name;
a 3D series flows through compare, plots, the store and the surrogate unchanged."""
import sys
from pathlib import Path

import numpy as np
import pytest

import terradyn as td
from terradyn import compare, models
from terradyn.errors import InputError
from terradyn.series import SCHEMAS, components, make_series, schema_of, validate

sys.path.insert(0, str(Path(__file__).parent))
import toy_model  # noqa: E402


@pytest.fixture
def toy():
    models.register(toy_model.MODEL)
    models.register(toy_model.MODEL_3D)
    yield toy_model.MODEL
    models.unregister("toy")
    models.unregister("toy3d")


def test_builtins_are_registered_with_their_options():
    assert {"rft", "sph"} <= set(models.names())
    rft = models.get("rft")
    assert {o.name for o in rft.options} >= {"alpha", "zeta", "interp", "table_file"}
    dx = models.get("sph").option("dx_mm")
    assert dx.unit == "mm" and dx.describe() == "(0, 10] mm"
    with pytest.raises(InputError, match="model: unknown model 'fem'; allowed: rft, rft3d, sph"):
        models.get("fem")


def test_rft_through_the_registry_is_rft():
    leg, mot = td.c_leg(n=20), td.standard_rotation(n_theta=9)
    a = models.simulate("rft", leg, mot, "poppy LP", alpha="generic", zeta=0.3)
    b = td.rft.simulate(leg, mot, td.stress_model("poppy LP", "generic", 0.3), medium="poppy LP")
    np.testing.assert_array_equal(a.Fz.values, b.Fz.values)
    with pytest.raises(InputError, match=r"zeta: must be in \(0, inf\)"):
        models.simulate("rft", leg, mot, "poppy LP", alpha="generic", zeta=-1.0)
    with pytest.raises(InputError, match="colour: unknown option of model 'rft'"):
        models.simulate("rft", leg, mot, "poppy LP", colour=3)


def test_a_new_model_is_one_file_and_one_registration(toy):
    leg, mot = td.c_leg(n=10), td.standard_rotation(n_theta=11)
    ds = models.simulate("toy", leg, mot, "anything", gain=500.0)
    assert ds.attrs["model"] == "toy" and components(ds) == ("Fx", "Fz")
    assert float(ds.Fz.max()) > 0 and np.allclose(ds.Fx, -0.1 * ds.Fz)
    with pytest.raises(InputError, match=r"gain: must be in \(0, inf\) N/m\^3, got -1"):
        models.simulate("toy", leg, mot, "x", gain=-1)
    with pytest.raises(ValueError, match="already registered"):
        models.register(models.Model("toy", toy_model.simulate))


def test_sweeps_dispatch_through_the_registry(toy, tmp_path):
    from terradyn import sweep

    spec = sweep.parse('[sweep]\nname = "t"\nmodel = "toy"\n[leg]\nshape = "c"\n[motion]\nn_theta = 7\n'
                       '[model]\nmedium = "sand"\n[grid]\nmodel.gain = [100.0, 200.0]\n')
    assert [c.params["model"]["gain"] for c in spec.cases] == [100.0, 200.0]
    assert spec.cases[0].params["model"]["drag"] == 0.1  # the declared default, part of the id
    s = sweep.run(spec, tmp_path / "t.sweep", workers=0)
    assert s.done == 2 and not s.failed
    ds = sweep.collect(tmp_path / "t.sweep")
    np.testing.assert_allclose(ds.Fz.isel(case=1), 2 * ds.Fz.isel(case=0))
    with pytest.raises(InputError, match="model.gain"):
        sweep.parse('[sweep]\nmodel = "toy"\n[leg]\nshape = "c"\n[model]\nmedium = "s"\ngain = 0\n')


def test_studies_dispatch_through_the_registry(tmp_path):
    from terradyn import studies

    r = studies.legs_study(tmp_path, medium="poppy LP", alpha="fit", n_theta=9, n_elements=10)
    assert set(r["features"]) == {"flat", "c", "reverse-c"}


def test_a_model_must_return_its_declared_schema(toy):
    bad = models.Model("bad3d", toy_model.simulate, toy_model.MODEL.options, schema="3d")
    with pytest.raises(TypeError, match="declared schema '3d'"):
        bad.simulate(td.c_leg(n=5), td.standard_rotation(n_theta=5), "x")


def test_schemas_declare_their_components():
    assert SCHEMAS["2d"].forces == ("Fx", "Fz") and SCHEMAS["2d"].torques == ("torque",)
    assert SCHEMAS["3d"].forces == ("Fx", "Fy", "Fz") and SCHEMAS["3d"].torques == ("Tx", "Ty", "Tz")
    t = np.linspace(0, 1, 5)
    ds = make_series("time", t, {"Fx": t, "Fy": -t, "Fz": 2 * t, "Tx": t, "Ty": t, "Tz": t},
                     schema="3d", model="m", inputs={})
    assert schema_of(ds).name == "3d" and components(ds, torques=True) == ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")
    assert ds.Fy.attrs["units"] == "N" and ds.Tz.attrs["units"] == "N m"
    with pytest.raises(InputError, match="missing variable 'Fy'"):
        validate(ds.drop_vars("Fy"))
    with pytest.raises(InputError, match="not all torque components"):
        validate(ds.drop_vars("Tz"))
    with pytest.raises(InputError, match="not components of schema '2d'"):
        make_series("time", t, {"Fx": t, "Fz": t, "Fy": t}, model="m", inputs={})


def test_3d_series_flow_through_compare_plots_and_surrogate(toy, tmp_path):
    from terradyn import plots
    from terradyn.dddas import Surrogate
    from terradyn.series import stack

    leg, mot = td.c_leg(n=10), td.standard_rotation(n_theta=21)
    a = models.simulate("toy3d", leg, mot, "x", gain=100.0)
    b = models.simulate("toy3d", leg, mot, "x", gain=200.0)
    assert set(compare.mse(a, b)) == {"Fx", "Fy", "Fz"}
    assert compare.mse(a, b)["Fz"] == pytest.approx(float((a.Fz ** 2).mean()))
    fig = plots.forces({"a": a, "b": b}, tmp_path / "f.png")
    assert len(fig.axes) == 3 and (tmp_path / "f.png").stat().st_size > 5000
    gains = [100.0, 150.0, 200.0, 250.0]
    st = stack([models.simulate("toy3d", leg, mot, "x", gain=g) for g in gains], {"gain": gains})
    sur = Surrogate(inputs=["gain"], n_restarts=0).fit(st)
    assert sur.components_ == ["Fx", "Fy", "Fz"]
    p = sur.predict({"gain": 175.0})
    assert schema_of(p).name == "3d" and "Fy_std" in p
    np.testing.assert_allclose(p.Fz, models.simulate("toy3d", leg, mot, "x", gain=175.0).Fz,
                               atol=0.02 * float(st.Fz.max()))
    with pytest.warns(UserWarning, match="gain=400 is outside the training range"):
        sur.predict({"gain": 400.0})


def test_readme_examples_work_as_written():
    leg = td.c_leg(n=20)
    motion = td.standard_rotation(n_theta=7)
    model = td.stress_model("3 mm glass CP", alpha="table", interp="linear")
    fx, fz, st = td.rft.element_forces(leg, motion, model)
    assert fx.shape == (7, 20) and st.depth.shape == (7, 20)
    # in air the whole way: the SPH model simulates nothing and the force is exactly zero
    air = td.Rotation(0.2, 0.2, -10 * np.pi / 180, 10 * np.pi / 180, 5)
    ds = td.sph.simulate(leg, air, material="3 mm glass CP", quick=True)
    assert float(abs(ds.Fz).max()) == 0.0


def test_rft3d_is_registered_with_the_3d_schema():
    from terradyn import models, rft3d, series

    body = rft3d.plate()
    mot = rft3d.AxisRotation(axis=(0.0, 1.0, 0.0), center=(0.0, 0.0, 0.03), omega=0.2,
                             angle_start=0.0, angle_end=0.5, n=6, position0=(0.0, 0.0, -0.01))
    ds = models.simulate("rft3d", body, mot, "poppy LP")
    assert series.schema_of(ds).name == "3d"
    direct = rft3d.simulate(body, mot, "poppy LP")
    assert np.allclose(ds.Fz.values, direct.Fz.values) and np.abs(ds.Fz.values).max() > 0
    with pytest.raises(InputError, match="model"):
        models.simulate("rft3d", body, mot, "poppy LP", model="nope")
