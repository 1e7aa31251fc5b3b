"""The DDDAS studies run end to end on given data and write what they promise."""
import json

import numpy as np
import pytest

import terradyn as td
from terradyn.dddas import studies
from terradyn.errors import InputError

THETA = np.linspace(-135.0, 135.0, 91)


def omega_stack():
    """Stand-in for an SPH speed series: forces that change with omega (rad/s)."""
    ws = np.round(np.arange(0.2, 1.15, 0.1), 2)
    out = []
    for w in ws:
        s = np.deg2rad(THETA)
        fz = (1 + w) * np.exp(-((s + 0.4) ** 2) / 0.4) - 0.2 * w * np.sin(2 * s) ** 2
        fx = 0.4 * np.sin(s) * np.exp(-(s ** 2)) * (1 + 0.3 * w ** 2)
        out.append(td.force_series("theta", THETA, fx, fz, model="sph", inputs={"omega": float(w)}))
    ds = td.stack(out, {"omega": ws})
    ds.attrs["model"] = "sph"
    return ds


def test_legs_study_on_given_speed_data(tmp_path):
    s = studies.legs_study(tmp_path, data={"flat": omega_stack()}, legs=("flat",), particles=2000, seed=1)
    leg = s["legs"]["flat"]
    assert leg["inputs"] == ["omega"] and leg["source"] == "sph" and leg["n_conditions"] == 10
    # Interpolating between speeds beats reusing the nearest speed's curve.
    assert leg["cv_mse_mean_N2"]["Fz"] < leg["cv_mse_nearest_mean_N2"]["Fz"]
    a = leg["assimilation"]
    # The posteriors are far more accurate than the noisy samples they were given.
    for v in ("Fx", "Fz"):
        assert a["mse_exact_N2"][v] < 0.2 * a["obs_std_N"][v] ** 2
        assert a["mse_pf_N2"][v] < 0.2 * a["obs_std_N"][v] ** 2
    for f in ("flat_model.nc", "flat_cv.csv", "flat_cv.png", "flat_assimilation.png", "flat_posterior_pf.nc",
              "summary.json"):
        assert (tmp_path / f).is_file(), f
    post = td.io.read(tmp_path / "flat_posterior_pf.nc")
    assert "Fz_std" in post and post.attrs["model"] == "dddas-pf"
    assert json.loads((tmp_path / "summary.json").read_text())["study"] == "dddas-legs"


def test_rft_standin_says_what_it_varies():
    ds = studies.rft_standin("c", hip_heights_cm=[1.0, 2.0, 3.0], n_theta=31)
    assert "hip_height_cm" in ds.coords and "stand-in" in ds.attrs["dddas_note"]
    # Deeper hip (lower hip height) means more sand engaged: a larger peak lift.
    peaks = ds.Fz.max("theta").values
    assert peaks[0] > peaks[1] > peaks[2]


def test_foot_study_assimilation_moves_towards_the_trial(tmp_path):
    s = studies.foot_study(tmp_path, lengths_cm=[25, 27, 29, 31, 33, 35], n_theta=31, particles=2000, seed=2)
    assert s["trial"] == "synthetic" and s["test_cm"] == 29.0
    # Held-out 29 cm: the surrogate interpolates RFT well (force ~ L^2 is smooth).
    assert s["surrogate_vs_rft_at_test_N2"]["Fz"] < 1e-3 * s["rft_peak_Fz_N"] ** 2
    m = s["mse_vs_trial_truth_N2"]
    # The trial was made with a 27 cm foot: assimilating its normal force corrects the 29 cm prior.
    assert m["exact"]["Fz"] < 0.1 * m["prior"]["Fz"]
    assert m["pf"]["Fz"] < 0.1 * m["prior"]["Fz"]
    assert m["pf"]["Fx"] < m["prior"]["Fx"]  # Fx was never observed: corrected through the basis
    assert (tmp_path / "foot_trial.csv").read_text().startswith("# SYNTHETIC")


def test_one_dataset_for_all_legs_is_split_by_its_shape_coordinate():
    """`terradyn sweep collect` stacks all legs along case with a 'shape' coordinate."""
    import xarray as xr

    from terradyn.dddas.studies import rft_standin, split_by_leg

    a = rft_standin("flat", hip_heights_cm=[1.0, 2.0, 3.0], n_theta=31)
    b = rft_standin("c", hip_heights_cm=[1.0, 2.0], n_theta=31)
    both = xr.concat([a.assign_coords(shape=("case", ["flat"] * 3)),
                      b.assign_coords(shape=("case", ["c"] * 2))], dim="case")
    parts = split_by_leg(both)
    assert sorted(parts) == ["c", "flat"]
    assert parts["flat"].sizes["case"] == 3 and parts["c"].sizes["case"] == 2
    assert "shape" not in parts["c"].coords
    np.testing.assert_array_equal(parts["c"].Fz.values, b.Fz.values)
    with pytest.raises(InputError, match="shape"):
        split_by_leg(a)


# -- Which data the legs study uses: the shipped SPH set by default, RFT on request or as a
# -- labelled fallback. Runs use small subsets so that they take seconds.

def test_default_data_is_the_shipped_sph_dataset():
    path = studies.find_sph_dataset()
    assert path is not None and path.name == "sph_legs_speeds.nc" and path.parent.name == "datasets"
    legs, info = studies.resolve_legs_data()
    assert info["requested"] == "default" and not info["fallback_to_rft"] and info["sph_dataset"] == str(path)
    assert list(legs) == ["flat", "c", "reverse-c"]
    for leg, r in legs.items():
        assert r["source"] == "sph" and not r["fallback"] and r["file"] == str(path)
        assert r["label"] == "SPH data: sph_legs_speeds.nc" and "SPH" in r["note"]
        ds = r["data"]
        assert ds.sizes["case"] == 10 and "shape" not in ds.coords
        np.testing.assert_allclose(ds["omega_rad_s"].values, np.round(np.arange(0.2, 1.15, 0.1), 2))
    # The keyword 'sph' is the same data; 'rft' does not even look for it.
    assert studies.resolve_legs_data("sph", legs=("c",))[0]["c"]["file"] == str(path)


def test_rft_on_request_never_looks_for_sph(monkeypatch):
    def boom():
        raise AssertionError("looked for the SPH dataset")

    monkeypatch.setattr(studies, "find_sph_dataset", boom)
    legs, info = studies.resolve_legs_data("rft")
    assert info["requested"] == "rft" and not info["fallback_to_rft"]
    for r in legs.values():
        assert r["data"] is None and r["source"] == "rft-standin" and not r["fallback"]
        assert r["label"] == "RFT-generated stand-in" and r["note"] == studies.STANDIN_NOTE
    monkeypatch.undo()
    mixed, info = studies.resolve_legs_data({"flat": "rft"})
    assert info["requested"] == "per-leg"
    assert [r["source"] for r in mixed.values()] == ["rft-standin", "sph", "sph"]
    with pytest.raises(InputError, match="unknown leg"):
        studies.resolve_legs_data({"hind": "rft"})


def test_missing_sph_dataset_falls_back_to_rft_and_says_so(monkeypatch, tmp_path):
    monkeypatch.setattr(studies, "find_sph_dataset", lambda: None)
    with pytest.raises(InputError, match="not found"):
        studies.resolve_legs_data("sph")
    legs, info = studies.resolve_legs_data()
    assert info["fallback_to_rft"] and "not found" in info["message"] and "RFT" in info["message"]
    assert all(r["fallback"] and r["source"] == "rft-standin" and "not found" in r["label"] for r in legs.values())
    # End to end on a small stand-in: the warning, the saved metadata and the summary say RFT.
    small = studies.rft_standin
    monkeypatch.setattr(studies, "rft_standin",
                        lambda shape, n_theta=31: small(shape, hip_heights_cm=[1.0, 1.75, 2.5, 3.25], n_theta=21))
    with pytest.warns(UserWarning, match="falling back to RFT-generated data"):
        s = studies.legs_study(tmp_path, legs=("flat",), particles=300)
    leg = s["legs"]["flat"]
    assert s["data"]["fallback_to_rft"] and leg["fallback_to_rft"] and leg["source"] == "rft-standin"
    assert leg["inputs"] == ["hip_height_cm"] and "not found" in leg["note"]
    for f in ("flat_data.nc", "flat_posterior_pf.nc"):
        a = td.io.read(tmp_path / f).attrs
        assert a["dddas_source"] == "rft-standin" and "RFT-generated" in a["dddas_data"] and "not found" in a["dddas_note"]
    assert json.loads((tmp_path / "summary.json").read_text())["data"]["fallback_to_rft"] is True


def test_legs_study_runs_on_the_sph_dataset_by_default(monkeypatch, tmp_path):
    """The default path end to end, on a subset of the shipped file found via TERRADYN_DATASETS
    (4 speeds of the flat leg, every 6th angle)."""
    full = td.io.read(studies.find_sph_dataset())
    keep = [i for i, (sh, w) in enumerate(zip(full["shape"].values, full["omega_rad_s"].values))
            if sh == "flat" and round(w * 10) in (2, 5, 8, 11)]
    sub = full.isel(case=keep, theta=slice(None, None, 6))
    d = tmp_path / "data"
    td.io.write(sub, d / "sph_legs_speeds.nc")
    monkeypatch.setenv("TERRADYN_DATASETS", str(d))
    msgs = []
    s = studies.legs_study(tmp_path / "out", legs=("flat",), particles=300, progress=msgs.append)
    assert s["data"] == {"requested": "default", "sph_dataset": str(d / "sph_legs_speeds.nc"),
                         "fallback_to_rft": False, "message": ""}
    leg = s["legs"]["flat"]
    assert leg["source"] == "sph" and leg["data_label"] == "SPH data: sph_legs_speeds.nc"
    assert leg["inputs"] == ["omega_rad_s"] and leg["n_conditions"] == 4 and not leg["fallback_to_rft"]
    assert leg["conditions"]["omega_rad_s"] == pytest.approx([0.2, 0.5, 0.8, 1.1])
    assert any("SPH data: sph_legs_speeds.nc" in m for m in msgs) and not any("WARNING" in m for m in msgs)
    a = td.io.read(tmp_path / "out" / "flat_data.nc").attrs
    assert a["dddas_source"] == "sph" and a["dddas_data_file"] == "sph_legs_speeds.nc" and a["model"] == "sph"


def test_a_leg_missing_from_the_sph_dataset_falls_back_alone(monkeypatch, tmp_path):
    full = td.io.read(studies.find_sph_dataset())
    td.io.write(full.isel(case=full["shape"].values == "flat"), tmp_path / "sph_legs_speeds.nc")
    monkeypatch.setenv("TERRADYN_DATASETS", str(tmp_path))
    legs, info = studies.resolve_legs_data(legs=("flat", "c"))
    assert legs["flat"]["source"] == "sph" and legs["flat"]["file"] == str(tmp_path / "sph_legs_speeds.nc")
    assert legs["c"]["source"] == "rft-standin" and legs["c"]["fallback"] and "no c leg" in legs["c"]["label"]
    assert info["fallback_to_rft"] and "has no 'c' leg" in info["message"]
    with pytest.raises(InputError, match="no 'c' leg"):
        studies.resolve_legs_data("sph", legs=("c",))


def test_figure_titles_name_the_condition_with_units():
    from terradyn.dddas.studies import _cond_text

    assert _cond_text({"omega_rad_s": 0.7}) == "omega = 0.7 rad/s"
    assert _cond_text({"hip_height_cm": 2.5, "length_cm": 29.0}) == "hip height = 2.5 cm, length = 29 cm"


def test_speed_study_scores_every_held_out_case_and_the_filter_reaches_the_exact_posterior(tmp_path):
    s = studies.speed_study(tmp_path, data={"flat": omega_stack()}, legs=("flat",), seeds=(0, 1), particles=2000)
    leg = s["legs"]["flat"]
    assert leg["held_out_cases"] == 10 and leg["held_out"]["omega"] == pytest.approx(np.arange(0.2, 1.15, 0.1))
    for sc in ("assimilation", "forecast"):
        for m in ("prior", "pf", "pf_move", "exact"):
            for c in ("Fx", "Fz"):
                v = leg["mse_N2"][sc][m][c]
                assert len(v) == 20 and np.all(np.isfinite(v))  # 10 cases x 2 seeds
                assert leg["mse_mean_N2"][sc][m][c] == pytest.approx(np.mean(v))
        for m in ("pf", "pf_move", "exact"):
            for c in ("Fx", "Fz"):
                assert leg["mean_over_prior"][sc][m][c] == pytest.approx(
                    leg["mse_mean_N2"][sc][m][c] / leg["mse_mean_N2"][sc]["prior"][c])
            assert leg["never_worse_than_prior"][sc][m] == all(leg["mean_over_prior"][sc][m][c] <= 1 for c in ("Fx", "Fz"))
    # resample-move samples the exact (linear-Gaussian) posterior: its mean MSE is the exact one's
    q = leg["mean_over_prior"]["assimilation"]
    for c in ("Fx", "Fz"):
        assert q["pf_move"][c] == pytest.approx(q["exact"][c], rel=0.1)
    assert json.loads((tmp_path / "speed_study.json").read_text())["study"] == "dddas-speed"
    assert (tmp_path / "speed_study.png").stat().st_size > 10_000


def test_speed_study_cli_for_one_leg_writes_json_figure_and_summary(tmp_path, capsys):
    from terradyn.cli import main

    td.io.write(omega_stack(), tmp_path / "flat.nc")
    rc = main(["dddas", "study", "speed", "--leg", "flat", "--data", f"flat={tmp_path / 'flat.nc'}",
               "--particles", "300", "-o", str(tmp_path / "out")])
    io = capsys.readouterr()
    assert rc == 0
    s = json.loads(io.out)
    assert list(s["legs"]) == ["flat"] and s["seeds"] == [0, 1] and s["particles"] == 300
    assert "flat:" in io.err and "mean posterior MSE / prior MSE" in io.err
    assert (tmp_path / "out" / "speed_study.json").is_file() and (tmp_path / "out" / "speed_study.png").is_file()
