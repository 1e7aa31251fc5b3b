"""Experiment trials: CSV I/O and validation, zero-phase filtering, RFT comparison, calibration."""
import numpy as np
import pytest

from terradyn import experiment as ex
from terradyn.errors import InputError
from terradyn.units import CM


def test_butterworth_is_zero_phase_on_a_known_sinusoid():
    fs = 200.0
    t = np.arange(0, 10, 1 / fs)
    slow = np.sin(2 * np.pi * 1.0 * t)
    fast = 0.5 * np.sin(2 * np.pi * 40.0 * t)
    y = ex.butter_lowpass(slow + fast, fs, cutoff_hz=10.0, order=4)
    mid = slice(200, -200)  # away from the ends
    # Passband: the 1 Hz wave comes through with no delay and unit gain.
    assert np.max(np.abs(y[mid] - slow[mid])) < 0.01
    lags = np.arange(-10, 11)
    xc = [np.dot(np.roll(y, k)[mid], slow[mid]) for k in lags]
    assert lags[int(np.argmax(xc))] == 0
    # Stopband: the 40 Hz wave is gone.
    resid = y[mid] - slow[mid]
    assert np.std(resid) < 0.01 * np.std(fast)
    # A causal filter of the same design would lag: sosfiltfilt must differ from it.
    from scipy.signal import butter, sosfilt

    causal = sosfilt(butter(4, 10.0, fs=fs, output="sos"), slow + fast)
    assert np.max(np.abs(causal[mid] - slow[mid])) > 0.05


def test_filter_input_checks():
    x = np.sin(np.linspace(0, 10, 500))
    with pytest.raises(InputError, match="Nyquist"):
        ex.butter_lowpass(x, 200.0, 150.0)
    with pytest.raises(InputError, match="short"):
        ex.butter_lowpass(x[:10], 200.0, 10.0)
    tr = ex.synthetic_trial(3.0, seed=1)
    t = tr["time"].values.copy()
    t[50:] += 0.003
    with pytest.raises(InputError, match="uniform"):
        ex.lowpass(tr.assign_coords(time=t))


def test_csv_round_trip_custom_columns_and_units(tmp_path):
    tr = ex.synthetic_trial(7.0, seed=2)
    p = ex.write_trial(tr, tmp_path / "trial.csv")
    text = p.read_text()
    assert text.startswith("# SYNTHETIC")
    back = ex.read_trial(p)
    assert back.attrs["synthetic"] == 1
    np.testing.assert_allclose(back["normal_force"].values, tr["normal_force"].values, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(back["time"].values, tr["time"].values, atol=1e-9)
    # The same data with other names and units: seconds and kN.
    q = tmp_path / "other.csv"
    t = tr["time"].values
    with open(q, "w") as fh:
        fh.write("t,theta,Fn_kN\n")
        for a, b, c in zip(t, tr["angle"].values, tr["normal_force"].values):
            fh.write(f"{a:.6f},{b:.8g},{c / 1000:.10g}\n")
    other = ex.read_trial(q, columns={"time": "t", "angle": "theta", "normal_force": "Fn_kN"},
                          units={"time": "s", "normal_force": "kN"})
    np.testing.assert_allclose(other["normal_force"].values, tr["normal_force"].values, rtol=1e-6, atol=1e-6)
    assert other.attrs["synthetic"] == 0 and "torque" not in other


def test_read_trial_validation(tmp_path):
    p = tmp_path / "bad.csv"
    rows = "\n".join(f"{i * 5},{0.01 * i},{0.1 * i}" for i in range(20))
    p.write_text("time_ms,angle_deg,force\n" + rows)
    with pytest.raises(InputError, match="normal_force_N"):
        ex.read_trial(p)
    p.write_text("time_ms,angle_deg,normal_force_N\n" + rows.replace("0.5,", "x,", 1) + "\n100,abc,1\n")
    with pytest.raises(InputError, match="non-numeric"):
        ex.read_trial(p)
    p.write_text("time_ms,angle_deg,normal_force_N\n" + rows + "\n50,1,1\n")
    with pytest.raises(InputError, match="increase"):
        ex.read_trial(p)
    with pytest.raises(InputError):
        ex.read_trial(p, units={"time": "minutes"})


def test_noise_free_trial_matches_rft_at_the_actual_angles():
    tr = ex.synthetic_trial(12.0, length=27 * CM, offset=0.0, lag=0.0, noise=0.0, torque_noise=0.0,
                            angle_noise=0.0, seed=0)
    c = ex.compare(tr, length=27 * CM, cutoff_hz=20.0)
    peak = float(c["normal_force_model"].max())
    assert peak > 10.0  # a 27 cm foot at ~2.5 deg in loose poppy seeds: tens of newtons
    assert c.attrs["normal_force_mse"] < 1e-3 * peak ** 2
    # A longer nominal foot pushes harder (force ~ L^2).
    c2 = ex.compare(tr, length=30 * CM, cutoff_hz=20.0)
    assert float(c2["normal_force_model"].max()) == pytest.approx(peak * (30 / 27) ** 2, rel=0.02)


def test_calibration_recovers_known_parameters_with_honest_uncertainty():
    truth = {"length": 27.5 * CM, "zeta": 0.23, "offset": -0.6}
    tr = ex.synthetic_trial(12.0, length=truth["length"], zeta=truth["zeta"], offset=truth["offset"],
                            lag=0.0, noise=0.3, torque_noise=0.03, seed=11)
    r = ex.calibrate(tr, params=("length", "zeta", "offset"), use=("normal_force", "torque"))
    assert r["success"]
    for k in ("length", "zeta", "offset"):
        err = abs(r["values"][k] - truth[k])
        assert err < 4 * r["std"][k], (k, r["values"][k], truth[k], r["std"][k])
        assert r["std"][k] > 0
    assert abs(r["values"]["length"] - truth["length"]) < 0.01 * truth["length"]
    # Normal force alone: length with zeta fixed at the truth.
    r2 = ex.calibrate(tr, params=("length", "offset"), initial={"zeta": truth["zeta"]})
    assert abs(r2["values"]["length"] - truth["length"]) < 4 * r2["std"]["length"] + 1e-4
    with pytest.raises(InputError, match="identifiable"):
        ex.calibrate(tr, params=("length", "zeta"))


def test_synthetic_trial_is_labelled_and_reaches_the_thesis_angles():
    tr = ex.synthetic_trial(3.0, duration=20.0, seed=0)
    assert tr.attrs["synthetic"] == 1 and "truth" in tr.attrs
    assert float(tr["angle"][-200:].mean()) == pytest.approx(0.84, abs=0.02)
    early = tr["normal_force"].values[:50]
    assert early.mean() < 0  # sensor bias: early samples read negative, as in the thesis
    obs = ex.to_force_series(tr)
    assert np.all(np.diff(obs["theta"].values) > 0)
