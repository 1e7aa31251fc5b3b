"""MuJoCo granular terrain (terradyn.adapters.mujoco): forces against rft3d, static sinkage
against the closed-form RFT depth, energy of a dropped block, moments about an off-contact
centre of mass, errors, the demo robot and its CLI."""
from __future__ import annotations

import json
import os

import numpy as np
import pytest

os.environ.setdefault("MUJOCO_GL", "egl")  # offscreen GL; read when mujoco is first imported
mujoco = pytest.importorskip("mujoco", reason="the 'mujoco' extra (CI installs it with the test extra)")

from terradyn import rft3d as r3  # noqa: E402
from terradyn.adapters import mujoco_demo as md  # noqa: E402
from terradyn.adapters.mujoco import GranularTerrain, energy  # noqa: E402
from terradyn.errors import InputError  # noqa: E402

GLASS = r3.medium3d("3 mm glass CP")
POPPY = r3.medium3d("poppy LP")

MIXED = """<mujoco><option timestep="0.001"/>
<asset><mesh name="tet" vertex="0 0 0  0.02 0 0  0 0.02 0  0 0 0.02"/></asset>
<worldbody><geom name="floor" type="plane" size="1 1 .1"/>
<body name="thing" pos="0 0 0.05"><freejoint/>
  <geom name="sole" type="box" size="0.03 0.02 0.003" pos="0.01 0 0" mass="0.3"/>
  <geom name="cap" type="capsule" size="0.006 0.02" pos="-0.01 0.015 0.012" euler="0 1.2 0.3" mass="0.05"/>
  <geom name="cyl" type="cylinder" size="0.008 0.01" pos="0.02 -0.02 0.02" mass="0.05"/>
  <geom name="tet" type="mesh" mesh="tet" pos="-0.03 -0.02 0.0" mass="0.02"/>
</body></worldbody></mujoco>"""


def _free_state(model, data, rng, depth=0.006):
    data.qpos[:3] = [0.004, -0.003, -depth]
    q = rng.normal(size=4)
    data.qpos[3:7] = q / np.linalg.norm(q)
    data.qvel[:] = rng.normal(size=6) * [0.1, 0.1, 0.1, 1.0, 1.0, 1.0]
    mujoco.mj_forward(model, data)


def test_wrench_equals_rft3d_for_the_same_pose_and_velocity():
    model = mujoco.MjModel.from_xml_string(MIXED)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(3)
    for lam in (None, 1.1):
        terrain = GranularTerrain(model, POPPY, bodies=("thing",), stick=False, dynamic_lambda=lam)
        body = terrain.surfaces["thing"]
        for _ in range(5):
            _free_state(model, data, rng)
            w = terrain.wrenches(data)[0].copy()
            R = data.xmat[1].reshape(3, 3)
            # MuJoCo free joint: world linear velocity of the body origin, body-frame angular
            ref = r3.wrench(body, data.xpos[1], data.xquat[1], data.qvel[:3], R @ data.qvel[3:6],
                            POPPY, 0.0, point=data.xipos[1], dynamic_lambda=lam)
            assert np.abs(ref[:3]).max() > 0.1  # really in the bed
            np.testing.assert_allclose(w, ref, rtol=0, atol=1e-9)


def test_geom_surfaces_are_closed_and_sized():
    model = mujoco.MjModel.from_xml_string(MIXED)
    terrain = GranularTerrain(model, POPPY, geoms=("sole", "cap"))
    body = terrain.surfaces["thing"]
    r, h = 0.006, 0.04
    box_area = 2 * (0.06 * 0.04 + 0.06 * 0.006 + 0.04 * 0.006)
    assert body.areas.sum() == pytest.approx(box_area + 4 * np.pi * r * r + 2 * np.pi * r * h, rel=0.03)
    assert body.mesh().is_watertight


@pytest.mark.parametrize("mass, load, thickness, ramp", [(0.5, 0.0, 0.002, 8.0), (0.2, 20.0, 0.004, 3.0)])
def test_static_sinkage_equals_closed_form_rft_depth(mass, load, thickness, ramp):
    # a level box foot of mass m (and a load) set down slowly (a faster ramp overshoots by
    # inertia: 4 s instead of 8 s leaves the light foot 1.4 % deep): a_b d A + sides = m g + load
    size = (0.06, 0.04, thickness)
    res = md.press_foot(GLASS, load=load, mass=mass, size=size, ramp=ramp, hold=0.3)
    assert res["expected_depth_m"] > thickness  # buried: the closed form applies
    assert res["final_depth_m"] == pytest.approx(res["expected_depth_m"], rel=0.01)
    # the depth holds still once the load is constant
    held = res["depth_m"][res["time_s"] > ramp + 0.1]
    assert np.ptp(held) < 1e-4 * res["expected_depth_m"] + 1e-7
    # the plain explicit force (no rest rule) ratchets deeper: the remedy is what makes it static
    plain = md.press_foot(GLASS, load=load, mass=mass, size=size, ramp=ramp, hold=0.3, stick=False)
    assert plain["final_depth_m"] > 1.1 * res["expected_depth_m"]


def _drop(height=0.02, tilt=0.0, stick=True, dt_factor=None, duration=0.6, mass=0.05):
    xml = md.foot_mjcf(0.06, 0.04, 0.004, mass).replace('pos="0 0 0.0021"', f'pos="0 0 {height}"')
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    if tilt:
        data.qpos[3:7] = [np.cos(tilt / 2), np.sin(tilt / 2), 0, 0]
    terrain = GranularTerrain(model, GLASS, bodies=("foot",), stick=stick)
    mujoco.mj_forward(model, data)
    if dt_factor:
        model.opt.timestep = dt_factor * terrain.stable_timestep(data)
    E0 = energy(model, data)
    E = []
    for _ in range(int(duration / model.opt.timestep)):
        terrain.step(data)
        E.append(energy(model, data))
    return model, data, terrain, E0, np.array(E)


@pytest.mark.parametrize("tilt", [0.0, 0.3])
def test_dropped_block_comes_to_rest_without_gaining_energy(tilt):
    model, data, terrain, E0, E = _drop(tilt=tilt)
    assert E.max() <= E0 + 1e-9
    assert np.all(np.diff(E) <= 1e-9)  # the terrain never adds energy, step by step
    assert np.abs(data.qvel).max() < 1e-9  # held exactly by the bed (the rest rule)
    assert data.qpos[2] < 0  # in the bed, held by it


def test_stiffness_rule_separates_stable_from_unstable_steps():
    # plain explicit force: within the rule's step no energy is gained; far beyond it, it is
    _, _, _, E0, E = _drop(stick=False, dt_factor=1.0, mass=0.02)
    assert E.max() <= E0 + 1e-9
    _, _, _, E0, E = _drop(stick=False, dt_factor=12.0, mass=0.02)
    assert E.max() > E0 + 1e-3
    # with the rest rule the terrain cannot reverse the motion, even at 12x the step
    _, data, _, E0, E = _drop(stick=True, dt_factor=12.0, mass=0.02)
    assert E.max() <= E0 + 1e-9


OFFSET = """<mujoco><option timestep="0.001"/><worldbody><geom name="floor" type="plane" size="1 1 .1"/>
<body name="foot" pos="0 0 0.0021"><freejoint/>
  <inertial pos="0.02 0 0.005" mass="0.35" diaginertia="5e-5 2e-4 2.4e-4"/>
  <geom name="sole" type="box" size="0.04 0.02 0.002"/>
</body></worldbody></mujoco>"""


def test_moment_about_an_off_contact_centre_of_mass():
    model = mujoco.MjModel.from_xml_string(OFFSET)
    data = mujoco.MjData(model)
    terrain = GranularTerrain(model, GLASS, geoms=("sole",), stick=False)
    rng = np.random.default_rng(0)
    data.qpos[:3] = [0, 0, -0.004]
    data.qvel[:] = [0.02, 0.0, -0.05, 0.0, 0.4, 0.0]
    mujoco.mj_forward(model, data)
    com = data.xipos[1].copy()
    assert np.linalg.norm(com - data.xpos[1]) > 0.02  # the CoM is well off the sole
    w = terrain.wrenches(data)[0].copy()
    # independent path: rft3d's NumPy per-element forces, moment about the CoM
    R = data.xmat[1].reshape(3, 3)
    el = r3.element_tractions(terrain.surfaces["foot"], data.xpos[1], data.xquat[1], data.qvel[:3],
                              R @ data.qvel[3:6], GLASS)
    f, r = el["force"][0], el["r"][0]
    np.testing.assert_allclose(w[:3], f.sum(0), rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(w[3:], np.cross(r - com, f).sum(0), rtol=1e-9, atol=1e-9)
    assert abs(w[4]) > 0.05 * abs(w[2]) * 0.025  # a real moment, not a negligible one
    del rng


def test_off_centre_body_settles_without_flipping():
    # CoM 2 cm ahead of the sole's centre, inside its 4 cm half-length: the sole lands level,
    # the bed's push at its centre tips it toward the CoM side, the deeper +x end is held by the
    # RFT moment about the CoM, and it comes to rest nearly upright (no flip)
    model = mujoco.MjModel.from_xml_string(OFFSET)
    data = mujoco.MjData(model)
    terrain = GranularTerrain(model, GLASS, geoms=("sole",))
    mujoco.mj_forward(model, data)
    for _ in range(1500):
        terrain.step(data)
    up = data.xmat[1].reshape(3, 3)[:, 2]
    tilt = np.degrees(np.arccos(np.clip(up[2], -1, 1)))
    assert 0.5 < tilt < 45
    assert up[0] > 0  # leans toward the heavy (+x) side, as the moment about the CoM implies
    assert np.abs(data.qvel).max() < 0.05


def test_rigid_floor_contact_is_switched_off():
    model = mujoco.MjModel.from_xml_string(MIXED)
    floor = model.geom("floor").id
    GranularTerrain(model, POPPY, bodies=("thing",))
    for g in range(model.ngeom):
        if g != floor:
            assert not (model.geom_contype[g] & model.geom_conaffinity[floor])
            assert not (model.geom_conaffinity[g] & model.geom_contype[floor])


def test_missing_body_or_geom_is_a_clear_error():
    model = mujoco.MjModel.from_xml_string(MIXED)
    with pytest.raises(InputError, match="no body named 'leg_fl'.*thing"):
        GranularTerrain(model, POPPY, bodies=("leg_fl",))
    with pytest.raises(InputError, match="no geom named 'toe'"):
        GranularTerrain(model, POPPY, geoms=("toe",))
    with pytest.raises(InputError, match="floor"):
        GranularTerrain(model, POPPY, bodies=("thing",), floor=("ground",))
    with pytest.raises(InputError, match="name at least one"):
        GranularTerrain(model, POPPY)
    hf = mujoco.MjModel.from_xml_string(
        '<mujoco><asset><hfield name="h" nrow="3" ncol="3" size="1 1 0.1 0.1"/></asset><worldbody>'
        '<body name="b"><freejoint/><geom type="sphere" size="0.1"/><geom type="hfield" hfield="h"/></body>'
        '</worldbody></mujoco>')
    with pytest.raises(InputError, match="HFIELD"):
        GranularTerrain(hf, POPPY, bodies=("b",))
    # the demo robot's terrain bodies on another model
    with pytest.raises(InputError, match="no body named 'torso'"):
        GranularTerrain(model, POPPY, bodies=md.terrain_bodies())


def test_hexapod_model_and_legs():
    for leg in md.LEG_SHAPES:
        model, data, terrain = md.build(leg, "poppy LP")
        assert model.nu == 6 and model.nv == 12
        for name in md.terrain_bodies()[1:]:
            surf = terrain.surfaces[name]
            assert surf.mesh().is_watertight
            lo, hi = surf.vertices.min(0), surf.vertices.max(0)
            assert hi[2] - lo[2] == pytest.approx(md.HEXAPOD.leg_chord + md.HEXAPOD.leg_thickness, rel=0.2)
    with pytest.raises(InputError, match="leg"):
        md.hexapod_mjcf("zigzag")


def test_hexapod_walks_forward_on_poppy_seeds():
    r = md.walk("c", "poppy LP", duration=1.2, settle=0.5)
    assert np.isfinite(r.speed_m_s) and r.speed_m_s > 0.01
    assert 0 < r.mean_torso_height_m < 0.1
    assert r.max_tilt_deg < 60  # the torso never flips


def test_cli_demo_writes_table_figure_and_says_about_the_gif(tmp_path):
    from terradyn.cli import main

    out = tmp_path / "demo"
    rc = main(["mujoco", "demo", "--out", str(out), "--duration-s", "0.6", "--settle-s", "0.2",
               "--leg", "c", "--leg", "flat", "--medium", "poppy LP", "--gif-duration-s", "0.1",
               "--gif-width", "64"])
    assert rc == 0
    res = json.loads((out / "mujoco_demo.json").read_text())
    assert {r["leg"] for r in res["runs"]} == {"c", "flat"}
    assert (out / "mujoco_demo_speed.png").stat().st_size > 1000
    assert (out / "mujoco_demo.csv").read_text().startswith("leg,medium,speed_cm_s")
    gif = res["gif"]
    if gif["written"]:
        assert (out / "mujoco_demo.gif").stat().st_size > 1000
    else:
        assert gif["reason"]


def test_cli_bad_input_exits_2(tmp_path, capsys):
    from terradyn.cli import main

    assert main(["mujoco", "demo", "--out", str(tmp_path / "x"), "--robot", "biped"]) == 2
    assert "robot" in capsys.readouterr().err
    assert main(["mujoco", "demo", "--out", str(tmp_path / "x"), "--medium", "sand"]) == 2
    assert main(["mujoco", "demo", "--out", str(tmp_path / "x"), "--duration-s", "-1"]) == 2
    f = tmp_path / "file"
    f.write_text("x")
    assert main(["mujoco", "demo", "--out", str(f)]) == 2


def test_cli_press_prints_sinkage_against_closed_form(capsys):
    from terradyn.cli import main

    assert main(["mujoco", "press", "--load-n", "20", "--ramp-s", "2", "--hold-s", "0.1"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["sinkage_cm"] == pytest.approx(res["closed_form_cm"], rel=0.03)
    assert main(["mujoco", "press", "--load-n", "-1"]) == 2


def test_gif_is_skipped_with_the_reason_when_gl_is_missing(tmp_path, monkeypatch):
    def no_gl(*a, **k):
        raise RuntimeError("no OpenGL here")

    monkeypatch.setattr(md.mujoco, "Renderer", no_gl)
    frames, why = md.render_frames(duration=0.1)
    assert frames is None and "no OpenGL here" in why and "MUJOCO_GL" in why
