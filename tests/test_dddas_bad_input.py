"""Issue 13's 'Bad input (found by trying it)' list for the dddas commands, and the
resample-move remedy of the coefficient particle filter."""
import numpy as np
import pytest

import terradyn as td
from terradyn import io as tio
from terradyn.cli import main
from terradyn.dddas import GaussianPosterior, ParticleFilter

THETA = np.linspace(-90.0, 90.0, 31)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("bad")
    series = []
    xs = np.linspace(25.0, 35.0, 5)
    s = np.deg2rad(THETA)
    for x in xs:
        series.append(td.force_series("theta", THETA, 0.01 * x * np.sin(s), 0.05 * x * np.cos(s) ** 2,
                                      model="analytic", inputs={}))
    stack = td.stack(series, {"length_cm": xs})
    data = tio.write(stack, d / "stack.nc")
    big = stack.copy()
    big["Fx"] = big["Fx"] * 1e300
    big["Fz"] = big["Fz"] * 1e300
    model = d / "m.nc"
    assert main(["dddas", "fit", str(data), "-o", str(model), "--restarts", "0"]) == 0
    return {"data": data, "big": tio.write(big, d / "big.nc"), "model": model, "dir": d}


def one_line(capsys, *words):
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    for w in words:
        assert w in err[0], err[0]
    return err[0]


@pytest.mark.parametrize("body, words", [
    ("theta_deg,Fz_N\n-90,hello\n", ("Fz_N", "not a number", "hello")),
    ("theta_deg,Fz_N\n-90,1e300\n", ("Fz", "1e+06")),
    ("theta_deg,Fz_N\n", ("no samples",)),
    ("theta_deg,Fz_N\n-60,1\n-70,1\n", ("theta", "increase")),
])
def test_assimilate_bad_observations(files, capsys, body, words):
    p = files["dir"] / "obs.csv"
    p.write_text(body)
    assert main(["dddas", "assimilate", str(files["model"]), "--at", "length_cm=30", "--obs", str(p)]) == 2
    one_line(capsys, *words)


def test_assimilate_bad_stream(files, capsys, monkeypatch):
    import io
    import sys

    for body, words in (("theta_deg,Fz_N\n", ("no samples",)), ("theta_deg,Fz_N\n-60,1\n-70,1\n", ("increase",)),
                        ("theta_deg,Fz_N\n-60,1e300\n", ("within",))):
        monkeypatch.setattr(sys, "stdin", io.StringIO(body))
        assert main(["dddas", "assimilate", str(files["model"]), "--at", "length_cm=30", "--obs", "-",
                     "--method", "exact"]) == 2
        one_line(capsys, *words)


def test_predict_warns_when_extrapolating_and_refuses_a_repeated_condition(files, capsys):
    assert main(["dddas", "predict", str(files["model"]), "--at", "length_cm=-5", "-o",
                 str(files["dir"] / "p.nc")]) == 0
    one_line(capsys, "warning", "length_cm=-5", "outside the training range [25, 35]")
    assert main(["dddas", "predict", str(files["model"]), "--at", "length_cm=30", "-o",
                 str(files["dir"] / "p.nc")]) == 0
    assert capsys.readouterr().err == ""
    assert main(["dddas", "predict", str(files["model"]), "--at", "length_cm=30", "--at", "length_cm=31"]) == 2
    one_line(capsys, "length_cm", "twice")


def test_fit_refuses_huge_forces_and_absurd_restarts(files, capsys):
    out = files["dir"] / "big_model.nc"
    assert main(["dddas", "fit", str(files["big"]), "-o", str(out)]) == 2
    one_line(capsys, "training forces", "1e+12")
    assert not out.exists()
    assert main(["dddas", "fit", str(files["data"]), "-o", str(out), "--restarts", "1000000000"]) == 2
    one_line(capsys, "restarts", "[0, 100]")
    assert main(["dddas", "fit", str(files["data"]), "-o", str(files["dir"] / "m.txt")]) == 2
    one_line(capsys, "out")


def test_resample_move_fixes_the_degeneracy_on_the_linear_model():
    """On a linear-Gaussian model in D = 8 with many informative samples the plain filter's
    mean ends away from the exact posterior's; with resample-move it matches it."""
    rng = np.random.default_rng(0)
    D, S = 8, 200
    th = np.linspace(-1, 1, S)
    H = np.stack([np.cos(np.pi * (k + 1) * th / 2) for k in range(D)], -1)
    c_true = rng.standard_normal(D)
    sigma = 0.05
    y = H @ c_true + sigma * rng.standard_normal(S)
    ex = GaussianPosterior(np.zeros(D), np.eye(D))
    ex.update_many(H, np.zeros(S), y, sigma)
    err = {}
    for name, kw in (("plain", {}), ("move", {"move_sweeps": 2, "jitter": 0.0})):
        pf = ParticleFilter(np.zeros(D), prior_std=np.ones(D), n_particles=2000, rng=1, **kw)
        for k in range(S):
            pf.update(H[k], 0.0, y[k], sigma)
        d = pf.mean - ex.mean
        err[name] = float(d @ np.linalg.solve(ex.cov, d))  # squared Mahalanobis distance
    assert err["move"] < 3.0 * D ** 0.5 + D  # within the posterior's own spread
    assert err["move"] < 0.2 * err["plain"]
