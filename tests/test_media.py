"""Stress coefficients against the published numbers of Li, Zhang & Goldman (2013)."""
import numpy as np
import pytest

import terradyn as td
from terradyn.errors import InputError
from terradyn.media import (FITS, INTERPOLATORS, MEDIA, ZETA, generic, packaged_tables,
                            read_tables, stress_model, wrap_angles, zeta_from_plate_test)

MEDIA_NAMES = list(MEDIA)


def test_generic_fit_is_one_for_a_horizontal_plate_pushed_down():
    ax, az = FITS["generic"].alpha(0.0, np.pi / 2)
    assert az / 1e6 == pytest.approx(1.0, abs=1e-3)  # the canonical value of Li 2013
    assert abs(ax) < 1e-6


@pytest.mark.parametrize("medium", MEDIA_NAMES)
def test_measured_grid_matches_table_s1_plate_value(medium):
    # Table S1 lists alpha_z(0, pi/2) measured by a horizontal plate pushed straight down.
    _, az = packaged_tables()[medium].alpha(0.0, np.pi / 2)
    assert az == pytest.approx(MEDIA[medium].alpha_z_plate, rel=0.02)


@pytest.mark.parametrize("medium", MEDIA_NAMES)
def test_fourier_fit_describes_the_measured_grid(medium):
    t = packaged_tables()[medium]
    B, G = np.meshgrid(t.beta, t.gamma, indexing="ij")
    ax, az = FITS[medium].alpha(B, G)
    scale = np.abs(t.alpha_z).max()
    assert np.sqrt(((az - t.alpha_z) ** 2).mean()) < 0.15 * scale
    assert np.sqrt(((ax - t.alpha_x) ** 2).mean()) < 0.10 * scale


@pytest.mark.parametrize("medium", MEDIA_NAMES)
def test_generic_times_zeta_approximates_each_fit(medium):
    b, g = np.meshgrid(np.linspace(-1.5, 1.5, 21), np.linspace(-1.5, 1.5, 21))
    az_m = FITS[medium].alpha(b, g)[1]
    az_g = generic(ZETA[medium]).alpha(b, g)[1]
    assert np.sqrt(((az_g - az_m) ** 2).mean()) < 0.06 * np.abs(az_m).max()


@pytest.mark.parametrize("medium", MEDIA_NAMES)
def test_zeta_from_the_plate_test_recovers_table_s2(medium):
    # Li 2013: zeta ~= 0.8 alpha_z(0, pi/2) in N/cm^3.
    assert zeta_from_plate_test(MEDIA[medium].alpha_z_plate) == pytest.approx(ZETA[medium], rel=0.15)


def _models():
    yield "fit", FITS["poppy CP"]
    for m in INTERPOLATORS:
        yield m, packaged_tables(m)["3 mm glass CP"]


@pytest.mark.parametrize("name,model", list(_models()), ids=lambda x: x if isinstance(x, str) else "")
def test_every_stress_model_obeys_the_mirror_symmetry_and_half_turn(name, model):
    rng = np.random.default_rng(1)
    b = rng.uniform(-4, 4, 400)
    g = rng.uniform(-4, 4, 400)
    ax, az = model.alpha(b, g)
    mx, mz = model.alpha(-b, np.pi - g)
    np.testing.assert_allclose(mz, az, atol=1e-6 * np.abs(az).max())
    np.testing.assert_allclose(mx, -ax, atol=1e-6 * np.abs(az).max())
    hx, hz = model.alpha(b + np.pi, g)  # a plate is the same plate after a half turn
    np.testing.assert_allclose(hz, az, atol=1e-6 * np.abs(az).max())
    np.testing.assert_allclose(hx, ax, atol=1e-6 * np.abs(az).max())


@pytest.mark.parametrize("method", INTERPOLATORS)
def test_interpolators_reproduce_the_grid_nodes(method):
    t = packaged_tables(method)["poppy LP"]
    B, G = np.meshgrid(t.beta, t.gamma, indexing="ij")
    ax, az = t.alpha(B, G)
    tol = 1e-4 * np.abs(t.alpha_z).max()  # spline solves leave round-off of this order
    np.testing.assert_allclose(az, t.alpha_z, atol=tol)
    np.testing.assert_allclose(ax, t.alpha_x, atol=tol)


def test_wrap_angles_lands_in_the_measured_domain():
    rng = np.random.default_rng(2)
    b, g, s = wrap_angles(rng.uniform(-10, 10, 1000), rng.uniform(-10, 10, 1000))
    assert (np.abs(b) <= np.pi / 2 + 1e-12).all() and (np.abs(g) <= np.pi / 2 + 1e-12).all()
    assert set(np.unique(s)) <= {-1.0, 1.0}


def _write(tmp_path, text):
    p = tmp_path / "grid.csv"
    p.write_text(text)
    return p


def _grid_csv(beta_vals, gamma_vals, fmt=lambda b, g: f"{0.1:.3f},{0.01:.3f}"):
    lines = ["medium,beta_rad,gamma_rad,alpha_z_N_per_cm3,alpha_x_N_per_cm3"]
    for b in beta_vals:
        for g in gamma_vals:
            lines.append(f"mine,{b},{g},{fmt(b, g)}")
    return "\n".join(lines) + "\n"


def test_a_users_grid_loads_and_interpolates(tmp_path):
    b = np.linspace(-np.pi / 2, np.pi / 2, 5)
    g = np.linspace(-np.pi / 2, np.pi / 2, 7)
    p = _write(tmp_path, _grid_csv(b, g, lambda b, g: f"{0.2 + 0.1 * np.sin(g):.6f},0"))
    t = read_tables(p)["mine"]
    assert t.alpha(0.3, 0.4)[1] / 1e6 == pytest.approx(0.2 + 0.1 * np.sin(0.4), abs=0.01)
    m = stress_model("mine", alpha="table", table_file=p)
    assert m.alpha(0.0, np.pi / 2)[1] / 1e6 == pytest.approx(0.3, abs=1e-6)


@pytest.mark.parametrize("text,match", [
    ("medium,beta_rad,gamma_rad\nx,0,0\n", "missing column"),
    ("medium,beta_rad,gamma_rad,alpha_z_N_per_cm3,alpha_x_N_per_cm3\nx,0,0,abc,0\n", "non-numeric"),
    ("medium,beta_rad,gamma_rad,alpha_z_N_per_cm3,alpha_x_N_per_cm3\nx,0,0,nan,0\n", "non-finite"),
    ("medium,beta_rad,gamma_rad,alpha_z_N_per_cm3,alpha_x_N_per_cm3\n", "no data rows"),
])
def test_bad_grid_files_are_rejected_with_a_clear_message(tmp_path, text, match):
    with pytest.raises(InputError, match=match):
        read_tables(_write(tmp_path, text))


def test_incomplete_grid_and_degrees_are_rejected(tmp_path):
    b = np.linspace(-np.pi / 2, np.pi / 2, 5)
    g = np.linspace(-np.pi / 2, np.pi / 2, 7)
    text = _grid_csv(b, g)
    with pytest.raises(InputError, match="full beta x gamma grid"):
        read_tables(_write(tmp_path, "\n".join(text.splitlines()[:-1]) + "\n"))
    with pytest.raises(InputError, match="cover|radians"):
        read_tables(_write(tmp_path, _grid_csv(np.degrees(b), np.degrees(g))))
    with pytest.raises(InputError, match="not found"):
        read_tables(tmp_path / "missing.csv")


def test_stress_model_names_bad_choices():
    with pytest.raises(InputError, match="medium"):
        stress_model("sand")
    with pytest.raises(InputError, match="alpha"):
        stress_model("poppy LP", alpha="magic")
    with pytest.raises(InputError, match="interp"):
        stress_model("poppy LP", alpha="table", interp="spline9")
    with pytest.raises(InputError, match="zeta"):
        stress_model("poppy LP", alpha="generic", zeta=-1)
    with pytest.raises(InputError, match="zeta"):
        stress_model("poppy LP", alpha="fit", zeta=0.3)
    assert isinstance(stress_model("anything", alpha="generic", zeta=0.5), td.FourierFit)
