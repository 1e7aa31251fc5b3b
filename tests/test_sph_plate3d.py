"""The 3D plate-test SPH (terradyn.sph.plate3d): its constitutive law against the 2D one, a bed
at rest, the symmetry planes, momentum and energy. Small beds; the study is
benchmarks/sph_plate3d.py."""
from __future__ import annotations

import math

import numpy as np
import pytest

from terradyn.errors import InputError
from terradyn.sph import physics
from terradyn.sph import plate3d as P
from terradyn.sph.materials import from_medium
from terradyn.sph.state import SOIL, SPHConfig
from terradyn.units import DEG, G


def _plane_strain_history(n=400, seed=1):
    """Random plane-strain velocity gradients (x-z) large enough to yield, load and unload,
    and reach the tension cut-off."""
    rng = np.random.default_rng(seed)
    L = rng.normal(0.0, 40.0, (n, 4))
    L[n // 2:n // 2 + 40] = (80.0, 0.0, 0.0, 80.0)  # an extension: to the tension cut-off
    return L, rng.normal(0.0, 5e3, n)


@pytest.mark.parametrize("medium,dilatancy", [("poppy LP", "none"), ("0.3 mm glass CP", "bolton")])
@pytest.mark.parametrize("compiled", [False, True])
def test_3d_drucker_prager_reduces_to_the_2d_update_for_plane_strain(medium, dilatancy, compiled):
    mat = from_medium(medium, dilatancy=dilatancy)
    f2 = physics.dp_update.py_func  # (its compiled form is inlined into the 2D loops)
    f3 = P.dp_update3 if compiled else P.dp_update3.py_func
    L, drho = _plane_strain_history()
    dt = 1e-4
    consts = (dt, mat.shear_modulus, mat.bulk_modulus, mat.alpha_phi, mat.k_c, 0.9 * mat.density,
              1.1 * mat.density, mat.alpha_psi, mat.dilation_limit)
    s2 = (mat.density, -800.0, -1500.0, 30.0, -700.0)  # rho, sxx, szz, sxz, syy
    s3 = (mat.density, -800.0, -700.0, -1500.0, 0.0, 30.0, 0.0)  # rho, sxx, syy, szz, sxy, sxz, syz
    yielded = cut = 0
    for k in range(len(drho)):
        lxx, lxz, lzx, lzz = L[k]
        rho, sxx, szz, sxz, syy = f2(s2[0], drho[k], lxx, lxz, lzx, lzz, *s2[1:], *consts,
                                     *mat.rate_constants.values())
        r3 = f3(s3[0], drho[k], lxx, 0.0, lxz, 0.0, 0.0, 0.0, lzx, 0.0, lzz, *s3[1:], *consts)
        want = (rho, sxx, syy, szz, 0.0, sxz, 0.0)
        scale = max(abs(sxx), abs(szz), abs(syy), 1.0)
        for got, ref in zip(r3[1:], want[1:]):
            assert abs(got - ref) <= 1e-12 * scale
        assert r3[0] == pytest.approx(rho, rel=1e-14)
        i1 = sxx + szz + syy
        m = i1 / 3
        j2 = 0.5 * ((sxx - m) ** 2 + (szz - m) ** 2 + (syy - m) ** 2) + sxz ** 2
        yielded += math.sqrt(j2) >= 0.999 * (-mat.alpha_phi * i1) > 0
        cut += abs(i1) < 1e-9
        s2 = (rho, sxx, szz, sxz, syy)
        s3 = r3
    assert yielded > 20  # the history exercised the return ...
    if dilatancy == "none":
        assert cut > 5  # ... and the tension cut-off (a dilatant packing stays compressed)


def test_3d_return_is_objective_and_isotropic_in_the_out_of_plane_direction():
    """A strain rate in the y-z plane gives the numbers of the same rate in the x-z plane with
    x and y swapped (the 3D update has no preferred in-plane axis)."""
    mat = from_medium("3 mm glass CP")
    c = (1e-4, mat.shear_modulus, mat.bulk_modulus, mat.alpha_phi, mat.k_c, 0.9 * mat.density,
         1.1 * mat.density, 0.0, 0.0)
    rho = mat.density
    a = P.dp_update3(rho, 10.0, 3.0, 0.0, 7.0, 0.0, -1.0, 0.0, -2.0, 0.0, 4.0,
                     -900.0, -500.0, -1400.0, 0.0, 60.0, 0.0, *c)
    b = P.dp_update3(rho, 10.0, -1.0, 0.0, 0.0, 0.0, 3.0, 7.0, 0.0, -2.0, 4.0,
                     -500.0, -900.0, -1400.0, 0.0, 0.0, 60.0, *c)
    # (rho, sxx, syy, szz, sxy, sxz, syz): b is a with x <-> y
    assert b[1] == pytest.approx(a[2]) and b[2] == pytest.approx(a[1])
    assert b[3] == pytest.approx(a[3]) and b[6] == pytest.approx(a[5])
    assert b[5] == pytest.approx(a[6], abs=1e-9) and b[4] == pytest.approx(a[4], abs=1e-9)


def test_geostatic_bed_at_rest_stays_at_rest():
    cfg = SPHConfig(dx=5e-3)
    sc = P.plate_scene("3 mm glass CP", config=cfg, half_x=0.03, half_y=0.025, depth=0.04,
                       with_plate=False)
    s = P.Solver3D(sc)
    n = 300
    s.advance(np.zeros((n, 6)), np.zeros(n))  # undamped: the initial state must hold
    soil = s.soil
    z = s.pos[soil, 2]
    szz = s.sig[soil, P.S_ZZ]
    inner = (z < -2 * cfg.dx) & (z > -sc.depth + 2 * cfg.dx)
    slope = np.polyfit(-z[inner], -szz[inner], 1)[0]
    assert slope == pytest.approx(sc.material.density * G, rel=0.04)
    k0 = s.sig[soil, P.S_XX][inner] / szz[inner]
    assert np.median(k0) == pytest.approx(sc.material.lateral_ratio, rel=0.1)
    assert np.median(s.sig[soil, P.S_YY][inner] / szz[inner]) == pytest.approx(np.median(k0), rel=0.05)
    v = np.linalg.norm(s.vel[soil], axis=1)
    # at rest: far below the speed a free fall over the run would give (g t)
    assert v.max() < 0.05 * G * n * s.dt
    assert s.lost == 0


def _push(mirror_x):
    cfg = SPHConfig(dx=5e-3, settle_time=0.005)
    return P.plate_push3d("3 mm glass CP", config=cfg, half_x=0.03, half_y=0.018, depth=0.02,
                          speed=0.2, push_depth=0.002, n_samples=5, fit_from=0.0,
                          mirror_x=mirror_x)


def test_plate_feels_no_net_lateral_force_and_the_x_mirror_equals_both_halves():
    half = _push(False)  # both halves in x, a wall at each end
    quarter = _push(True)
    fz = half["fz_quarter_N"][-1]
    assert fz > 0.05  # the plate is in the bed and pushed up
    # both halves simulated: the lateral forces cancel
    assert abs(half["fx_quarter_N"][-1]) < 0.01 * fz
    # the mirror plane x = 0 stands for the other half: the same stress on the plate
    assert quarter["stress"][-1] == pytest.approx(half["stress"][-1], rel=0.02)
    assert quarter["force_factor"] == 4.0 and half["force_factor"] == 2.0
    assert quarter["ghosts"] > 0 and quarter["particles"] < 0.6 * half["particles"]


def test_momentum_is_conserved_and_energy_not_created_in_a_free_block():
    mat = from_medium("poppy LP")
    cfg = SPHConfig(dx=5e-3)
    dx = cfg.dx
    pos = P._grid3(0, 6 * dx, 0, 6 * dx, 0, 6 * dx, dx)
    n = len(pos)
    rng = np.random.default_rng(3)
    vel = rng.normal(0.0, 0.05, (n, 3))
    sig = np.zeros((n, 6))
    sig[:, :3] = -200.0  # a confined block, released
    rho = np.full(n, mat.density)
    sc = P.Scene3D(pos, np.full(n, SOIL, np.int8), rho * dx ** 3, rho, sig, vel, mat, cfg,
                   np.zeros(n), np.zeros(n), np.zeros(n), np.zeros((0, 3)), mirror=(False, False, False),
                   gravity=0.0, depth=6 * dx)
    s = P.Solver3D(sc)
    m = s.mass[:n, None]

    def energy():
        sg = s.sig[:n]
        p = -sg[:, :3].mean(axis=1)
        dev = sg[:, :3] + p[:, None]
        s2 = (dev ** 2).sum(axis=1) + 2 * (sg[:, 3:] ** 2).sum(axis=1)
        vol = s.mass[:n] / s.rho[:n]
        elastic = vol * (s2 / (4 * mat.shear_modulus) + p ** 2 / (2 * mat.bulk_modulus))
        return 0.5 * float((m[:, 0] * (s.vel[:n] ** 2).sum(axis=1)).sum()) + float(elastic.sum())

    p0 = (m * s.vel[:n]).sum(axis=0)
    e0 = energy()
    s.advance(np.zeros((200, 6)), np.zeros(200))
    p1 = (m * s.vel[:n]).sum(axis=0)
    scale = float((m * np.abs(vel)).sum())
    assert np.abs(p1 - p0).max() < 1e-12 * scale
    assert energy() < e0 * 1.01


def test_bad_requests_are_refused_before_any_allocation():
    with pytest.raises(InputError, match="dx"):
        P.plate_scene("poppy LP", dx=4e-4)
    with pytest.raises(InputError, match="slab"):
        P.plate_scene("poppy LP", dx=4e-3, slab=2)
    with pytest.raises(InputError, match="speed"):
        P.plate_push3d("poppy LP", speed=0.0)


def test_shape_factor_is_the_de_beer_surcharge_factor():
    assert P.shape_factor(P.PLATE_LENGTH, P.PLATE_WIDTH, 36 * DEG) == pytest.approx(
        1 + (2.54 / 3.81) * math.tan(36 * DEG))
    assert P.shape_factor(P.PLATE_WIDTH, P.PLATE_LENGTH, 36 * DEG) == pytest.approx(
        P.shape_factor(P.PLATE_LENGTH, P.PLATE_WIDTH, 36 * DEG))


def test_vertical_plate_pushed_horizontally_is_resisted_and_at_rest_feels_no_net_push():
    cfg = SPHConfig(dx=6e-3, settle_time=0.01)
    r = P.plate_drag3d("poppy LP", config=cfg, half_x=0.05, half_y=0.03, centre_depth=0.025,
                       depth=0.06, travel=0.008, speed=0.1, n_samples=9)
    fx = r["fx_N"]
    assert r["scene"]["pose0"][2] == pytest.approx(-0.5 * math.pi) and r["force_factor"] == 2.0
    # pushed along +x, the bed pushes back: alpha_x (against the motion) is positive ...
    assert r["alpha_x"] > 0 and fx[-1] < 0
    # ... and grows from the settled state, where the two faces' pressures balance
    assert abs(fx[0]) < 0.3 * abs(fx[-1])
    assert r["lost"] == 0


def test_vertical_plate_bad_requests_are_one_line_errors():
    with pytest.raises(InputError, match="mirror_x"):  # off x = 0: needs both halves
        P.plate_scene("poppy LP", dx=6e-3, pose=(0.0, -0.03, -0.5 * math.pi))
    with pytest.raises(InputError, match="pose"):  # below the floor
        P.plate_scene("poppy LP", dx=6e-3, mirror_x=False, depth=0.04,
                      pose=(0.0, -0.03, -0.5 * math.pi))
    with pytest.raises(InputError, match="travel"):
        P.plate_drag3d("poppy LP", travel=0.0)
    with pytest.raises(InputError, match="centre_depth"):
        P.plate_drag3d("poppy LP", centre_depth=-0.01)


def test_flat_leg_in_3d_is_pushed_forward_and_up_as_it_sweeps_back_through_the_bed():
    # a shallow stroke (tip 1.6 cm deep) at 8 mm particles, plane-strain slab: seconds
    cfg = SPHConfig(dx=8e-3, settle_time=0.01)
    r = P.flat_leg3d("poppy LP", config=cfg, slab=4, omega=4.0, hip_height=0.06, n_theta=55)
    th = r["theta"] / DEG
    deep = np.abs(th) < 15  # the leg near vertical, its tip sweeping backwards (-x)
    assert r["Fx"][deep].mean() > 0.1  # the bed pushes it forwards: thrust
    assert r["Fz"][(th > -30) & (th < 0)].mean() > 0  # intruding: lift
    assert np.all(r["Fx"][np.abs(th) > 90] == 0.0)  # outside the contact window: nothing
    assert r["lost"] == 0 and r["force_factor"] == 1.0


def test_curved_leg_markers_lie_on_the_arc_layers_with_radial_normals():
    # the C leg hanging straight down (hip 2 cm up): its markers against geometry.c_leg's arc
    from terradyn.geometry import c_leg
    from terradyn.sph.state import LEG

    cfg = SPHConfig(dx=4e-3)
    L = 7.62e-2
    sc = P.plate_scene("poppy LP", config=cfg, length=L, half_x=0.1, depth=0.1, mirror_x=False,
                       pose=(0.0, 0.02 - 0.5 * L, -0.5 * math.pi), curvature=1.0)
    m = sc.pos[sc.kind == LEG]
    arc = c_leg().outline(4000)
    centre = np.array([0.0, 0.02 - 0.5 * L])  # the half circle's centre: the chord's middle
    r = np.hypot(m[:, 0] - centre[0], m[:, 2] - centre[1])
    offsets = np.sort(np.unique(np.round(np.abs(r - 0.5 * L) * 1e4)) / 1e4)
    t, dx = P.PLATE_THICKNESS, cfg.dx
    expected = sorted({round(abs(0.5 * t - (k + 0.5) * dx), 4) for k in range(cfg.wall_layers)})
    assert offsets.tolist() == pytest.approx(expected, abs=1e-4)
    assert np.all(m[:, 0] <= 1e-12)  # the C bulges backwards (-x), the tip's way
    d = np.sqrt((m[:, 0, None] - arc[None, :, 0]) ** 2
                + (m[:, 2, None] - 0.02 - arc[None, :, 1]) ** 2).min(1)
    assert d.max() < 0.5 * t + cfg.wall_layers * dx
    s = P.Solver3D(sc)
    wn = s.wn[s.lidx]
    radial = (m[:, [0, 2]] - centre) / r[:, None]
    cosang = np.sum(wn * radial, 1)
    assert np.allclose(np.abs(cosang), 1.0) and np.allclose(np.hypot(*wn.T), 1.0)
    assert np.all((cosang > 0) == (sc.nz[sc.kind == LEG] > 0))  # +1: the convex face, outwards


@pytest.fixture(scope="module")
def slab_legs():
    # plane-strain slab, 8 mm particles, a shallow fast stroke: seconds each
    cfg = SPHConfig(dx=8e-3, settle_time=0.01)
    kw = dict(config=cfg, slab=4, omega=4.0, hip_height=0.06, n_theta=55)
    return {name: P.leg3d("poppy LP", **kw, **a) for name, a in
            (("flat", {}), ("nearly flat arc", {"curvature": 1e-3}), ("c", {"shape": "c"}),
             ("reverse-c", {"shape": "reverse-c"}))}


def test_a_nearly_flat_arc_reproduces_the_flat_plate(slab_legs):
    # the curved-leg path (radial normals, nearest-marker guard, circle side test) against the
    # flat plate's at curvature 1e-3 (radius 38 m): the same forces within the flow's scatter
    f, a = slab_legs["flat"], slab_legs["nearly flat arc"]
    for c in ("Fx", "Fz"):
        assert np.abs(a[c] - f[c]).max() < 0.03 * np.abs(f[c]).max()


def test_leg_shapes_order_the_lift_as_li_2013_measured(slab_legs):
    # Li 2013 Fig. S5: the C leg lifts most, the reverse C least (peak lift C > flat > reverse C)
    lift = {k: v["peak_lift"] for k, v in slab_legs.items()}
    assert lift["c"] > 2.0 * lift["flat"] > 2.0 * lift["reverse-c"]
    th = slab_legs["c"]["theta"]
    assert th[np.argmax(slab_legs["c"]["Fz"])] < th[np.argmax(slab_legs["flat"]["Fz"])]


def test_flat_leg_3d_bad_requests_are_one_line_errors():
    with pytest.raises(InputError, match="omega"):
        P.flat_leg3d("poppy LP", omega=0.0)
    with pytest.raises(InputError, match="hip_height"):
        P.flat_leg3d("poppy LP", hip_height=0.2)
    with pytest.raises(InputError, match="leg"):
        P.leg3d("poppy LP", shape="oval")
    with pytest.raises(InputError, match="curvature"):
        P.leg3d("poppy LP", curvature=1.5)
    with pytest.raises(InputError, match="mirror_x"):
        P.plate_scene("poppy LP", curvature=1.0)


def test_leg3d_figure_labels_what_it_draws(tmp_path):
    from terradyn.sph.plots import leg3d

    th = np.linspace(-135, 135, 11)
    pts = [{"kind": k, "theta_deg": th, "Fx_N": np.cos(th * DEG), "Fz_N": np.sin(th * DEG)}
           for k in ("slab", "finite")]
    fig = leg3d(pts, {"Fz": (th, 0.5 * th / 135), "Fx": (th, 0 * th)})
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert labels == ["SPH 3D, plane-strain slab", "SPH 3D, 2.54 cm wide leg",
                      "measured (Li 2013 Fig. S5)"]
    assert [a.get_ylabel() for a in fig.axes] == ["lift $F_z$ (N)", "thrust $F_x$ (N)"]
    leg3d(pts, {"Fz": (th, th), "Fx": (th, th)}, tmp_path / "f.png")
    assert (tmp_path / "f.png").stat().st_size > 1000
    # two spacings, the finer read part-way (None past the angle it reached): labelled by
    # spacing and reach, in two colours, the missing part not drawn
    part = [None if t > 0 else 1.0 for t in th]
    pts = [{"kind": "finite", "dx_mm": 4.0, "theta_deg": th, "Fx_N": np.cos(th * DEG),
            "Fz_N": np.sin(th * DEG)},
           {"kind": "finite", "dx_mm": 3.0, "theta_deg": th, "Fx_N": part, "Fz_N": part,
            "partial_to_deg": 0.4}]
    fig = leg3d(pts, {"Fz": (th, th), "Fx": (th, th)})
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert labels[:2] == ["SPH 3D, 4 mm particles", "SPH 3D, 3 mm particles (to 0 deg)"]
    lines = fig.axes[0].get_lines()
    assert lines[0].get_color() != lines[1].get_color()
    assert np.isnan(lines[1].get_ydata()[th > 0]).all()


def _pushed_solver(steps=60):
    # a plate with both halves in x and the y = 0 mirror (ghosts), already in the bed
    cfg = SPHConfig(dx=5e-3, settle_time=0.0)
    sc = P.plate_scene("3 mm glass CP", config=cfg, half_x=0.03, half_y=0.018, depth=0.02,
                       mirror_x=False, z0=-0.002)
    s = P.Solver3D(sc, plate_speed=0.2)
    pose = np.zeros((steps, 6))
    pose[:, 1] = -0.002 - 0.2 * s.dt * np.arange(steps)
    pose[:, 4] = -0.2
    return s, s.advance(pose, np.zeros(steps))


def test_parallel_pair_passes_write_only_into_neighbouring_chunks():
    # the race-freedom condition of the three-phase chunk schedule: every pair the passes
    # visit joins particles of the same or adjacent chunks (cell order), so chunks three
    # apart never write to the same particle
    s, _ = _pushed_solver(5)
    q = int(s.ip[P.I_NCHUNK])
    assert q >= 3  # the bed is split, so the passes do run in parallel
    b = s.bounds[:q + 1]
    assert np.all(np.diff(b) > 0) and b[-1] == np.sum(s.rank[:s.nr + s.ip[P.I_NG]] >= 0)
    chunk = np.searchsorted(b, s.rank[:s.nr + s.ip[P.I_NG]], side="right") - 1
    n = s.nr + int(s.ip[P.I_NG])
    for lst, off in ((s.ss, s.sso), (s.sb, s.sbo)):
        rows = np.repeat(np.arange(n), np.diff(off[:n + 1]))
        cols = lst[:off[n]]
        assert len(cols) > 0
        assert np.abs(chunk[rows] - chunk[cols]).max() <= 1
    # each granular pair listed once
    rows = np.repeat(np.arange(n), np.diff(s.sso[:n + 1]))
    pairs = np.sort(np.stack([rows, s.ss[:s.sso[n]]], 1), axis=1)
    assert len(np.unique(pairs, axis=0)) == len(pairs)


def test_forces_do_not_depend_on_the_number_of_threads():
    import numba
    if numba.config.NUMBA_NUM_THREADS >= 2:
        _one_and_two_threads_agree()
        return
    # a test worker runs one Numba thread (conftest): compare in a process allowed two
    import os
    import subprocess
    import sys
    from pathlib import Path

    code = ("import sys; sys.path.insert(0, sys.argv[1]); import test_sph_plate3d as t; "
            "t._one_and_two_threads_agree(); print('bitwise')")
    env = dict(os.environ, NUMBA_NUM_THREADS="2")
    env.pop("PYTEST_XDIST_WORKER", None)
    r = subprocess.run([sys.executable, "-c", code, str(Path(__file__).parent)], env=env,
                       capture_output=True, text=True, timeout=900)
    assert r.returncode == 0 and r.stdout.strip().endswith("bitwise"), r.stderr[-2000:]


def _one_and_two_threads_agree():
    import numba
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        s1, f1 = _pushed_solver()
        numba.set_num_threads(2)
        s2, f2 = _pushed_solver()
    finally:
        numba.set_num_threads(before)
    assert int(s2.ip[P.I_NCHUNK]) >= 3  # the passes ran in parallel chunks
    assert np.abs(f1).max() > 0
    np.testing.assert_array_equal(f1, f2)  # bitwise: fixed chunks and blocks, fixed sum order
    np.testing.assert_array_equal(s1.pos, s2.pos)


class _Stop(Exception):
    pass


def test_a_3d_run_stopped_and_resumed_from_its_checkpoint_gives_the_same_forces(tmp_path, monkeypatch):
    cfg = SPHConfig(dx=8e-3, settle_time=0.01)
    kw = dict(config=cfg, slab=4, omega=4.0, hip_height=0.06, n_theta=55)
    whole = P.leg3d("poppy LP", shape="c", **kw)
    ck = tmp_path / "leg.npz"
    calls = []

    def stop_after_two_blocks(done, total):
        calls.append(done)
        if len(calls) == 3:  # the start and two blocks: the checkpoint holds block 2's end
            raise _Stop

    monkeypatch.setattr(P, "_run_blocks", _small_blocks(P._run_blocks))
    with pytest.raises(_Stop):
        P.leg3d("poppy LP", shape="c", progress=stop_after_two_blocks, checkpoint=ck, **kw)
    assert ck.exists()
    # the curve so far, read from the checkpoint without running: the whole run's up to the
    # angle reached (at or before that angle's sample), NaN after it
    part = P.leg3d("poppy LP", shape="c", checkpoint=ck, so_far=True, **kw)
    th = np.degrees(part["theta"])
    seen = th <= part["reached_deg"]
    last = np.flatnonzero(seen)[-1]
    assert 0 < last < len(th) - 1 and np.isnan(part["Fx"][~seen]).all()
    np.testing.assert_array_equal(part["Fx"][:last], whole["Fx"][:last])
    np.testing.assert_array_equal(part["Fz"][:last], whole["Fz"][:last])
    assert part["peak_lift"] == np.nanmax(part["Fz"])
    assert ck.exists()  # read, not touched
    with pytest.raises(InputError, match="not a checkpoint of this run"):
        P.leg3d("poppy LP", shape="flat", checkpoint=ck, so_far=True, **kw)
    with pytest.raises(InputError, match="not a terradyn checkpoint"):
        P.leg3d("poppy LP", shape="c", checkpoint=tmp_path / "none.npz", so_far=True, **kw)
    again = P.leg3d("poppy LP", shape="c", checkpoint=ck, **kw)
    assert again["resumed_from"]["step"] == 2 * 300  # where it stopped
    assert not ck.exists()  # removed at the end
    np.testing.assert_array_equal(again["Fx"], whole["Fx"])  # bit-identical
    np.testing.assert_array_equal(again["Fz"], whole["Fz"])
    assert whole["resumed_from"] is None


def _small_blocks(run_blocks):
    # blocks of 300 steps, a checkpoint after every block
    def wrapped(*a, **kw):
        kw.update(block=300, checkpoint_every=0.0)
        return run_blocks(*a, **kw)
    return wrapped


def test_a_3d_checkpoint_path_holding_another_file_or_run_is_refused_and_kept(tmp_path):
    cfg = SPHConfig(dx=8e-3, settle_time=0.01)
    kw = dict(config=cfg, slab=4, omega=4.0, hip_height=0.06, n_theta=55)
    other = tmp_path / "notes.npz"
    other.write_text("mine")
    with pytest.raises(InputError, match="checkpoint.*not a terradyn checkpoint"):
        P.leg3d("poppy LP", checkpoint=other, **kw)
    assert other.read_text() == "mine"
    from terradyn.sph.solver import atomic_savez
    foreign = tmp_path / "run.npz"
    atomic_savez(foreign, key=np.array("0123456789abcdef"), done=np.array(0))
    with pytest.raises(InputError, match="not a checkpoint of this run"):
        P.leg3d("poppy LP", checkpoint=foreign, **kw)
    assert foreign.exists()
