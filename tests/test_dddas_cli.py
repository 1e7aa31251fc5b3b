"""The dddas and experiment commands: thin layers that run end to end and fail cleanly."""
import io
import json
import sys

import numpy as np
import pytest

import terradyn as td
from terradyn import io as tio
from terradyn.cli import main

THETA = np.linspace(-90.0, 90.0, 61)


@pytest.fixture(scope="module")
def stack_file(tmp_path_factory):
    d = tmp_path_factory.mktemp("cli")
    series = []
    xs = np.linspace(0.2, 1.1, 8)
    for x in xs:
        s = np.deg2rad(THETA)
        series.append(td.force_series("theta", THETA, 0.2 * x * np.sin(s), (1 + x) * np.cos(s) ** 2,
                                      model="analytic", inputs={}))
    return tio.write(td.stack(series, {"omega": xs}), d / "stack.nc")


def test_fit_predict_assimilate_roundtrip(stack_file, tmp_path, capsys, monkeypatch):
    model = tmp_path / "m.nc"
    assert main(["dddas", "fit", str(stack_file), "-o", str(model)]) == 0
    assert main(["dddas", "predict", str(model), "--at", "omega=0.5", "-o", str(tmp_path / "p.nc")]) == 0
    pred = tio.read(tmp_path / "p.nc")
    s = np.deg2rad(THETA)
    assert np.max(np.abs(pred.Fz.values - 1.5 * np.cos(s) ** 2)) < 0.02
    # Stream observations of a 'true' omega = 0.8 curve on stdin while the prior is at 0.5.
    lines = ["theta_deg,Fz_N"] + [f"{t},{1.8 * np.cos(np.deg2rad(t)) ** 2:.6f}" for t in THETA]
    monkeypatch.setattr(sys, "stdin", io.StringIO("\n".join(lines) + "\n"))
    out = tmp_path / "post.nc"
    assert main(["dddas", "assimilate", str(model), "--at", "omega=0.5", "--obs", "-", "--obs-std-N", "0.01",
                 "--method", "exact", "--prior-floor", "1", "-o", str(out)]) == 0
    post = tio.read(out)
    assert np.max(np.abs(post.Fz.values - 1.8 * np.cos(s) ** 2)) < 0.05


def test_bad_input_exits_2_with_one_line(stack_file, tmp_path, capsys):
    model = tmp_path / "m.nc"
    assert main(["dddas", "fit", str(stack_file), "-o", str(model), "--energy", "1.5"]) == 2
    assert "energy" in capsys.readouterr().err
    main(["dddas", "fit", str(stack_file), "-o", str(model)])
    capsys.readouterr()
    assert main(["dddas", "predict", str(model), "--at", "speed=1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "condition" in err[0]
    bogus = tmp_path / "bogus.nc"
    bogus.write_bytes(b"not netcdf")
    assert main(["dddas", "predict", str(bogus), "--at", "omega=1"]) == 2


def test_experiment_synth_and_calibrate(tmp_path, capsys):
    p = tmp_path / "t.csv"
    assert main(["experiment", "synth", "-o", str(p), "--commanded-deg", "12", "--lag-s", "0",
                 "--length-cm", "28"]) == 0
    assert p.read_text().startswith("# SYNTHETIC")
    capsys.readouterr()
    assert main(["experiment", "calibrate", str(p), "--fit", "length", "--fit", "offset"]) == 0
    r = json.loads(capsys.readouterr().out)
    assert abs(r["values"]["length_cm"] - 28.0) < 0.3
    assert main(["experiment", "filter", str(p), "--cutoff-hz", "500"]) == 2


def test_study_legs_data_keywords(tmp_path, capsys, monkeypatch):
    """`--data rft` asks for RFT-generated data (the default is the shipped SPH set); the
    printed summary names the data; `--data sph` without the dataset fails cleanly."""
    from terradyn.dddas import studies

    real, small = studies.legs_study, studies.rft_standin
    seen = []

    def tiny(out, data, **kw):  # one leg, four hip heights: seconds
        seen.append(data)
        return real(out, data, **{**kw, "legs": ("flat",), "particles": 200})

    monkeypatch.setattr(studies, "legs_study", tiny)
    monkeypatch.setattr(studies, "rft_standin",
                        lambda shape, n_theta=31: small(shape, hip_heights_cm=[1.0, 1.75, 2.5, 3.25], n_theta=21))
    assert main(["dddas", "study", "legs", "--data", "rft", "-o", str(tmp_path)]) == 0
    assert seen == [{"all": "rft"}]
    cap = capsys.readouterr()
    s = json.loads(cap.out)
    assert s["data"]["requested"] == "rft" and s["legs"]["flat"]["source"] == "rft-standin"
    assert "flat: RFT-generated stand-in;" in cap.err and "LOO CV mean MSE" in cap.err
    monkeypatch.setattr(studies, "find_sph_dataset", lambda: None)
    assert main(["dddas", "study", "legs", "--data", "sph", "-o", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "sph_legs_speeds.nc not found" in err[0]
