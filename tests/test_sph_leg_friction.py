"""Grain-leg friction (issue 17, build item 3; docs/sph.md "Grain-leg friction"): Coulomb's
law on the force the leg exerts on each grain, an option (``SPHConfig.leg_friction``,
``--leg-friction-deg``, the sweep key ``leg_friction_deg``); the default leg stays rough
(no-slip) and its forces unchanged."""
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from terradyn.cli import main
from terradyn.errors import InputError
from terradyn.sph.materials import from_medium
from terradyn.sph.physics import _leg_slip
from terradyn.sph.state import SPHConfig
from terradyn.units import DEG

sys.path.insert(0, str(Path(__file__).parent))
from test_sph_cli_input import _one_line_error, no_work  # noqa: E402,F401 (a fixture)

_slip = _leg_slip.py_func if hasattr(_leg_slip, "py_func") else _leg_slip


def _split(fx, fz, nx, nz):
    """Normal push and tangential force of the leg on the grain (minus the grain's on the
    leg), along the unit normal (nx, nz)."""
    fn = -(fx * nx + fz * nz)
    return fn, np.hypot(-fx - fn * nx, -fz - fn * nz)


def test_leg_slip_caps_the_tangential_force_and_keeps_momentum_balanced():
    """Random grains: after the cap |F_t| <= mu F_n (0 where the leg pulls), the normal part is
    untouched, a grain under the cap is left exactly as it was, and what the grain's
    acceleration loses the leg's force gains (m da = -df), with the torque of that change
    about the hip at the grain's position."""
    rng = np.random.default_rng(3)
    capped = kept = 0
    for _ in range(2000):
        mu = rng.uniform(0.0, 1.5)
        rx, rz, fx, fz, tq, ax, az = rng.normal(size=7)
        ang = rng.uniform(0, 2 * math.pi)
        lnx, lnz = 3.7 * math.cos(ang), 3.7 * math.sin(ang)  # any length
        mi = rng.uniform(1e-4, 1e-2)
        a2x, a2z, f2x, f2z, t2 = _slip(rx, rz, mi, ax, az, fx, fz, tq, lnx, lnz, mu)
        nx, nz = math.cos(ang), math.sin(ang)
        fn0, ft0 = _split(fx, fz, nx, nz)
        fn1, ft1 = _split(f2x, f2z, nx, nz)
        assert fn1 == pytest.approx(fn0, abs=1e-12)
        assert ft1 <= mu * max(fn0, 0.0) + 1e-12
        if ft0 <= mu * max(fn0, 0.0):
            assert (a2x, a2z, f2x, f2z, t2) == (ax, az, fx, fz, tq)
            kept += 1
        else:
            assert ft1 == pytest.approx(mu * max(fn0, 0.0), abs=1e-12)
            capped += 1
        dfx, dfz = f2x - fx, f2z - fz
        assert mi * (a2x - ax) == pytest.approx(-dfx, abs=1e-12)
        assert mi * (a2z - az) == pytest.approx(-dfz, abs=1e-12)
        assert t2 - tq == pytest.approx(rx * dfz - rz * dfx, abs=1e-12)
    assert capped > 100 and kept > 100


def test_frictionless_leg_takes_all_tangential_force_and_a_pulling_leg_none():
    # grain above a horizontal face (n = +z), pushed up by 2 N and dragged by 1 N along x
    a = _slip(0.0, 0.0, 1.0, 0.0, 0.0, 1.0, -2.0, 0.0, 0.0, 1.0, 0.0)
    assert a[2] == pytest.approx(0.0) and a[3] == pytest.approx(-2.0) and a[0] == pytest.approx(1.0)
    # mu = 0.3: the drag becomes 0.6 N
    a = _slip(0.0, 0.0, 1.0, 0.0, 0.0, 1.0, -2.0, 0.0, 0.0, 1.0, 0.3)
    assert -a[2] == pytest.approx(-0.6)
    # the leg pulls the grain (F_n < 0): no friction at all
    a = _slip(0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 2.0, 0.0, 0.0, 1.0, 0.9)
    assert a[2] == pytest.approx(0.0) and a[3] == pytest.approx(2.0)


def test_config_checks_and_run_key():
    assert "leg_friction" not in SPHConfig().run_items()
    assert SPHConfig(leg_friction=0.2).run_items()["leg_friction"] == 0.2
    for bad in (-0.1, math.radians(61.0), float("nan")):
        with pytest.raises(InputError, match="leg-friction"):
            SPHConfig(leg_friction=bad)
    with pytest.raises(InputError, match="leg-friction.*noslip"):
        SPHConfig(leg_friction=0.2, noslip=False)


@pytest.mark.parametrize("value, part", [("-5", "[0, 60] deg"), ("70", "[0, 60] deg"),
                                         ("nan", "finite")])
def test_cli_refuses_bad_leg_friction_before_any_work(value, part, no_work, capsys):
    assert main(["sph", "run", "--quick", "--leg-friction-deg", value]) == 2
    _one_line_error(capsys, "leg-friction-deg", part)


def test_sweep_key_only_when_set_and_3d_refuses_it():
    from terradyn import models
    from terradyn.sph import plate3d

    m = models.get("sph")
    base = {"medium": "poppy LP", "quick": True}
    assert "leg_friction_deg" not in m.resolve(dict(base))
    assert m.resolve({**base, "leg_friction_deg": 20.0})["leg_friction_deg"] == 20.0
    with pytest.raises(InputError, match="model.leg_friction_deg"):
        m.resolve({**base, "leg_friction_deg": 75.0})
    with pytest.raises(InputError, match="leg-friction"):
        plate3d.plate_push3d("poppy LP", dx=8e-3, config=SPHConfig(dx=8e-3, leg_friction=0.3))


def test_rig_plate_sliding_along_itself_feels_its_friction():
    """Li's small plate dragged along itself at 3 cm depth (the rig's beta = 0, gamma = 0
    point, 4 mm): frictionless, only its 0.64 cm nose resists (well under half the rough
    plate's drag); at 60 deg (mu = 1.7, above what the poppy seeds themselves mobilise) the
    cap seldom binds and the drag is the rough plate's."""
    from terradyn.sph.suite import rig_point

    dx = 4e-3
    mat = from_medium("poppy LP", dx=dx)

    def ax(deg):
        cfg = SPHConfig(dx=dx, leg_friction=None if deg is None else deg * DEG)
        return rig_point(mat, 0.0, 0.0, dx=dx, config=cfg)[1]

    rough, smooth, sixty = ax(None), ax(0.0), ax(60.0)
    assert rough > 0.0
    assert smooth < 0.4 * rough
    assert sixty == pytest.approx(rough, rel=0.1)


def test_validate_passes_leg_friction_to_the_plate_rig_and_legs(monkeypatch):
    """Every scene with a leg or plate runs with the grain-leg friction asked for (and with
    the default configuration when it is not)."""
    from terradyn.sph import calibration, suite

    seen = []

    def plate(mat, *, dx, config=None, **kw):
        seen.append(("plate", None if config is None else config.leg_friction))
        return {"alpha_z": 1.0, "slope": 1.0, "intercept_Pa": 0.0}

    def rig(mat, beta, gamma, *, dx, config=None, **kw):
        seen.append(("rig", None if config is None else config.leg_friction))
        return 0.0, 0.0

    def legs(name, medium, *, config=None, **kw):
        seen.append(("legs", None if config is None else config.leg_friction))
        raise StopIteration

    monkeypatch.setattr(calibration, "plate_slope", plate)
    monkeypatch.setattr(suite, "rig_point", rig)
    monkeypatch.setattr(suite, "leg_vs_measured", legs)
    for lf in (None, 20 * DEG):
        seen.clear()
        with pytest.raises(StopIteration):
            suite.validate(quick=True, scenes=("plate", "rig", "legs"), media=["poppy LP"],
                           leg_friction=lf)
        assert {k for k, _ in seen} == {"plate", "rig", "legs"}
        assert all(v == lf for _, v in seen)
    with pytest.raises(InputError, match="leg-friction"):
        suite.validate(quick=True, scenes=("plate",), media=["poppy LP"], leg_friction=-1.0)


def test_calibrate_takes_the_plate_friction_and_the_merge_refuses_it(monkeypatch, capsys, tmp_path):
    """``sph calibrate --leg-friction-deg`` runs its plate tests with that plate friction
    (checked before any work; recorded in the output), and such a calibration is never
    merged into the shipped file, whose media run with the rough leg."""
    import json

    from terradyn.sph import calibration

    assert main(["sph", "calibrate", "--medium", "poppy LP", "--leg-friction-deg", "61"]) == 2
    _one_line_error(capsys, "leg-friction-deg", "[0, 60] deg")
    seen = []

    def spy(mat, target, *, dx, config=None, **kw):
        seen.append(None if config is None else config.leg_friction)
        raise StopIteration

    monkeypatch.setattr(calibration, "calibrate_friction", spy)
    import terradyn.cli.sph_validate as cmd

    with pytest.raises(StopIteration):
        cmd.calibrate_cmd(medium=["poppy LP"], density_kg_m3=None, alpha_z_n_cm3=None,
                          name="custom", friction_start_deg=None, dx_mm=2.5, youngs_mpa=0.25,
                          tol=0.03, realizations=1, starts="nm", max_evals=2, plate_bed_pad_cm=None,
                          leg_friction_deg=20.0, out=tmp_path / "c.json", store=None)
    assert seen == [pytest.approx(20 * DEG)]
    base = calibration.shipped()
    rec = dict(base["poppy LP"], converged=True)
    new = {"_meta": {"plate_test": dict(calibration.PLATE_TEST, leg_friction_deg=20.0)},
           "poppy LP": rec}
    with pytest.raises(InputError, match="leg_friction_deg"):
        calibration.merge_resolutions(base, json.loads(json.dumps(new)))
