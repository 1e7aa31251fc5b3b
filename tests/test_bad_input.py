"""Bad input and faults in every command family, as a new user meets them: each one exits
with the documented code (2 bad input or usage, 1 I/O) and one line on stderr naming the
field, never a traceback, and never after work started (every simulation entry point is
replaced by one that fails the test).

The commands run in-process through ``typer.testing.CliRunner``.
"""
from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest
from typer.testing import CliRunner

from terradyn.cli import get_app


class Started(AssertionError):
    pass


@pytest.fixture
def no_work(monkeypatch):
    """Every way the commands start real work fails the test."""
    import terradyn.dddas.crossval as cv
    import terradyn.dddas.studies as dstudies
    import terradyn.dddas.surrogate as sur
    import terradyn.experiment as ex
    import terradyn.rft.api as rft_api
    import terradyn.sph.api as sph_api
    import terradyn.sph.validation as val
    import terradyn.studies as studies
    import terradyn.sweep.execute as execute

    def boom(*a, **k):
        raise Started("work started before the input was checked")

    for mod, name in ((rft_api, "net_forces"), (sph_api, "leg_scene"), (sph_api, "run"),
                      (val, "bed_at_rest"), (val, "column_collapse"), (val, "plate_push"),
                      (val, "rotating_leg"), (ex, "rft_foot_forces"), (sur.Surrogate, "fit"),
                      (sur.Surrogate, "load"), (cv, "cross_validate"), (dstudies, "legs_study"),
                      (dstudies, "foot_study"), (execute, "simulate_case"),
                      (studies, "interp_study"), (studies, "run_all"), (studies, "frames_study"),
                      (studies, "experiment_study")):
        monkeypatch.setattr(mod, name, boom)


@pytest.fixture
def files(tmp_path, monkeypatch):
    """A working folder with the small files the cases refer to (no simulation made them)."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "afile").write_text("mine")
    (tmp_path / "adir").mkdir()
    (tmp_path / "leg.csv").write_text("x_cm,z_cm\n0,0\n-2,-4\n0,-7.62\n")
    (tmp_path / "badleg.csv").write_text("a,b\n1,2\n3,4\n")
    (tmp_path / "nanleg.csv").write_text("x_cm,z_cm\n0,0\nnan,-4\n0,-7.62\n")
    (tmp_path / "badmotion.csv").write_text("time_s,hip_x_cm\n0,0\n1,1\n")
    (tmp_path / "model.nc").write_text("not read: the bad option fails first")
    (tmp_path / "binary.csv").write_bytes(bytes(range(256)) * 4)
    (tmp_path / "garbage.nc").write_text("not NetCDF")
    (tmp_path / "stack.nc").write_text("not read: the bad option fails first")
    t = np.arange(200) / 200.0  # a 200 Hz trial written by hand
    rows = "\n".join(f"{1e3 * x:g},{min(x, 1):g},{0.3 * min(x, 1):g},1,0.3,{0.01 * x:g},{2 * x:g}" for x in t)
    (tmp_path / "trial.csv").write_text(
        "time_ms,angle_cmd_deg,angle_deg,speed_cmd_deg_s,speed_deg_s,torque_Nm,normal_force_N\n" + rows + "\n")
    base = '[sweep]\nname = "{name}"\nmodel = "rft"\n[leg]\nshape = "c"\n[motion]\nn_theta = 5\n' \
           '[model]\nmedium = "{medium}"\n'
    (tmp_path / "a.toml").write_text(base.format(name="s", medium="poppy LP"))
    (tmp_path / "b.toml").write_text(base.format(name="s", medium="poppy CP"))
    specs = {
        "escape.toml": base.format(name="../../x", medium="poppy LP"),
        "slash.toml": base.format(name="a/b", medium="poppy LP"),
        "dot.toml": base.format(name=".hidden", medium="poppy LP"),
        "bad.toml": "[sweep\nname=",
        "nomodel.toml": '[sweep]\nname = "s"\n[leg]\nshape = "c"\n',
        "unknownmodel.toml": '[sweep]\nmodel = "fem"\n[leg]\nshape = "c"\n[model]\nmedium = "poppy LP"\n',
        "section.toml": base.format(name="s", medium="poppy LP") + "[extra]\nx = 1\n",
        "big.toml": base.format(name="s", medium="poppy LP")
        + "[grid]\nleg.length_cm = {start = 1, stop = 10, num = 10000}\n"
          "motion.omega_rad_s = {start = 0.1, stop = 1, num = 10000}\n",
        "num.toml": base.format(name="s", medium="poppy LP")
        + "[grid]\nleg.length_cm = {start = 1, stop = 10, num = 1000000000}\n",
        "step.toml": base.format(name="s", medium="poppy LP")
        + "[grid]\nleg.length_cm = {start = 1, stop = 1e9, step = 1}\n",
        "shape.toml": base.format(name="s", medium="poppy LP").replace('shape = "c"', 'shape = "spoon"'),
        "alpha.toml": base.format(name="s", medium="poppy LP") + 'alpha = "spoon"\n',
        "zeta.toml": base.format(name="s", medium="poppy LP") + "zeta = 0.3\n",
        "interp.toml": base.format(name="s", medium="poppy LP") + 'interp = "cubic"\n',
        "nomedium.toml": '[sweep]\nmodel = "rft"\n[leg]\nshape = "c"\n',
        "length.toml": base.format(name="s", medium="poppy LP").replace('shape = "c"', 'shape = "c"\nlength_cm = -1'),
        "ntheta.toml": base.format(name="s", medium="poppy LP").replace("n_theta = 5", "n_theta = 1"),
        "empty.toml": base.format(name="s", medium="poppy LP") + "[grid]\nleg.length_cm = []\n",
        "medium.toml": base.format(name="s", medium="mud"),
        "sphdx.toml": base.format(name="s", medium="poppy LP").replace('model = "rft"', 'model = "sph"') + "dx_mm = 0\n",
        "sphphi.toml": base.format(name="s", medium="poppy LP").replace('model = "rft"', 'model = "sph"') + "friction_deg = 95\n",
        "unknownkey.toml": base.format(name="s", medium="poppy LP") + "colour = 3\n",
    }
    for name, text in specs.items():
        (tmp_path / name).write_text(text)
    return tmp_path


RFT = [
    (["--leg", "spoon"], 2, "'--leg'"),
    (["--medium", "sand"], 2, "medium"),
    (["--medium", "generic", "--alpha", "table"], 2, "medium"),
    (["--elements", "1"], 2, "elements"),
    (["--elements", "0"], 2, "elements"),
    (["--elements", "-5"], 2, "elements"),
    (["--elements", "1000000000"], 2, "elements"),
    (["--elements", "ten"], 2, "'--elements'"),
    (["--n-theta", "1"], 2, "n-theta"),
    (["--n-theta", "0"], 2, "n-theta"),
    (["--n-theta", "100000000"], 2, "n-theta"),
    (["--n-theta", "2.5"], 2, "'--n-theta'"),
    (["--length-cm", "0"], 2, "length-cm"),
    (["--length-cm", "-7"], 2, "length-cm"),
    (["--length-cm", "nan"], 2, "length-cm"),
    (["--length-cm", "inf"], 2, "length-cm"),
    (["--width-cm", "0"], 2, "width-cm"),
    (["--width-cm", "-1"], 2, "width-cm"),
    (["--hip-height-cm", "nan"], 2, "hip-height-cm"),
    (["--omega", "0"], 2, "omega"),
    (["--omega", "-1"], 2, "omega"),
    (["--omega", "nan"], 2, "omega"),
    (["--theta-start-deg", "5", "--theta-end-deg", "5"], 2, "theta-end-deg"),
    (["--theta-start-deg", "inf"], 2, "theta-start-deg"),
    (["--curvature", "3"], 2, "curvature"),
    (["--curvature", "-1.5"], 2, "curvature"),
    (["--curvature", "nan"], 2, "curvature"),
    (["--leg-file", "leg.csv", "--curvature", "0.5"], 2, "curvature"),
    (["--leg-file", "/no/such.csv"], 2, "leg-file"),
    (["--leg-file", "badleg.csv"], 2, "leg-file"),
    (["--leg-file", "nanleg.csv"], 2, "leg-file"),
    (["--motion-file", "/no/such.csv"], 2, "motion-file"),
    (["--motion-file", "badmotion.csv"], 2, "motion-file"),
    (["--alpha", "generic", "--zeta", "nan"], 2, "zeta"),
    (["--alpha", "generic", "--zeta", "-1"], 2, "zeta"),
    (["--dynamic-lambda", "-1"], 2, "dynamic"),
    (["--dynamic-lambda", "nan"], 2, "dynamic"),
    (["--dynamic-lambda", "1e9"], 2, "dynamic"),
    (["--dynamic-lambda", "1.1", "--medium", "generic"], 2, "dynamic"),
    (["--alpha", "generic", "--zeta", "0"], 2, "zeta"),
    (["--alpha", "fit", "--zeta", "0.3"], 2, "zeta"),
    (["--alpha", "spoon"], 2, "'--alpha'"),
    (["--interp", "spoon"], 2, "'--interp'"),
    (["--alpha", "table", "--table-file", "/no/such.csv"], 2, "table-file"),
    (["--leg-file", "binary.csv"], 2, "leg-file"),
    (["--leg-file", "adir"], 2, "leg-file"),
    (["--motion-file", "binary.csv"], 2, "motion-file"),
    (["--alpha", "table", "--table-file", "binary.csv"], 2, "table-file"),
    (["--alpha", "table", "--table-file", "leg.csv"], 2, "table-file"),
    (["-o", "out.txt"], 2, "out"),
    (["-o", "adir"], 2, "out"),
    (["-o", "afile/x.nc"], 2, "out"),
    (["-o", "/proc/x.nc"], 2, "out"),
    (["-o", "noext"], 2, "out"),
    (["--plot", "f.xyz"], 2, "plot"),
    (["--plot", "afile/f.png"], 2, "plot"),
    (["--no-such-option"], 2, "--no-such-option"),
]

SPH = [
    (["run", "--quick", "--dx-mm", "0"], 2, "dx-mm"),
    (["run", "--quick", "--dx-mm", "-1"], 2, "dx-mm"),
    (["run", "--quick", "--dx-mm", "50"], 2, "dx-mm"),
    (["run", "--quick", "--dx-mm", "nan"], 2, "dx-mm"),
    (["run", "--quick", "--cfl", "0"], 2, "cfl"),
    (["run", "--quick", "--cfl", "5"], 2, "cfl"),
    (["run", "--quick", "--friction-deg", "0"], 2, "friction-deg"),
    (["run", "--quick", "--friction-deg", "95"], 2, "friction-deg"),
    (["run", "--quick", "--density-kg-m3", "1600"], 2, "friction-deg"),
    (["run", "--quick", "--density-kg-m3", "-5", "--friction-deg", "30"], 2, "density-kg-m3"),
    (["run", "--quick", "--medium", "mud"], 2, "medium"),
    (["run", "--quick", "--boundary", "spoon"], 2, "boundary"),
    (["run", "--quick", "--thickness-cm", "0"], 2, "thickness-cm"),
    (["run", "--quick", "--lowpass-hz", "0"], 2, "lowpass-hz"),
    (["run", "--quick", "--lowpass-hz", "-1"], 2, "lowpass-hz"),
    (["run", "--quick", "--snapshots", "-3"], 2, "snapshots"),
    (["run", "--quick", "--snapshots", "2", "--snapshots-out", "s.csv"], 2, "snapshots-out"),
    (["run", "--quick", "-o", "x.xlsx"], 2, "out"),
    (["run", "--quick", "-o", "afile/x.nc"], 2, "out"),
    (["run", "--quick", "--plot", "afile/f.png"], 2, "plot"),
    (["run", "--quick", "--checkpoint", "adir"], 2, "checkpoint"),
    (["run", "--quick", "--checkpoint", "afile"], 2, "checkpoint"),
    (["run", "--quick", "--omega", "-1"], 2, "omega"),
    (["run", "--quick", "--n-theta", "1"], 2, "n-theta"),
    (["run", "--quick", "--length-cm", "-2"], 2, "length-cm"),
    (["run", "--quick", "--compare-rft", "--density-kg-m3", "1600", "--friction-deg", "30"], 2, "compare-rft"),
    (["run", "--quick", "--backend", "quantum"], 2, "'--backend'"),
    (["plate", "--quick", "--speed-cm-s", "0"], 2, "speed-cm-s"),
    (["plate", "--quick", "--depth-cm", "-3"], 2, "depth-cm"),
    (["bed", "--quick", "--plot", "f.xlsx"], 2, "plot"),
    (["column", "--quick", "--plot", "f.xlsx"], 2, "plot"),
    (["bed", "--quick", "--dx-mm", "0"], 2, "dx-mm"),
    (["legs", "--quick", "--outdir", "afile"], 2, "out"),
    (["legs", "--quick", "-o", "afile"], 2, "out"),
    (["legs", "--quick", "--outdir", "o", "--checkpoint-dir", "afile"], 2, "checkpoint-dir"),
    (["legs", "--quick", "--outdir", "o", "--leg", "spoon"], 2, "leg"),
]

EXPERIMENT = [
    (["filter", "trial.csv", "--cutoff-hz", "0"], 2, "cutoff-hz"),
    (["filter", "trial.csv", "--cutoff-hz", "-1"], 2, "cutoff-hz"),
    (["filter", "trial.csv", "--cutoff-hz", "100"], 2, "cutoff-hz"),  # exactly Nyquist
    (["filter", "trial.csv", "--cutoff-hz", "150"], 2, "cutoff-hz"),
    (["filter", "trial.csv", "--cutoff-hz", "nan"], 2, "cutoff-hz"),
    (["filter", "trial.csv", "--order", "0"], 2, "order"),
    (["filter", "trial.csv", "--order", "13"], 2, "order"),
    (["filter", "trial.csv", "--column", "torque=foo"], 2, "column"),
    (["filter", "trial.csv", "--column", "bogus=x"], 2, "column"),
    (["filter", "trial.csv", "--column", "noequals"], 2, "column"),
    (["filter", "trial.csv", "--unit", "time=hours"], 2, "unit"),
    (["filter", "trial.csv", "--unit", "bogus=s"], 2, "unit"),
    (["filter", "missing.csv"], 2, "trial"),
    (["filter", "binary.csv"], 2, "trial"),
    (["calibrate", "binary.csv"], 2, "trial"),
    (["filter", "trial.csv", "-o", "x.nc"], 2, "out"),
    (["filter", "trial.csv", "-o", "adir"], 2, "out"),
    (["compare", "trial.csv", "-o", "x.csv"], 2, "out"),
    (["compare", "trial.csv", "--offset-N", "nan"], 2, "offset-N"),
    (["compare", "trial.csv", "--length-cm", "-7"], 2, "length-cm"),
    (["compare", "trial.csv", "--zeta", "-1"], 2, "zeta"),
    (["compare", "trial.csv", "--plot", "f.xyz"], 2, "plot"),
    (["compare", "trial.csv", "--cutoff-hz", "100"], 2, "cutoff-hz"),
    (["calibrate", "trial.csv", "--fit", "spoon"], 2, "fit"),
    (["calibrate", "trial.csv", "--use", "spoon"], 2, "use"),
    (["calibrate", "trial.csv", "--length-cm", "0"], 2, "length-cm"),
    (["synth", "-o", "x.nc"], 2, "out"),
    (["synth", "-o", "adir"], 2, "out"),
    (["synth", "-o", "t.csv", "--rate-hz", "1e9"], 2, "rate-hz"),
    (["synth", "-o", "t.csv", "--rate-hz", "0"], 2, "rate-hz"),
    (["synth", "-o", "t.csv", "--duration-s", "-1"], 2, "duration-s"),
    (["synth", "-o", "t.csv", "--noise-N", "-1"], 2, "noise-N"),
    (["synth", "-o", "t.csv", "--lag-s", "-1"], 2, "lag-s"),
    (["synth", "-o", "t.csv", "--commanded-deg", "0"], 2, "commanded-deg"),
    (["synth", "-o", "t.csv", "--commanded-deg", "3", "--reached-deg", "5"], 2, "reached-deg"),
    (["synth", "-o", "t.csv", "--length-cm", "0"], 2, "length-cm"),
    (["synth"], 2, "'--out'"),
]

DDDAS = [
    (["fit", "missing.nc", "-o", "m.nc"], 2, "data"),
    (["fit", "stack.nc", "-o", "m.csv"], 2, "out"),
    (["fit", "stack.nc", "-o", "afile/m.nc"], 2, "out"),
    (["fit", "stack.nc", "-o", "m.nc", "--plot", "f.xyz"], 2, "plot"),
    (["cv", "missing.nc"], 2, "data"),
    (["cv", "leg.csv"], 2, "data"),
    (["cv", "stack.nc", "-o", "x.xlsx"], 2, "out"),
    (["cv", "stack.nc", "--baseline", "missing.nc"], 2, "baseline"),
    (["predict", "missing.nc", "--at", "omega=0.5"], 2, "model"),
    (["predict", "model.nc", "--at", "omega"], 2, "at"),
    (["predict", "model.nc", "--at", "omega=abc"], 2, "at"),
    (["predict", "model.nc"], 2, "at"),
    (["predict", "model.nc", "--at", "omega=0.5", "-o", "x.txt"], 2, "out"),
    (["assimilate", "model.nc", "--at", "omega=0.5", "--obs", "-", "--particles", "1000000000"], 2, "particles"),
    (["assimilate", "model.nc", "--at", "omega=0.5", "--obs", "-", "--particles", "0"], 2, "particles"),
    (["assimilate", "model.nc", "--at", "omega=0.5", "--obs", "-", "--obs-std-N", "0"], 2, "obs-std-N"),
    (["assimilate", "model.nc", "--at", "omega=0.5", "--obs", "-", "--obs-std-N", "-1"], 2, "obs-std-N"),
    (["assimilate", "model.nc", "--at", "omega=0.5", "--obs", "-", "--obs-std-N", "nan"], 2, "obs-std-N"),
    (["assimilate", "model.nc", "--at", "omega=0.5", "--obs", "-", "--jitter", "1.5"], 2, "jitter"),
    (["assimilate", "model.nc", "--at", "omega=0.5", "--obs", "-", "--jitter", "1"], 2, "jitter"),
    (["assimilate", "model.nc", "--at", "omega=0.5", "--obs", "-", "--prior-floor", "-1"], 2, "prior-floor"),
    (["assimilate", "model.nc", "--at", "omega=0.5", "--obs", "-", "--jitter-floor", "-1"], 2, "jitter-floor"),
    (["assimilate", "model.nc", "--at", "omega=0.5", "--obs", "missing.csv"], 2, "obs"),
    (["assimilate", "missing.nc", "--at", "omega=0.5", "--obs", "-"], 2, "model"),
    (["assimilate", "model.nc", "--at", "omega=0.5", "--obs", "-", "-o", "x.xlsx"], 2, "out"),
    (["assimilate", "model.nc", "--at", "=0.5", "--obs", "-"], 2, "at"),
    (["assimilate", "model.nc", "--at", "omega=0.5", "--obs", "-", "--method", "spoon"], 2, "'--method'"),
    (["study", "legs", "--data", "fem", "-o", "o"], 2, "data"),
    (["study", "legs", "--data", "spoon=rft", "-o", "o"], 2, "data"),
    (["study", "legs", "--data", "missing.nc", "-o", "o"], 2, "data"),
    (["study", "legs", "--particles", "0", "-o", "o"], 2, "particles"),
    (["study", "legs", "--particles", "1000000000", "-o", "o"], 2, "particles"),
    (["study", "legs", "-o", "afile"], 2, "out"),
    (["study", "speed", "--data", "fem", "-o", "o"], 2, "data"),
    (["study", "speed", "--particles", "0", "-o", "o"], 2, "particles"),
    (["study", "speed", "-o", "afile"], 2, "out"),
    (["study", "speed", "--leg", "spoon", "-o", "o"], 2, "leg"),
    (["study", "legs", "--leg", "flat", "--leg", "flat", "-o", "o"], 2, "leg"),
    (["study", "foot", "--trial", "missing.csv", "-o", "o"], 2, "trial"),
    (["study", "foot", "--trial", "binary.csv", "-o", "o"], 2, "trial"),
    (["study", "bogus"], 2, "'which'"),
]

SWEEP = [
    (["plan", "missing.toml"], 2, "spec"),
    (["plan", "bad.toml"], 2, "spec"),
    (["plan", "escape.toml"], 2, "sweep.name"),
    (["plan", "slash.toml"], 2, "sweep.name"),
    (["plan", "dot.toml"], 2, "sweep.name"),
    (["plan", "nomodel.toml"], 2, "sweep.model"),
    (["plan", "unknownmodel.toml"], 2, "sweep.model"),
    (["plan", "section.toml"], 2, "extra"),
    (["plan", "big.toml"], 2, "grid"),
    (["plan", "num.toml"], 2, "num"),
    (["plan", "step.toml"], 2, "grid.leg.length_cm"),
    (["plan", "shape.toml"], 2, "leg.shape"),
    (["plan", "alpha.toml"], 2, "model.alpha"),
    (["plan", "zeta.toml"], 2, "model.zeta"),
    (["plan", "interp.toml"], 2, "model.interp"),
    (["plan", "nomedium.toml"], 2, "model.medium"),
    (["plan", "length.toml"], 2, "leg.length_cm"),
    (["plan", "ntheta.toml"], 2, "motion.n_theta"),
    (["plan", "empty.toml"], 2, "grid.leg.length_cm"),
    (["plan", "medium.toml"], 2, "model.medium"),
    (["plan", "sphdx.toml"], 2, "model.dx_mm"),
    (["plan", "sphphi.toml"], 2, "model.friction_deg"),
    (["plan", "unknownkey.toml"], 2, "model.colour"),
    (["run", "a.toml", "--out", "x.csv"], 2, "out"),
    (["run", "a.toml", "--store", "afile"], 2, "store"),
    (["run", "a.toml", "--store", "adir2"], 2, "store"),  # a foreign folder (made below)
    (["run", "a.toml", "--workers", "-1"], 2, "workers"),
    (["run", "a.toml", "--retries", "-1"], 2, "retries"),
    (["run", "missing.toml"], 2, "spec"),
    (["collect", "adir", "--out", "x.csv"], 2, "out"),
    (["collect", "adir", "--out", "x.nc"], 2, "store"),
    (["status", "adir"], 2, "store"),
]

STUDY = [
    (["legs", "--alpha", "spoon", "-o", "o"], 2, "alpha"),
    (["legs", "-o", "afile"], 2, "out"),
    (["legs", "--n-theta", "1", "-o", "o"], 2, "n-theta"),
    (["legs", "--elements", "1", "-o", "o"], 2, "elements"),
    (["legs", "--n-theta", "100000000", "-o", "o"], 2, "n-theta"),
    (["legs", "--medium", "mud", "-o", "o"], 2, "medium"),
    (["legs", "--alpha", "generic", "--zeta", "-1", "-o", "o"], 2, "zeta"),
    (["foot", "--length-cm", "-3", "-o", "o"], 2, "length-cm"),
    (["foot", "--max-deg", "0", "-o", "o"], 2, "max-deg"),
    (["foot", "--width-cm", "0", "-o", "o"], 2, "width-cm"),
    (["frames", "--theta-deg", "nan", "-o", "o"], 2, "theta-deg"),
    (["interp", "--map-medium", "mud", "-o", "o"], 2, "medium"),
    (["all", "-o", "afile"], 2, "out"),
    (["experiment", "-o", "afile/x"], 2, "out"),
]

CASES = ([("rft", a, c, f) for a, c, f in RFT] + [("sph", a, c, f) for a, c, f in SPH]
         + [("experiment", a, c, f) for a, c, f in EXPERIMENT]
         + [("dddas", a, c, f) for a, c, f in DDDAS] + [("sweep", a, c, f) for a, c, f in SWEEP]
         + [("study", a, c, f) for a, c, f in STUDY])


def _id(case):
    family, args, _, field = case
    return f"{family}:{' '.join(args)}"[:80]


def test_the_suite_is_broad():
    assert len(CASES) >= 150
    assert {c[0] for c in CASES} == {"rft", "sph", "experiment", "dddas", "sweep", "study"}


@pytest.mark.parametrize("family,args,code,field", CASES, ids=[_id(c) for c in CASES])
def test_bad_input_is_one_line_naming_the_field(family, args, code, field, files, no_work):
    (files / "adir2").mkdir()
    (files / "adir2" / "notes.txt").write_text("not a sweep")
    argv = [family, *args]
    r = CliRunner().invoke(get_app(), argv, prog_name="terradyn")
    err = r.stderr
    assert "Started" not in err, "work started before the input was checked"
    assert r.exit_code == code, (r.exit_code, err, r.exception)
    assert "Traceback" not in err and "Traceback" not in r.stdout
    lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith("warning:")]
    assert len(lines) == 1, err
    assert lines[0].startswith("error: ") and field in lines[0], err
    # nothing was written over or beside the user's files
    assert (files / "afile").read_text() == "mine"
    assert (files / "adir2" / "notes.txt").read_text() == "not a sweep"


def test_another_spec_on_an_existing_store_is_refused(files, no_work):
    from terradyn import sweep
    from terradyn.sweep.store import Store

    Store(files / "s.sweep").write_plan(sweep.load(files / "a.toml"))
    r = CliRunner().invoke(get_app(), ["sweep", "run", "b.toml"], prog_name="terradyn")
    assert r.exit_code == 2 and r.stderr.startswith("error: store:") and "another spec" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1


@pytest.mark.parametrize("args,field", [
    (["rft", "--interp", "cubic", "--n-theta", "3"], "interp"),
    (["rft", "--table-file", "leg.csv", "--n-theta", "3"], "table-file"),
    (["rft", "--leg", "foot", "--curvature", "0.5", "--n-theta", "3"], "curvature"),
])
def test_an_option_with_no_effect_warns_in_one_line(args, field, files):
    r = CliRunner().invoke(get_app(), args, prog_name="terradyn")
    assert r.exit_code == 0, r.stderr
    assert r.stderr.strip() == r.stderr.strip().splitlines()[0]
    assert r.stderr.startswith(f"warning: {field}:") and "no effect" in r.stderr
    assert r.stdout.startswith("theta_deg,")


def test_messages_quote_the_users_units(files, no_work):
    r = CliRunner().invoke(get_app(), ["experiment", "compare", "trial.csv", "--length-cm", "-7"])
    assert "cm" in r.stderr and "-7" in r.stderr and " m," not in r.stderr
    r = CliRunner().invoke(get_app(), ["sph", "run", "--quick", "--dx-mm", "50"])
    assert "mm" in r.stderr and "50" in r.stderr


def test_gpu_hint_names_the_extra(files, no_work):
    from terradyn.sph.solver import gpu_available

    if gpu_available():
        pytest.skip("a GPU is usable here: --backend gpu is not an error")
    r = CliRunner().invoke(get_app(), ["sph", "run", "--quick", "--backend", "gpu"])
    assert r.exit_code == 2 and "pip install 'terradyn[gpu]'" in r.stderr


def test_help_shows_defaults():
    r = CliRunner().invoke(get_app(), ["rft", "--help"], env={"COLUMNS": "200"})
    assert r.exit_code == 0
    assert "[default: 0.2]" in r.stdout and "default: 7.62; foot 25" in r.stdout


def _run(cmd: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONWARNINGS="ignore")
    return subprocess.run(["bash", "-c", cmd], capture_output=True, text=True, env=env, timeout=120)


def test_full_disk_and_broken_pipe_are_one_line_io_errors():
    py = f"{sys.executable} -m terradyn"
    r = _run(f"{py} rft --n-theta 7 > /dev/full")
    assert r.returncode == 1 and r.stderr.strip() == "error: no space left on device: the output was not written"
    r = _run(f"{py} rft --n-theta 20001 | head -c 10 > /dev/null; exit ${{PIPESTATUS[0]}}")
    assert "Traceback" not in r.stderr
    assert r.returncode in (0, 1)  # 1 when the pipe closed before the data were out
    if r.returncode == 1:
        assert r.stderr.strip().splitlines() == ["error: output pipe closed (broken pipe)"]
