"""The `terradyn rft` and `terradyn study` commands, as a user runs them."""
import subprocess
import sys

import numpy as np
import pytest

from terradyn import io
from terradyn.cli import main


def test_rft_writes_netcdf_with_the_full_input(tmp_path, capsys):
    out = tmp_path / "c.nc"
    assert main(["rft", "--leg", "c", "--n-theta", "19", "--medium", "poppy LP", "--out", str(out),
                 "--plot", str(tmp_path / "c.png")]) == 0
    ds = io.read(out)
    assert set(ds.data_vars) >= {"Fx", "Fz", "torque"} and ds.theta.size == 19
    assert ds.attrs["medium"] == "poppy LP" and '"omega_rad_per_s": 0.2' in ds.attrs["input"]
    assert (tmp_path / "c.png").stat().st_size > 10_000


def test_rft_csv_to_stdout_and_file(tmp_path, capsys):
    assert main(["rft", "--leg", "flat", "--n-theta", "5", "--alpha", "table", "--interp", "cubic"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0] == "theta_deg,Fx_N,Fz_N,torque_N_m,time_s" and len(lines) == 6
    assert main(["rft", "--leg", "foot", "--length-cm", "27", "-o", str(tmp_path / "f.csv")]) == 0
    ds = io.read(tmp_path / "f.csv")
    assert ds.theta.values[-1] == pytest.approx(3.0) and float(ds.Fz[-1]) > 10


def test_rft_polyline_and_motion_files(tmp_path, capsys):
    leg = tmp_path / "leg.csv"
    leg.write_text("x_cm,z_cm\n0,0\n-2,-4\n0,-7.62\n")
    mot = tmp_path / "m.csv"
    mot.write_text("time_s,hip_x_cm,hip_z_cm,angle_deg\n" + "\n".join(
        f"{t},{t},{2 - 0.5 * t},{-40 + 20 * t}" for t in np.linspace(0, 4, 9)) + "\n")
    assert main(["rft", "--leg-file", str(leg), "--motion-file", str(mot), "--alpha", "generic",
                 "--zeta", "0.3"]) == 0
    assert capsys.readouterr().out.startswith("time_s,Fx_N,Fz_N")


@pytest.mark.parametrize("args,field", [
    (["--leg", "spoon"], "--leg"),
    (["--medium", "sand"], "medium"),
    (["--elements", "1"], "elements"),
    (["--length-cm", "0"], "length-cm"),
    (["--theta-start-deg", "5", "--theta-end-deg", "5"], "theta-end-deg"),
    (["--omega", "-1"], "omega"),
    (["--curvature", "3"], "curvature"),
    (["--leg-file", "/no/such.csv"], "leg-file"),
    (["--alpha", "generic", "--zeta", "nan"], "zeta"),
    (["-o", "out.txt"], "out"),
])
def test_bad_input_exits_2_naming_the_field(args, field, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["rft", *args]) == 2
    err = capsys.readouterr().err
    assert field in err and "Traceback" not in err


def test_help_lists_media_and_legs():
    r = subprocess.run([sys.executable, "-m", "terradyn", "rft", "--help"], capture_output=True,
                       text=True, env={"COLUMNS": "200", "PATH": ""})
    assert r.returncode == 0
    for word in ("poppy LP", "3 mm glass CP", "reverse-c", "foot", "flat"):
        assert word in r.stdout


def test_study_all_quick_writes_figures_and_data(tmp_path):
    assert main(["study", "all", "--quick", "--out", str(tmp_path)]) == 0
    for f in ("interp_holdout.nc", "alpha_maps.png", "rft_legs.nc", "rft_legs.png", "frames_c.png", "frames.nc",
              "rft_foot.nc", "rft_foot.png", "rft_vs_li2013_s12.csv", "summary.json"):
        assert (tmp_path / f).exists(), f
    legs = io.read(tmp_path / "rft_legs.nc")
    assert list(legs.leg.values) == ["c", "flat", "reverse-c"]


def test_rft_dynamic_lambda_adds_an_inertial_term_quadratic_in_speed_and_linear_in_lambda(tmp_path, capsys):
    """--dynamic-lambda: Agarwal et al. 2021's lambda rho v_n^2 term. It is linear in lambda,
    grows as omega^2 (v = omega r), and vanishes in the slow (quasi-static) limit."""
    def run(omega, lam=None):
        out = tmp_path / f"f{omega}_{lam}.nc"
        args = ["rft", "--leg", "flat", "--n-theta", "37", "--medium", "poppy LP", "--omega", str(omega),
                "-o", str(out)] + ([] if lam is None else ["--dynamic-lambda", str(lam)])
        assert main(args) == 0
        return io.read(out)

    qs = run(20.0)
    d1, d2 = run(20.0, 1.1), run(20.0, 2.2)
    extra1, extra2 = d1.Fz.values - qs.Fz.values, d2.Fz.values - qs.Fz.values
    assert np.abs(extra1).max() > 0.05 * np.abs(qs.Fz.values).max()  # visible at 20 rad/s
    np.testing.assert_allclose(extra2, 2 * extra1, rtol=1e-9, atol=1e-12)
    slow = run(2.0, 1.1).Fz.values - run(2.0).Fz.values
    np.testing.assert_allclose(slow, extra1 / 100, rtol=1e-6, atol=1e-12)  # omega^2
    assert '"lambda": 1.1' in d1.attrs["input"]
