"""The large-bed plate calibrations (issue 17, docs/sph.md "Bed size"): the standard plate
bed holds the plate up, so a medium calibrated with its plate in a settled bed needs a
steeper friction angle. How they are merged into the shipped file, what they record, and how
a user picks them (``calibration_bed`` / ``--calibration-bed``), checked before any work."""
import math
import sys
from pathlib import Path

import pytest

from terradyn.cli import main
from terradyn.errors import InputError
from terradyn.sph import calibration, validation
from terradyn.sph.materials import MATERIALS, from_medium
from terradyn.units import DEG

sys.path.insert(0, str(Path(__file__).parent))
from test_sph_cli_input import Started, _one_line_error, no_work  # noqa: E402,F401 (a fixture)

LARGE = [m for m, r in calibration.shipped().items() if m != "_meta" and "large_bed" in r]


@pytest.fixture
def no_plate_work(no_work, monkeypatch):
    """As ``no_work``, and the calibration's plate test fails the test too."""

    def boom(*a, **k):
        raise Started("a plate test started before the input was checked")

    monkeypatch.setattr(calibration, "plate_slope", boom)


def test_prandtl_reach_limits_and_the_documented_values():
    """At phi = 0 the log spiral is a circle and the mechanism reaches one footing width past
    the edge; it grows with phi; for Li's 3.81 cm plate 14.4 cm at 27.7 deg and 23 cm at
    35.7 deg (docs/sph.md)."""
    B = 0.0381
    assert calibration.prandtl_reach(0.0, B) == pytest.approx(B, rel=1e-12)
    r = [calibration.prandtl_reach(p * DEG) for p in range(0, 50, 5)]
    assert all(b > a for a, b in zip(r, r[1:]))
    assert calibration.prandtl_reach(27.7 * DEG) == pytest.approx(0.144, abs=0.001)
    assert calibration.prandtl_reach(35.7 * DEG) == pytest.approx(0.230, abs=0.001)


def _base():
    return {"_meta": {"dx_m": 2.5e-3},
            "poppy LP": {"friction_deg": 35.7, "dx_m": 2.5e-3, "converged": True,
                         "other_resolutions": {"1.6": {"friction_deg": 37.0, "dx_m": 1.6e-3}}}}


def _new(pad, phi=37.7, dx=2.5e-3, converged=True):
    return {"_meta": {"created": "today", "realizations": 1,
                      "plate_test": dict(calibration.PLATE_TEST, bed_pad_m=pad)},
            "poppy LP": {"friction_deg": phi, "dx_m": dx, "converged": converged,
                         "plate_test": dict(calibration.PLATE_TEST)}}


def test_a_calibration_in_a_larger_bed_merges_under_large_bed():
    base = _base()
    got = calibration.merge_resolutions(base, _new(0.24))
    rec = got["poppy LP"]
    assert rec["friction_deg"] == 35.7 and "1.6" in rec["other_resolutions"]  # untouched
    big = rec["large_bed"]
    assert big["friction_deg"] == 37.7 and big["plate_test"]["bed_pad_m"] == 0.24
    assert big["bed_over_prandtl_reach"] == pytest.approx(
        0.24 / calibration.prandtl_reach(37.7 * DEG), abs=1e-3)
    assert "large_bed" not in base["poppy LP"]  # the input is not changed
    # a new production calibration keeps the large-bed one and the other resolutions
    again = calibration.merge_resolutions(got, {"poppy LP": {"friction_deg": 35.9, "dx_m": 2.5e-3,
                                                             "converged": True}})
    assert again["poppy LP"]["friction_deg"] == 35.9
    assert again["poppy LP"]["large_bed"]["friction_deg"] == 37.7
    assert "1.6" in again["poppy LP"]["other_resolutions"]


@pytest.mark.parametrize("new, match", [
    (_new(0.08), "Prandtl reach"),           # 8 cm is 0.31 of the 26 cm reach at 37.7 deg
    (_new(0.24, dx=1.6e-3), "production"),   # large-bed calibrations at 2.5 mm only
    (_new(0.24, converged=False), "converge")])
def test_a_large_bed_calibration_that_is_not_one_is_refused(new, match):
    with pytest.raises(InputError, match=match):
        calibration.merge_resolutions(_base(), new)


def test_shipped_large_bed_calibrations_are_steeper_and_settled():
    """Every shipped large-bed calibration: converged at the production spacing, its bed
    recorded and at least half the plate's Prandtl reach, and its friction angle no lower
    than the standard bed's (the standard bed's walls hold the plate up, so the same slope
    needs less friction there); the two media with the largest reach gain the most."""
    assert {"poppy LP", "0.3 mm glass LP"} <= set(LARGE)
    ship = calibration.shipped()
    gain = {}
    for m in LARGE:
        std, big = ship[m], ship[m]["large_bed"]
        assert big["converged"] and big["dx_m"] == std["dx_m"]
        pad = big["plate_test"]["bed_pad_m"]
        assert pad / calibration.prandtl_reach(big["friction_deg"] * DEG) >= calibration.LARGE_BED_MIN_REACH
        meas = big["alpha_z_measured_N_per_cm3"]  # a plate run within 3 % of it was made
        assert min(abs(a / meas - 1) for _, a in big["history"]) <= 0.03
        gain[m] = big["friction_deg"] - std["friction_deg"]
        assert gain[m] >= 0.0, m
    if "poppy LP" in gain and "0.3 mm glass LP" in gain:
        assert gain["poppy LP"] > gain["0.3 mm glass LP"]


@pytest.mark.parametrize("medium", LARGE)
def test_from_medium_takes_the_large_bed_calibration(medium):
    big = calibration.shipped()[medium]["large_bed"]
    mat = from_medium(medium, calibration_bed="large")
    assert mat.friction == pytest.approx(big["friction_deg"] * DEG)
    assert f"plate bed {big['plate_test']['bed_pad_m'] * 100:g} cm" in mat.sources["friction"]
    std = from_medium(medium)
    assert std.friction == pytest.approx(calibration.shipped()[medium]["friction_deg"] * DEG)
    assert mat.with_(friction=std.friction) == std  # only the friction angle differs


@pytest.mark.parametrize("kw, part", [({"friction_deg": 30.0}, "friction angle of your own"),
                                      ({"friction": "repose"}, "repose"),
                                      ({"dilatancy": "bolton"}, "dilatancy"),
                                      ({"calibration_bed": "huge"}, "allowed")])
def test_large_bed_conflicts_are_errors(kw, part):
    kw = {"calibration_bed": "large"} | kw
    with pytest.raises(InputError, match=part):
        from_medium("poppy LP", **kw)


def test_a_medium_without_a_large_bed_calibration_is_an_error(monkeypatch):
    ship = calibration.shipped()
    ship["poppy CP"].pop("large_bed", None)
    monkeypatch.setattr(calibration, "shipped", lambda: ship)
    with pytest.raises(InputError, match="no large-bed plate calibration of 'poppy CP'"):
        from_medium("poppy CP", calibration_bed="large")


@pytest.mark.parametrize("cmd", [["run", "--quick"], ["plate", "--quick"], ["legs", "--quick"],
                                 ["leg3d"]])
def test_cli_checks_the_calibration_bed_before_the_run(cmd, no_plate_work, capsys, tmp_path):
    assert main(["sph", *cmd, "--medium", "poppy LP", "--calibration-bed", "huge",
                 *(["--out", str(tmp_path / "o")] if cmd[0] == "legs" else [])]) == 2
    _one_line_error(capsys, "calibration-bed", "standard, large")
    if cmd[0] != "legs":
        assert main(["sph", *cmd, "--medium", "poppy LP", "--calibration-bed", "large",
                     "--friction-deg", "30"]) == 2
        _one_line_error(capsys, "calibration-bed", "friction angle of your own")
    assert not (tmp_path / "o").exists()


def test_cli_own_medium_has_no_large_bed_calibration(no_plate_work, capsys):
    assert main(["sph", "run", "--quick", "--medium", "my sand", "--density-kg-m3", "1600",
                 "--friction-deg", "30", "--calibration-bed", "large"]) == 2
    _one_line_error(capsys, "calibration-bed", "your own medium")


def test_validate_checks_every_medium_before_making_the_folder(monkeypatch, capsys, tmp_path):
    ship = calibration.shipped()
    ship["3 mm glass CP"].pop("large_bed", None)
    monkeypatch.setattr(calibration, "shipped", lambda: ship)
    out = tmp_path / "v"
    assert main(["sph", "validate", "--out", str(out), "--calibration-bed", "large",
                 "--medium", "poppy LP", "--medium", "3 mm glass CP"]) == 2
    _one_line_error(capsys, "calibration-bed", "'3 mm glass CP'")
    assert not out.exists()


def test_validate_checks_media_names_before_making_the_folder(capsys, tmp_path):
    out = tmp_path / "v"
    assert main(["sph", "validate", "--out", str(out), "--medium", "nosuch"]) == 2
    _one_line_error(capsys, "medium", "poppy LP")
    assert not out.exists()


def test_plate_with_the_large_bed_calibration_runs_in_that_bed(monkeypatch, capsys):
    """``sph plate --calibration-bed large`` pushes the plate in the bed the calibration was
    made in (unless --bed-pad-cm says otherwise), with that calibration's angle."""
    seen = []

    def spy(mat, *, config, **kw):
        seen.append((mat.friction, config.bed_pad))
        raise InputError("spy", "stopped")

    monkeypatch.setattr(validation, "plate_push", spy)
    big = calibration.shipped()["poppy LP"]["large_bed"]
    main(["sph", "plate", "--quick", "--medium", "poppy LP", "--calibration-bed", "large"])
    main(["sph", "plate", "--quick", "--medium", "poppy LP", "--calibration-bed", "large",
          "--bed-pad-cm", "12"])
    main(["sph", "plate", "--quick", "--medium", "poppy LP"])
    (p1, b1), (p2, b2), (p3, b3) = seen
    assert p1 == p2 == pytest.approx(big["friction_deg"] * DEG)
    assert b1 == pytest.approx(big["plate_test"]["bed_pad_m"]) and b2 == pytest.approx(0.12)
    assert p3 == pytest.approx(from_medium("poppy LP", dx=4e-3).friction) and b3 is None


def test_validate_uses_the_large_bed_calibration_and_its_plate_bed(monkeypatch):
    from terradyn.sph import suite

    seen = []

    def spy(mat, *, dx, config=None, **kw):
        seen.append((mat.name, mat.friction, None if config is None else config.bed_pad))
        return {"alpha_z": 0.0, "slope": 0.0, "intercept_Pa": 0.0}

    monkeypatch.setattr(calibration, "plate_slope", spy)
    res = suite.validate(scenes=("plate",), media=["poppy LP"], calibration_bed="large")
    big = calibration.shipped()["poppy LP"]["large_bed"]
    assert seen == [("poppy LP", pytest.approx(big["friction_deg"] * DEG),
                     pytest.approx(big["plate_test"]["bed_pad_m"]))]
    assert res["settings"]["calibration_bed"] == "large"


def test_sweep_cases_carry_the_calibration_bed():
    from terradyn import models
    from terradyn.models import sph as sph_model

    m = models.get("sph")
    base = {"medium": "poppy LP", "quick": True}
    r0, r1 = m.resolve(dict(base)), m.resolve({**base, "calibration_bed": "large"})
    assert "calibration_bed" not in r0 and r1["calibration_bed"] == "large"
    big = calibration.shipped()["poppy LP"]["large_bed"]
    assert sph_model.physics(r1)["friction_deg"] == pytest.approx(big["friction_deg"], abs=1e-3)
    assert sph_model.physics(r0)["friction_deg"] != sph_model.physics(r1)["friction_deg"]
    with pytest.raises(InputError, match="model.calibration_bed"):
        m.resolve({**base, "calibration_bed": "huge"})
    with pytest.raises(InputError, match="model.calibration_bed"):
        m.resolve({**base, "calibration_bed": "large", "friction_deg": 30.0})


def test_shipped_file_meta_says_where_large_bed_calibrations_come_from():
    meta = calibration.shipped()["_meta"]
    assert "large_bed" in meta and "--plate-bed-pad-cm" in meta["large_bed"]
    assert set(LARGE) <= set(MATERIALS)
    assert all(math.isfinite(calibration.shipped()[m]["large_bed"]["friction_deg"]) for m in LARGE)
