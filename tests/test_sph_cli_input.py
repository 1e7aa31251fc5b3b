"""`terradyn sph` with bad input: one line naming the field (and the allowed range in the
user's units), exit code 2, and no simulation work; checkpoints that are not the run's own
are left alone; a resumed run says so and gives the uninterrupted run's forces."""
import numpy as np
import pytest

import terradyn.sph as sph_pkg
from terradyn.cli import main
from terradyn.sph import api, solver, validation


class Started(AssertionError):
    pass


@pytest.fixture
def no_work(monkeypatch):
    """Every way the commands start a simulation fails the test."""

    def boom(*a, **k):
        raise Started("a simulation started before the input was checked")

    for mod, name in ((sph_pkg, "simulate"), (api, "simulate"), (api, "leg_scene"), (api, "run"),
                      (solver, "Solver"), (validation, "bed_at_rest"),
                      (validation, "column_collapse"), (validation, "plate_push"),
                      (validation, "rotating_leg")):
        monkeypatch.setattr(mod, name, boom)


def _one_line_error(capsys, field, *parts):
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert err.startswith(f"error: {field}:") and "Traceback" not in err, err
    for p in parts:
        assert p in err, err
    return err


@pytest.mark.parametrize("cmd", [["run", "--quick"], ["bed", "--quick"], ["column", "--quick"],
                                 ["plate", "--quick"], ["legs", "--quick"]])
@pytest.mark.parametrize("dx", ["0", "-1", "nan", "50"])
def test_dx_mm_zero_negative_nan_or_too_coarse(cmd, dx, no_work, capsys, tmp_path):
    assert main(["sph", *cmd, "--dx-mm", dx] + (["--outdir", str(tmp_path)] if cmd[0] == "legs" else [])) == 2
    _one_line_error(capsys, "dx-mm", "finite" if dx == "nan" else "(0, 10] mm")


def test_default_config_treats_zero_dx_as_an_error_not_the_default():
    from terradyn.errors import InputError

    assert api.default_config(True).dx == api.QUICK_DX and api.default_config(dx=None).dx == api.FULL_DX
    for bad in (0.0, -1e-3):
        with pytest.raises(InputError, match="dx"):
            api.default_config(dx=bad)


def test_negative_snapshots(no_work, capsys):
    assert main(["sph", "run", "--quick", "--snapshots", "-3"]) == 2
    _one_line_error(capsys, "snapshots", ">= 0")


@pytest.mark.parametrize("args, field, unit", [
    (["--speed-cm-s", "0"], "speed-cm-s", "cm/s"), (["--speed-cm-s", "-1"], "speed-cm-s", "cm/s"),
    (["--depth-cm", "0"], "depth-cm", "> 0 cm"), (["--depth-cm", "-3"], "depth-cm", "> 0 cm")])
def test_plate_speed_and_depth(args, field, unit, no_work, capsys):
    assert main(["sph", "plate", "--quick", *args]) == 2
    _one_line_error(capsys, field, unit)


def test_plate_push_api_checks_speed():
    from terradyn.errors import InputError

    with pytest.raises(InputError, match="speed"):
        validation.plate_push(speed=0.0)


def test_outputs_checked_before_the_run(no_work, capsys, tmp_path):
    afile = tmp_path / "afile"
    afile.write_text("mine")
    cases = [(["--out", str(tmp_path / "x.xlsx")], "out", ".xlsx"),
             (["--out", str(afile / "x.nc")], "out", "not a directory"),
             (["--out", str(tmp_path)], "out", ""),
             (["--plot", str(tmp_path / "f.bmp")], "plot", ".bmp"),
             (["--plot", str(afile / "f.png")], "plot", "not a directory"),
             (["--snapshots", "3", "--snapshots-out", str(tmp_path / "s.csv")], "snapshots-out", ".nc"),
             (["--checkpoint", str(tmp_path)], "checkpoint", "directory")]
    for args, field, part in cases:
        assert main(["sph", "run", "--quick", *args]) == 2, args
        _one_line_error(capsys, field, part)
    assert afile.read_text() == "mine"
    for cmd in (["bed"], ["column"], ["plate"]):
        assert main(["sph", *cmd, "--quick", "--plot", str(tmp_path / "f.xlsx")]) == 2
        _one_line_error(capsys, "plot", ".xlsx")


def test_legs_outdir_and_checkpoint_dir_that_are_files(no_work, capsys, tmp_path):
    afile = tmp_path / "afile"
    afile.write_text("mine")
    assert main(["sph", "legs", "--quick", "--outdir", str(afile)]) == 2
    _one_line_error(capsys, "out", "not a directory")
    assert main(["sph", "legs", "--quick", "--outdir", str(tmp_path / "o"),
                 "--checkpoint-dir", str(afile)]) == 2
    _one_line_error(capsys, "checkpoint-dir", "not a directory")
    ckdir = tmp_path / "ck"
    ckdir.mkdir()
    (ckdir / "c_w0.2.npz").write_text("not a checkpoint")
    assert main(["sph", "legs", "--quick", "--leg", "flat", "--leg", "c", "--outdir",
                 str(tmp_path / "o"), "--checkpoint-dir", str(ckdir)]) == 2
    _one_line_error(capsys, "checkpoint", "c_w0.2.npz", "not a terradyn checkpoint")
    assert (ckdir / "c_w0.2.npz").read_text() == "not a checkpoint"
    assert afile.read_text() == "mine" and not (tmp_path / "o").exists()


@pytest.mark.parametrize("content", [b"my notes", b"PK\x03\x04 truncated", None])
def test_a_file_that_is_not_a_checkpoint_is_refused_and_kept(content, no_work, capsys, tmp_path):
    ck = tmp_path / "mine.npz"
    if content is None:  # a valid .npz, but not a terradyn checkpoint (no key)
        np.savez(ck, data=np.arange(3))
        content = ck.read_bytes()
    else:
        ck.write_bytes(content)
    assert main(["sph", "run", "--quick", "--checkpoint", str(ck)]) == 2
    _one_line_error(capsys, "checkpoint", "not a terradyn checkpoint", "remove it")
    assert ck.read_bytes() == content


RUN = ["sph", "run", "--dx-mm", "6", "--omega", "2", "--theta-start-deg", "-80",
       "--theta-end-deg", "-70", "--n-theta", "5"]


def test_another_runs_checkpoint_is_refused_before_the_solver(monkeypatch, capsys, tmp_path):
    def boom(*a, **k):
        raise Started("the solver started")

    monkeypatch.setattr(solver, "Solver", boom)
    ck = tmp_path / "ck.npz"
    np.savez(ck, key=np.array("0123456789abcdef"), nrec=np.array(0), rec=np.zeros((0, 4)))
    before = ck.read_bytes()
    assert main(RUN + ["--checkpoint", str(ck), "-o", str(tmp_path / "f.csv")]) == 2
    _one_line_error(capsys, "checkpoint", "not a checkpoint of this run")
    assert ck.read_bytes() == before and not (tmp_path / "f.csv").exists()


def test_interrupted_run_resumes_says_so_and_matches(monkeypatch, capsys, tmp_path):
    full = tmp_path / "full.csv"
    assert main(RUN + ["-o", str(full)]) == 0
    capsys.readouterr()
    real = solver.run

    def interrupted(scene, duration, **kw):
        cb = kw["progress"]

        def progress(done, total):
            cb(done, total)
            if done > 0.5 * total:
                raise KeyboardInterrupt

        return real(scene, duration, **(kw | {"progress": progress, "checkpoint_every": 0.0}))

    ck = tmp_path / "ck.npz"
    out = tmp_path / "f.csv"
    monkeypatch.setattr(api, "run", interrupted)
    assert main(RUN + ["--checkpoint", str(ck), "-o", str(out)]) == 130
    assert ck.exists() and not out.exists()
    capsys.readouterr()
    monkeypatch.setattr(api, "run", real)
    assert main(RUN + ["--checkpoint", str(ck), "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert f"resumed from checkpoint {ck} at step " in err and " s of " in err
    assert out.read_text() == full.read_text()  # the same digits as the uninterrupted run
    assert not ck.exists() and not list(tmp_path.glob("*.tmp.npz"))


@pytest.mark.parametrize("args,field", [(["--dx-mm", "0"], "dx-mm"), (["--slab", "2"], "slab"),
                                        (["--out", "x.xlsx"], "out"), (["--medium", "nope"], "medium"),
                                        (["--plot", "f.xyz"], "plot"), (["--leg", "oval"], "leg"),
                                        (["--so-far"], "so-far")])
def test_leg3d_bad_input_is_one_line_before_work(monkeypatch, capsys, args, field):
    _leg3d_refused(monkeypatch, capsys, args, field)


def test_leg3d_refuses_a_checkpoint_path_holding_another_file(monkeypatch, capsys, tmp_path):
    mine = tmp_path / "mine.npz"
    mine.write_text("not a checkpoint")
    _leg3d_refused(monkeypatch, capsys, ["--checkpoint", str(mine)], "checkpoint")
    assert mine.read_text() == "not a checkpoint"


def _leg3d_refused(monkeypatch, capsys, args, field):
    from terradyn.sph import plate3d

    def boom(*a, **k):
        raise Started("the 3D run started before the input was checked")

    monkeypatch.setattr(plate3d, "leg3d", boom)
    assert main(["sph", "leg3d", *args]) == 2
    _one_line_error(capsys, field)


@pytest.mark.parametrize("leg", ["flat", "c"])
def test_leg3d_writes_the_curves_scores_and_figure(monkeypatch, capsys, tmp_path, leg):
    # the 3D physics is tested in test_sph_plate3d; here the command's plumbing, on a stub run
    import json

    from terradyn.sph import plate3d

    th = np.linspace(-135, 135, 271) * np.pi / 180
    shape = np.clip(np.cos(th), 0, None)

    def fake(mat, **k):
        assert k["omega"] == 1.1 and k["slab"] is None and k["shape"] == leg
        return {"theta": th, "Fz": 4.0 * shape, "Fx": 3.0 * shape, "peak_lift": 4.0,
                "peak_thrust": 3.0, "particles": 10, "steps": 5, "lost": 0, "wall_s": 0.1}

    monkeypatch.setattr(plate3d, "leg3d", fake)
    out, fig = tmp_path / "leg.json", tmp_path / "leg.png"
    assert main(["sph", "leg3d", "--medium", "poppy LP", "--leg", leg, "-o", str(out),
                 "--plot", str(fig)]) == 0
    summary = json.loads(capsys.readouterr().out)
    # scored against that leg's measured curve (Li 2013 Fig. S5: C 9.36 N, flat 4.21 N lift)
    assert summary["leg"] == leg and summary["peak_lift_N"] == 4.0
    assert summary["measured_peak_lift_N"] == pytest.approx(9.3571 if leg == "c" else 4.2121)
    assert summary["rms_thrust_rft_N"] > 0 and summary["rms_lift_N"] > 0
    stored = json.loads(out.read_text())
    assert len(stored["theta_deg"]) == 271 and stored["Fz_N"][135] == pytest.approx(4.0)
    assert fig.stat().st_size > 1000


@pytest.mark.parametrize("cmd", [["run", "--quick"], ["column", "--quick"], ["plate", "--quick"],
                                 ["legs", "--quick"]])
def test_rheology_checked_before_the_run(cmd, no_work, capsys, tmp_path):
    out = ["--outdir", str(tmp_path / "o")] if cmd[0] == "legs" else []
    assert main(["sph", *cmd, "--rheology", "viscous", *out]) == 2
    _one_line_error(capsys, "rheology", "mu-i")


def test_mu_i_needs_a_named_medium(no_work, capsys):
    assert main(["sph", "run", "--quick", "--medium", "my sand", "--density-kg-m3", "1600",
                 "--friction-deg", "30", "--rheology", "mu-i"]) == 2
    _one_line_error(capsys, "rheology", "Li 2013 medium")


def test_validate_checks_rheology_before_making_the_folder(capsys, tmp_path):
    out = tmp_path / "v"
    assert main(["sph", "validate", "--quick", "--out", str(out), "--rheology", "fast"]) == 2
    _one_line_error(capsys, "rheology")
    assert not out.exists()


def test_sweep_cases_carry_the_rheology():
    """A sweep's SPH case names its friction law (a mu(I) case is another case), and the
    material it runs with is the mu(I) one; a bad value names the sweep key."""
    from terradyn import models
    from terradyn.errors import InputError
    from terradyn.models import sph as sph_model

    m = models.get("sph")
    base = {"medium": "poppy LP", "quick": True}
    r0, r1 = m.resolve(dict(base)), m.resolve({**base, "rheology": "mu-i"})
    assert "rheology" not in r0 and r1["rheology"] == "mu-i"
    opts = {k: v for k, v in r1.items() if k not in ("name", "medium")}
    assert sph_model.material("poppy LP", opts).mu_rise > 0
    with pytest.raises(InputError, match="model.rheology"):
        m.resolve({**base, "rheology": "fast"})


@pytest.mark.parametrize("args, field, part", [
    (["--channel-width-cm", "0"], "channel-width-cm", "cm"),
    (["--channel-width-cm", "10", "--wall-friction-deg", "75"], "wall-friction-deg", "deg"),
    (["--wall-friction-deg", "20"], "wall-friction-deg", "channel-width-cm")])
def test_column_side_walls_checked_before_the_run(args, field, part, no_work, capsys):
    assert main(["sph", "column", "--quick", *args]) == 2
    _one_line_error(capsys, field, part)


@pytest.mark.parametrize("value", ["0", "0.5", "60", "nan"])
def test_bed_pad_checked_before_the_run(value, no_work, capsys):
    assert main(["sph", "run", "--quick", "--bed-pad-cm", value]) == 2
    _one_line_error(capsys, "bed-pad-cm", "cm")


@pytest.mark.parametrize("option, value, part", [("--bed-pad-cm", "0", "[1, 50] cm"),
                                                  ("--leg-friction-deg", "75", "[0, 60] deg")])
def test_validate_checks_its_options_before_making_the_folder(option, value, part, capsys, tmp_path):
    out = tmp_path / "v"
    assert main(["sph", "validate", "--quick", "--out", str(out), option, value]) == 2
    _one_line_error(capsys, option.removeprefix("--"), part)
    assert not out.exists()


def test_bed_pad_sets_the_leg_bed_and_names_the_sweep_case(monkeypatch):
    """``bed_pad`` is the bed beyond the leg's path: each side and below it by that much, the
    default (6 cm) unchanged; a sweep case with it is another case."""
    import terradyn as td
    from terradyn import models
    from terradyn.sph.state import SPHConfig
    from terradyn.units import CM, DEG

    seen = []

    def spy(leg, traj, i0, mat, *, bed_width, bed_depth, **kw):
        seen.append((bed_width, bed_depth))
        raise Started("bed sized")

    monkeypatch.setattr(api, "leg_scene", spy)
    mot = td.Rotation(omega=2.0, hip_height=2 * CM, theta_start=-80 * DEG, theta_end=80 * DEG, n_theta=41)
    for pad in (None, 0.06, 0.03):
        with pytest.raises(Started):
            api.simulate(td.flat_leg(), mot, "poppy LP", config=SPHConfig(dx=4e-3, bed_pad=pad))
    (w0, d0), (w6, d6), (w3, d3) = seen
    assert (w0, d0) == (w6, d6)
    assert w6 - w3 == pytest.approx(0.06) and d6 - d3 == pytest.approx(0.03)
    m = models.get("sph")
    base = {"medium": "poppy LP", "quick": True}
    assert "bed_pad_cm" not in m.resolve(dict(base))
    assert m.resolve({**base, "bed_pad_cm": 3.0})["bed_pad_cm"] == 3.0
    assert "bed_pad" not in SPHConfig().run_items()  # checkpoints written before it still resume


def test_plate_bed_pad_sets_the_plate_bed_and_is_checked(monkeypatch, capsys):
    """The plate test's ``config.bed_pad``: the bed reaches that far beyond the plate's edges
    and below its deepest point; None keeps the calibration's bed; ``sph plate --bed-pad-cm``
    sets it, and refuses one out of range before any work."""
    from terradyn.cli import main
    from terradyn.sph.state import SPHConfig
    from terradyn.units import CM

    seen = []

    def spy(leg, traj, i0, mat, *, bed_width, bed_depth, **kw):
        seen.append((bed_width, bed_depth))
        raise Started("bed sized")

    monkeypatch.setattr(api, "leg_scene", spy)
    for pad in (None, 0.12):
        with pytest.raises(Started):
            validation.plate_push(depth=0.04, config=SPHConfig(dx=4e-3, bed_pad=pad))
    main(["sph", "plate", "--quick", "--depth-cm", "4", "--bed-pad-cm", "12"])  # stopped by the spy
    assert "bed sized" in capsys.readouterr().err
    (w0, d0), (w12, d12), (wc, dc) = seen
    L = 3.81 * CM
    assert (w0, d0) == pytest.approx((max(6 * L, 0.15), 0.04 + max(2 * L, 0.04)))
    assert (w12, d12) == pytest.approx((L + 0.24, 0.04 + 0.12)) == (wc, dc)
    assert main(["sph", "plate", "--quick", "--bed-pad-cm", "0.5"]) == 2
    _one_line_error(capsys, "bed-pad-cm", "cm")
    # ``below`` sets the depth below the plate on its own (the width keeps the pad), checked
    with pytest.raises(Started):
        validation.plate_push(depth=0.04, config=SPHConfig(dx=4e-3, bed_pad=0.12), below=0.0762)
    assert seen[-1] == pytest.approx((L + 0.24, 0.04 + 0.0762))
    from terradyn.errors import InputError

    with pytest.raises(InputError, match="below"):
        validation.plate_push(depth=0.04, config=SPHConfig(dx=4e-3, bed_pad=0.12), below=0.001)
    assert len(seen) == 4
    main(["sph", "plate", "--quick", "--depth-cm", "4", "--bed-pad-cm", "16", "--bed-below-cm", "7.62"])
    assert "bed sized" in capsys.readouterr().err
    assert seen[-1] == pytest.approx((L + 0.32, 0.04 + 0.0762))
    assert main(["sph", "plate", "--quick", "--bed-below-cm", "60"]) == 2
    _one_line_error(capsys, "bed-below-cm", "cm")
    assert len(seen) == 5
