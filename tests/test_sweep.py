"""Sweeps: spec expansion and ids, CLI errors, resumable store, local pool, driver killed mid-sweep."""
from __future__ import annotations

import collections
import importlib.util
import json
import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest
import xarray as xr

import terradyn as td
import terradyn.sweep as sw
from terradyn.cli import main
from terradyn.errors import InputError

SMALL = """
[sweep]
name = "small"
model = "rft"

[leg]
elements = 40

[motion]
n_theta = 37

[model]
medium = "3 mm glass CP"

[grid]
leg.length_cm = [6.0, 7.62]

[[zip]]
leg.shape = ["flat", "c", "reverse-c"]
model.medium = ["3 mm glass CP", "poppy LP", "poppy CP"]
"""


def heavy_spec(n_cases: int) -> str:
    """Cases of ~0.05 s each (2000 elements x 2000 angles), for kill tests."""
    return textwrap.dedent(f"""
        [sweep]
        name = "heavy"
        model = "rft"
        [leg]
        shape = "flat"
        elements = 2000
        [motion]
        n_theta = 2000
        [model]
        medium = "3 mm glass CP"
        [grid]
        leg.length_cm = {{start = 6, stop = 9, num = {n_cases}}}
        """)


# ------------------------------------------------------------------------------------------
# spec
# ------------------------------------------------------------------------------------------
def test_expansion_is_product_of_grid_and_zip_groups():
    s = sw.parse(SMALL)
    assert len(s.cases) == 2 * 3
    assert s.varied == ["leg.length_cm", "leg.shape", "model.medium"]
    pairs = {(c.varied["leg.shape"], c.varied["model.medium"]) for c in s.cases}
    assert pairs == {("flat", "3 mm glass CP"), ("c", "poppy LP"), ("reverse-c", "poppy CP")}
    assert len({c.id for c in s.cases}) == 6
    assert all(len(c.id) == 12 and int(c.id, 16) >= 0 for c in s.cases)


def test_same_case_same_id_however_written():
    """Defaults written out, ints for floats, a range instead of a list, the foot motion as
    the rotation it is: same resolved parameters, same ids."""
    a = sw.parse(textwrap.dedent("""
        [sweep]
        model = "rft"
        [leg]
        shape = "foot"
        [motion]
        kind = "foot"
        max_deg = 3
        [model]
        medium = "poppy LP"
        [grid]
        leg.length_cm = {start = 25, stop = 27, step = 1}
        """))
    b = sw.parse(textwrap.dedent("""
        [sweep]
        model = "rft"
        name = "other name"
        [leg]
        shape = "foot"
        width_cm = 8.5
        elements = 100
        curvature = 0
        [motion]
        kind = "rotation"
        hip_height_cm = 0.0
        theta_start_deg = 0
        theta_end_deg = 3.0
        n_theta = 61
        omega_rad_s = 0.2
        [model]
        medium = "poppy LP"
        alpha = "fit"
        [grid]
        leg.length_cm = [25.0, 26, 27.000000000000004]
        """))
    assert [c.id for c in a.cases] == [c.id for c in b.cases]
    c = sw.parse(textwrap.dedent("""
        [sweep]
        model = "rft"
        [leg]
        shape = "foot"
        length_cm = 26
        [motion]
        kind = "foot"
        [model]
        medium = "poppy LP"
        """))
    assert c.cases[0].id == a.cases[1].id
    d = sw.parse(textwrap.dedent("""
        [sweep]
        model = "rft"
        [leg]
        shape = "foot"
        length_cm = 26
        [motion]
        kind = "foot"
        [model]
        medium = "poppy CP"
        """))
    assert d.cases[0].id != c.cases[0].id


def test_ranges_include_stop_and_linspace():
    s = sw.parse(SMALL.replace("leg.length_cm = [6.0, 7.62]", "motion.omega_rad_s = {start = 0.2, stop = 1.1, step = 0.1}"))
    omegas = sorted({c.params["motion"]["omega_rad_s"] for c in s.cases})
    assert omegas == pytest.approx(np.arange(2, 12) / 10, abs=0) or omegas == [x / 10 for x in range(2, 12)]
    s = sw.parse(SMALL.replace("leg.length_cm = [6.0, 7.62]", "leg.length_cm = {start = 5, stop = 7, num = 5}"))
    assert sorted({c.params["leg"]["length_cm"] for c in s.cases}) == [5.0, 5.5, 6.0, 6.5, 7.0]


BAD = [
    ("[leg]\nlenght_cm = 3\n", "leg.lenght_cm"),
    ('[leg]\nlength_cm = "30"\n', "leg.length_cm"),
    ('[leg]\nelements = 2.5\n', "leg.elements"),
    ('[leg]\nshape = "hoof"\n', "leg.shape"),
    ('[model]\nmedium = "moon dust"\n', "model.medium"),
    ("[grid]\nleg.length_cm = []\n", "grid.leg.length_cm"),
    ("[grid]\nleg.colour = [1, 2]\n", "leg.colour"),
    ('[[zip]]\nleg.length_cm = [1, 2]\nleg.shape = ["c"]\n', "zip[0]"),
    ("[grid]\nmotion.omega_rad_s = [0.2, -1]\n", "motion.omega_rad_s"),
    ("[extra]\nx = 1\n", "extra"),
]


@pytest.mark.parametrize("edit, key", BAD)
def test_bad_spec_is_one_line_naming_the_key(tmp_path, capsys, edit, key):
    base = {"sweep": 'model = "rft"', "leg": 'shape = "flat"', "model": 'medium = "3 mm glass CP"'}
    text = ""
    for sec, line in base.items():
        if f"[{sec}]" in edit:
            if line.split(" =")[0] + " =" not in edit:
                edit = edit.replace(f"[{sec}]\n", f"[{sec}]\n{line}\n")
        else:
            text += f"[{sec}]\n{line}\n"
    p = tmp_path / "bad.toml"
    p.write_text(text + edit)
    assert main(["sweep", "plan", str(p)]) == 2
    err = " ".join(capsys.readouterr().err.split())  # rich may wrap the one line at 80 columns
    assert err.startswith("error:") and err.count("error:") == 1 and key in err, err


def test_unknown_model_and_missing_model(tmp_path, capsys):
    p = tmp_path / "m.toml"
    p.write_text('[sweep]\nmodel = "dem"\n')
    assert main(["sweep", "plan", str(p)]) == 2
    assert "sweep.model" in capsys.readouterr().err
    with pytest.raises(InputError, match="sweep.model"):
        sw.parse("[leg]\nshape = 'flat'\n")


def test_plan_cli_lists_cases(tmp_path, capsys):
    p = tmp_path / "small.toml"
    p.write_text(SMALL)
    assert main(["sweep", "plan", str(p)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == "case_id,leg.length_cm,leg.shape,model.medium"
    assert [line.split(",")[0] for line in out[1:]] == [c.id for c in sw.parse(SMALL).cases]


# ------------------------------------------------------------------------------------------
# storage and execution
# ------------------------------------------------------------------------------------------
def direct(params):
    leg, motion = sw.build(params)
    m = params["model"]
    return td.rft.simulate(leg, motion, td.stress_model(m["medium"], alpha=m["alpha"]), medium=m["medium"])


def test_serial_run_collect_matches_direct_simulation_and_resumes(tmp_path):
    spec = sw.parse(SMALL)
    store = tmp_path / "small.sweep"
    s1 = sw.run(spec, store, workers=0)
    assert (s1.done, s1.skipped, s1.failed) == (6, 0, {})
    ds = sw.collect(store, tmp_path / "small.nc")
    assert ds.sizes == {"case": 6, "theta": 37}
    assert list(ds.case_id.values) == [c.id for c in spec.cases]
    for i, c in enumerate(spec.cases):
        ref = direct(c.params)
        np.testing.assert_array_equal(ds.Fz.isel(case=i).values, ref.Fz.values)
        np.testing.assert_array_equal(ds.Fx.isel(case=i).values, ref.Fx.values)
        assert ds.length_cm.values[i] == c.varied["leg.length_cm"]
        assert ds.shape.values[i] == c.varied["leg.shape"]
        assert json.loads(ds.params.values[i]) == c.params
    assert np.all(ds.wall_time_s.values > 0) and all(ds.host.values)
    back = xr.open_dataset(tmp_path / "small.nc", engine="h5netcdf").load()
    xr.testing.assert_identical(back.drop_vars([]), back)  # readable
    np.testing.assert_array_equal(back.Fz.values, ds.Fz.values)
    assert list(back.medium.values) == [c.varied["model.medium"] for c in spec.cases]
    # per-case provenance in the case file
    one = sw.Store(store).read_case(spec.cases[0].id)
    assert json.loads(one.attrs["sweep_params"]) == spec.cases[0].params
    assert one.attrs["terradyn_version"] == td.__version__ and one.attrs["sweep_host"]
    # rerun: nothing to do
    s2 = sw.run(spec, store, workers=0)
    assert (s2.done, s2.skipped) == (0, 6)
    # a grown spec runs only the new cases
    grown = sw.parse(SMALL.replace("[6.0, 7.62]", "[6.0, 7.62, 9.0]"))
    s3 = sw.run(grown, store, workers=0)
    assert (s3.done, s3.skipped) == (3, 6)
    assert sw.status(store)["done"] == 9


def test_failed_case_does_not_stop_others_and_is_retried(tmp_path, monkeypatch):
    spec = sw.parse(SMALL)
    bad = spec.cases[2].id
    real = sw.run_case

    def flaky(cid, params, *args):
        if cid == bad:
            raise RuntimeError("solver blew up")
        return real(cid, params, *args)

    monkeypatch.setattr("terradyn.sweep.execute.run_case", flaky)
    store = tmp_path / "f.sweep"
    s = sw.run(spec, store, workers=0)
    assert s.done == 5 and list(s.failed) == [bad] and "solver blew up" in s.failed[bad]
    st = sw.status(store)
    assert (st["done"], st["failed"], st["pending"]) == (5, 1, 0)
    assert "solver blew up" in st["failures"][bad]["error"]
    with pytest.raises(InputError, match="not finished"):
        sw.collect(store)
    assert sw.collect(store, partial=True).sizes["case"] == 5
    monkeypatch.setattr("terradyn.sweep.execute.run_case", real)
    s = sw.run(spec, store, workers=0)
    assert (s.done, s.skipped, s.failed) == (1, 5, {})
    assert sw.status(store)["failed"] == 0


def test_crash_while_writing_never_leaves_a_finished_looking_case(tmp_path, monkeypatch):
    spec = sw.parse(SMALL)
    store = tmp_path / "c.sweep"
    real_replace = os.replace
    calls = []

    def dying_replace(src, dst):
        if str(dst).endswith(".nc"):
            if len(calls) == 2:  # die while storing the third case
                raise KeyboardInterrupt("killed")
            calls.append(dst)
        return real_replace(src, dst)

    monkeypatch.setattr("terradyn.sweep.store.os.replace", dying_replace)
    with pytest.raises(KeyboardInterrupt):
        sw.run(spec, store, workers=0)
    st = sw.Store(store)
    assert len(st.done_ids()) == 2
    assert list((store / "cases").glob(".*.tmp"))  # the half-written file exists, unnamed
    monkeypatch.setattr("terradyn.sweep.store.os.replace", real_replace)
    s = sw.run(spec, store, workers=0)
    assert (s.done, s.skipped) == (4, 2)
    assert not list((store / "cases").glob(".*.tmp"))
    for c in spec.cases:
        np.testing.assert_array_equal(st.read_case(c.id).Fz.values, direct(c.params).Fz.values)


def test_store_is_locked_against_a_second_driver(tmp_path):
    spec = sw.parse(SMALL)
    st = sw.Store(tmp_path / "l.sweep")
    st.lock()
    try:
        with pytest.raises(InputError, match="in use"):
            sw.run(spec, st.path, workers=0)
    finally:
        st.unlock()


def test_cli_run_status_collect(tmp_path, capsys):
    p = tmp_path / "small.toml"
    p.write_text(SMALL)
    store = tmp_path / "s.sweep"
    assert main(["sweep", "run", str(p), "--store", str(store), "--workers", "0", "-q",
                 "--out", str(tmp_path / "a.nc")]) == 0
    assert "6 run, 0 already done, 0 failed" in capsys.readouterr().err
    assert main(["sweep", "status", str(store)]) == 0
    assert "6/6 done, 0 failed, 0 pending" in capsys.readouterr().out
    assert main(["sweep", "collect", str(store), "--out", str(tmp_path / "b.nc")]) == 0
    a = xr.open_dataset(tmp_path / "a.nc", engine="h5netcdf").load()
    b = xr.open_dataset(tmp_path / "b.nc", engine="h5netcdf").load()
    np.testing.assert_array_equal(a.Fz.values, b.Fz.values)
    assert main(["sweep", "status", str(tmp_path)]) == 2  # not a store


def _alive_in_group(pgid: int) -> dict[int, str]:
    """Live (not zombie) processes of process group ``pgid``: pid -> command line."""
    out = {}
    for d in os.listdir("/proc"):
        if not d.isdigit():
            continue
        try:
            with open(f"/proc/{d}/stat") as fh:
                fields = fh.read().rsplit(")", 1)[1].split()
            if int(fields[2]) == pgid and fields[0] not in "ZX":
                with open(f"/proc/{d}/cmdline", "rb") as fh:
                    out[int(d)] = fh.read().replace(b"\0", b" ").decode(errors="replace")
        except (OSError, IndexError, ValueError):
            continue
    return out


def test_driver_killed_mid_sweep_then_rerun_loses_nothing_and_repeats_nothing(tmp_path):
    """The driver (``terradyn sweep run --workers 2``, a subprocess) is SIGKILLed mid-sweep and
    the sweep rerun. Lost: a case of the plan missing from the store afterwards, or not the
    plain simulation's numbers. Run twice: a case stored before the kill computed again by
    the rerun, or any case stored twice (counted from the case files present after the kill,
    the rerun's case-done events and each file's ``sweep_run``). Cases in flight when the
    driver died had no stored result and are computed by the rerun: that is not running twice.
    The killed driver's pool workers end with it (on Linux) instead of computing on as orphans."""
    n = 40
    spec_path = tmp_path / "heavy.toml"
    spec_path.write_text(heavy_spec(n))
    store = tmp_path / "h.sweep"
    cmd = [sys.executable, "-m", "terradyn", "sweep", "run", str(spec_path), "--store", str(store),
           "--workers", "2", "-q"]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True)
    pool = {}
    try:
        deadline = time.monotonic() + 90
        while time.monotonic() < deadline and proc.poll() is None:
            if len(sw.Store(store).done_ids()) >= 4:
                break
            time.sleep(0.01)
        if sys.platform.startswith("linux"):
            pool = {p: c for p, c in _alive_in_group(proc.pid).items() if "multiprocessing.spawn" in c}
        os.kill(proc.pid, signal.SIGKILL)  # the driver only
        proc.wait(10)
        if sys.platform.startswith("linux"):  # its pool workers die with it, whatever they were doing
            assert len(pool) == 2, _alive_in_group(proc.pid)
            deadline = time.monotonic() + 20
            while set(pool) & set(_alive_in_group(proc.pid)) and time.monotonic() < deadline:
                time.sleep(0.05)
            assert not set(pool) & set(_alive_in_group(proc.pid)), "orphaned pool workers outlived the driver"
    finally:
        try:
            os.killpg(proc.pid, signal.SIGKILL)  # then its orphaned pool workers
        except ProcessLookupError:
            pass
    assert proc.returncode == -signal.SIGKILL, proc.stderr.read().decode()[-2000:]
    done_before = sw.Store(store).done_ids()
    assert 4 <= len(done_before) < n, "the kill must land mid-sweep"
    s = sw.run(sw.load(spec_path), store, workers=0)
    assert s.skipped == len(done_before) and s.done == n - len(done_before) and not s.failed
    # Per-case run counts: a case counts once for the killed run if its file was there after
    # the kill, and once for every case-done event of the rerun. (The killed run's own events
    # may miss its last case: the kill can land between the rename and the log line.)
    st = sw.Store(store)
    ev = st.events()
    rerun = [e["run"] for e in ev if e["event"] == "run-start"][-1]
    runs = collections.Counter(done_before)
    runs.update(e["case"] for e in ev if e["event"] == "case-done" and e["run"] == rerun)
    spec = sw.load(spec_path)
    assert set(runs) == {c.id for c in spec.cases}  # none lost
    assert set(runs.values()) == {1}  # none run twice
    first = {e["run"] for e in ev if e["event"] == "run-start"} - {rerun}
    for cid in runs:  # each stored file was written by the run that counted it
        assert st.read_case(cid).attrs["sweep_run"] in (first if cid in done_before else {rerun})
    assert sw.status(store)["done"] == n
    ds = sw.collect(store)
    for i in (0, n // 2, n - 1):
        np.testing.assert_array_equal(ds.Fz.isel(case=i).values, direct(spec.cases[i].params).Fz.values)


SPH_TINY = """
[sweep]
model = "sph"
[leg]
shape = "flat"
[motion]
omega_rad_s = 2.0
theta_start_deg = -50
theta_end_deg = -40
n_theta = 6
[model]
medium = "3 mm glass CP"
quick = true
dx_mm = 6
"""


def test_sph_case_through_the_sweep_is_the_direct_simulation(tmp_path):
    sph = pytest.importorskip("terradyn.sph")
    spec = sw.parse(SPH_TINY)
    (c,) = spec.cases
    assert c.params["model"]["dx_mm"] == 6.0 and c.params["model"]["hdx"] == sph.SPHConfig().hdx
    s = sw.run(spec, tmp_path / "sph.sweep", workers=0)
    assert (s.done, s.failed) == (1, {})
    got = sw.Store(tmp_path / "sph.sweep").read_case(c.id)
    leg, motion = sw.build(c.params)
    ref = sph.simulate(leg, motion, "3 mm glass CP", quick=True, config=sph.SPHConfig(dx=6e-3))
    assert got.attrs["model"] == "sph" and np.abs(got.Fz.values).max() > 0.1
    np.testing.assert_allclose(got.Fz.values, ref.Fz.values, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(got.Fx.values, ref.Fx.values, rtol=1e-6, atol=1e-9)


def test_sph_options_are_checked_at_plan_time():
    pytest.importorskip("terradyn.sph")
    with pytest.raises(InputError, match="model.dx_mm"):
        sw.parse(SPH_TINY.replace("dx_mm = 6", "dx_mm = -1"))
    with pytest.raises(InputError, match="model.zeta"):
        sw.parse(SPH_TINY.replace("dx_mm = 6", "zeta = 1"))


def test_case_files_round_trip_exactly_in_both_netcdf_flavours(tmp_path):
    c = sw.parse(SMALL).cases[0]
    _, ds = sw.run_case(c.id, c.params, single_thread=False)
    st = sw.Store(tmp_path / "r.sweep")
    (tmp_path / "r.sweep" / "cases").mkdir(parents=True)
    (tmp_path / "r.sweep" / "failed").mkdir()
    st.write_case("nc3", ds)
    assert st.case_path("nc3").read_bytes()[:3] == b"CDF"
    xr.testing.assert_identical(st.read_case("nc3"), ds)
    with xr.open_dataset(st.case_path("nc3")) as f:  # any NetCDF reader sees the same
        xr.testing.assert_identical(f.load(), ds)
    odd = ds.assign_attrs(note="µm, not ASCII")
    st.write_case("nc4", odd)
    assert st.case_path("nc4").read_bytes()[:4] == b"\x89HDF"
    xr.testing.assert_identical(st.read_case("nc4"), odd)


def test_shipped_specs_plan():
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    specs = sorted((root / "examples" / "sweeps").glob("*.toml")) + sorted((root / "datasets").glob("*.toml"))
    assert len(specs) >= 3
    counts = {}
    for p in specs:
        if "sph" in p.name and importlib.util.find_spec("terradyn.sph") is None:
            continue
        counts[p.stem] = len(sw.load(p).cases)
    assert counts["rft_foot_lengths"] == 11
    if "sph_legs_speeds" in counts:
        s = sw.load(root / "datasets" / "sph_legs_speeds.toml")
        assert len(s.cases) == 30
        assert sorted({c.params["motion"]["omega_rad_s"] for c in s.cases}) == [x / 10 for x in range(2, 12)]
        assert {c.params["model"]["dx_mm"] for c in s.cases} == {2.5}  # the production resolution (docs/sph.md, Convergence)
        assert {c.params["model"]["boundary"] for c in s.cases} == {"resolved"}


def test_shipped_foot_dataset_is_what_its_spec_gives():
    """datasets/rft_foot_lengths.nc matches a fresh in-process RFT run of its spec."""
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    ds = xr.open_dataset(root / "datasets" / "rft_foot_lengths.nc", engine="h5netcdf").load()
    spec = sw.load(root / "datasets" / "rft_foot_lengths.toml")
    assert list(ds.case_id.values) == [c.id for c in spec.cases]
    assert list(ds.length_cm.values) == list(range(25, 36))
    for i in (0, 4, 10):
        np.testing.assert_allclose(ds.Fz.isel(case=i).values, direct(spec.cases[i].params).Fz.values, rtol=1e-12)
    assert np.all(np.diff(ds.Fz.isel(theta=-1).values) > 0)  # longer foot, more lift (brief 2.3)


def test_sph_sweep_takes_a_users_own_medium_and_the_boundary_model(tmp_path):
    """A medium of the user's (density and friction angle) and the leg boundary are sweep
    options, part of the case id, and reach the simulation."""
    sph = pytest.importorskip("terradyn.sph")
    own = SPH_TINY.replace('medium = "3 mm glass CP"',
                           'medium = "my sand"\ndensity_kg_m3 = 1600.0\nfriction_deg = 33.0')
    (c,) = sw.parse(own).cases
    m = c.params["model"]
    assert (m["medium"], m["density_kg_m3"], m["friction_deg"], m["boundary"]) == (
        "my sand", 1600.0, 33.0, "resolved")
    (g,) = sw.parse(SPH_TINY + 'boundary = "guard"\n').cases
    assert g.id != sw.parse(SPH_TINY).cases[0].id and g.params["model"]["boundary"] == "guard"
    with pytest.raises(InputError, match="model.friction_deg"):
        sw.parse(own.replace("friction_deg = 33.0", ""))
    with pytest.raises(InputError, match="model.medium"):
        sw.parse(SPH_TINY.replace('"3 mm glass CP"', '"my sand"'))
    with pytest.raises(InputError, match="model.boundary"):
        sw.parse(SPH_TINY + 'boundary = "glue"\n')
    _, ds = sw.run_case(c.id, c.params, single_thread=True)
    inputs = td.series.inputs_of(ds)
    assert inputs["material"]["density_kg_m3"] == 1600.0
    assert inputs["material"]["friction_deg"] == pytest.approx(33.0)


def test_sph_store_made_with_another_calibration_is_not_resumed(tmp_path, monkeypatch):
    """A store whose finished SPH case ran with other material values than the shipped
    calibration now gives the same case (same case id) is refused before any work: resuming
    would mix two models under one id. Same values: the case is skipped as usual."""
    pytest.importorskip("terradyn.sph")
    from terradyn.models import sph as msph
    from terradyn.series import force_series
    from terradyn.sph import calibration

    spec = sw.parse(SPH_TINY)
    (c,) = spec.cases
    st = sw.Store(tmp_path / "sph.sweep")
    st.claim(spec)
    st.write_plan(spec)

    def finished(material: dict):
        ds = force_series("theta", np.linspace(-50, -40, 6), np.zeros(6), np.ones(6), model="sph",
                          inputs={"medium": "3 mm glass CP", "material": material})
        st.write_case(c.id, ds)

    made = msph.material("3 mm glass CP", {}).describe()
    finished(made)
    s = sw.run(spec, st.path, workers=0)  # nothing to do: same physics
    assert (s.done, s.skipped) == (0, 1)
    cal = dict(calibration.shipped()["3 mm glass CP"], friction_deg=made["friction_deg"] + 3.0)
    monkeypatch.setattr(calibration, "shipped", lambda: {"3 mm glass CP": cal})
    with pytest.raises(InputError, match="friction_deg") as e:
        sw.run(spec, st.path, workers=0)
    assert e.value.field == "store" and c.id in str(e.value)
