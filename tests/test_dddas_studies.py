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
