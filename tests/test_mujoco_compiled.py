"""MuJoCo terrain, compiled stepping loop and culling (terradyn.adapters.mujoco): the compiled
loop against the per-step Python path, its fallback, the per-cluster bed test, float32, each
geom type against rft3d, and the demo mesh against a finer one."""
from __future__ import annotations

import dataclasses
import os
import warnings

import numpy as np
import pytest

os.environ.setdefault("MUJOCO_GL", "egl")
mujoco = pytest.importorskip("mujoco", reason="the 'mujoco' extra (CI installs it with the test extra)")

from terradyn import rft3d as r3  # noqa: E402
from terradyn.adapters import mujoco as am  # noqa: E402
from terradyn.adapters import mujoco_demo as md  # noqa: E402
from terradyn.errors import InputError  # noqa: E402

POPPY = r3.medium3d("poppy LP")


def _python_walk(model, data, terrain, n):
    for _ in range(n):
        data.ctrl[:] = md.gait_targets(data.time)
        terrain.step(data)


@pytest.mark.parametrize("stick", [True, False])
def test_compiled_loop_gives_the_python_paths_trajectory(stick):
    m1, d1, t1 = md.build("c", "poppy LP", stick=stick)
    m2, d2, t2 = md.build("c", "poppy LP", stick=stick)
    n = 400
    _python_walk(m1, d1, t1, n)
    res = t2.run(d2, 150, ctrl=md.gait_schedule(d2.time, 150, m2.opt.timestep))
    res = t2.run(d2, n - 150, ctrl=md.gait_schedule(d2.time, n - 150, m2.opt.timestep))
    assert res["compiled"]
    assert d1.time == d2.time
    assert np.abs(d1.xpos[1]).max() > 0.01 and np.abs(t1._out).max() > 0  # walking in the bed
    np.testing.assert_allclose(d2.qpos, d1.qpos, rtol=0, atol=1e-12)
    np.testing.assert_allclose(d2.qvel, d1.qvel, rtol=0, atol=1e-11)
    np.testing.assert_array_equal(d2.xfrc_applied, d1.xfrc_applied)  # the terrain wrench is taken out


def test_run_holds_ctrl_and_user_forces_and_substeps_like_step():
    m1, d1, t1 = md.build("flat", "3 mm glass CP")
    m2, d2, t2 = md.build("flat", "3 mm glass CP")
    for d in (d1, d2):
        d.ctrl[:] = 0.7
        d.xfrc_applied[1, 2] = -0.5  # the user's own force on the torso stays
    for _ in range(120):
        t1.step(d1, substeps=2)
    t2.run(d2, 120, substeps=2)
    np.testing.assert_allclose(d2.qpos, d1.qpos, rtol=0, atol=1e-12)
    assert d2.xfrc_applied[1, 2] == -0.5 and m2.opt.timestep == m1.opt.timestep == 0.001


def test_run_falls_back_to_python_with_a_clear_warning(monkeypatch):
    monkeypatch.setitem(am._LIB, "f", None)
    monkeypatch.setitem(am._LIB, "why", "MuJoCo's shared library was not found (test)")
    monkeypatch.setattr(am, "_WARNED", [])
    m1, d1, t1 = md.build("c", "poppy LP")
    m2, d2, t2 = md.build("c", "poppy LP")
    _python_walk(m1, d1, t1, 50)
    with pytest.warns(RuntimeWarning, match="not found.*per-step Python path"):
        res = t2.run(d2, 50, ctrl=md.gait_schedule(0.0, 50, 0.001))
    assert not res["compiled"]
    np.testing.assert_array_equal(d2.qpos, d1.qpos)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # warned once only
        t2.run(d2, 2)


def test_run_rejects_bad_arguments():
    model, data, terrain = md.build("c", "poppy LP")
    with pytest.raises(InputError, match="ctrl.*shape"):
        terrain.run(data, 10, ctrl=np.zeros((9, model.nu)))
    with pytest.raises(InputError, match="ctrl.*finite"):
        terrain.run(data, 2, ctrl=np.full((2, model.nu), np.nan))
    with pytest.raises(InputError, match="nsteps"):
        terrain.run(data, -1)
    with pytest.raises(InputError, match="substeps"):
        terrain.run(data, 1, substeps=0)
    with pytest.raises(InputError, match="precision"):
        am.GranularTerrain(model, POPPY, bodies=("torso",), precision="half")


def test_gait_schedule_is_the_per_step_targets():
    t, dt, rows = 0.0, 0.001, []
    for _ in range(1000):
        rows.append(md.gait_targets(t))
        t += dt
    np.testing.assert_array_equal(md.gait_schedule(0.0, 1000, dt), np.array(rows))


MIXED = """<mujoco><option timestep="0.001"/>
<asset><mesh name="tet" vertex="0 0 0  0.03 0 0  0 0.03 0  0 0 0.03"/></asset>
<worldbody><geom name="floor" type="plane" size="1 1 .1"/>
<body name="b_box" pos="0 0 0.05"><freejoint/><geom type="box" size="0.03 0.02 0.006" mass="0.3"/></body>
<body name="b_capsule" pos="0.2 0 0.05"><freejoint/><geom type="capsule" size="0.008 0.02" euler="0 1.2 0.3" mass="0.05"/></body>
<body name="b_cylinder" pos="0.4 0 0.05"><freejoint/><geom type="cylinder" size="0.01 0.012" euler="0.4 0 0" mass="0.05"/></body>
<body name="b_mesh" pos="0.6 0 0.05"><freejoint/><geom type="mesh" mesh="tet" pos="-0.01 -0.01 -0.01" mass="0.02"/></body>
</worldbody></mujoco>"""


@pytest.mark.parametrize("kind", ["box", "capsule", "cylinder", "mesh"])
def test_each_geom_type_gets_the_rft3d_wrench(kind):
    model = mujoco.MjModel.from_xml_string(MIXED)
    data = mujoco.MjData(model)
    terrain = am.GranularTerrain(model, POPPY, bodies=(f"b_{kind}",), stick=False, dynamic_lambda=1.1)
    body = terrain.surfaces[f"b_{kind}"]
    bid = model.body(f"b_{kind}").id
    j = model.body_jntadr[bid]
    qa, va = model.jnt_qposadr[j], model.jnt_dofadr[j]
    rng = np.random.default_rng(11)
    for _ in range(4):
        q = rng.normal(size=4)
        depth = 0.012 if kind == "mesh" else 0.004  # partly buried
        data.qpos[qa:qa + 7] = [*data.qpos[qa:qa + 2], -depth, *(q / np.linalg.norm(q))]
        data.qvel[va:va + 6] = rng.normal(size=6) * [0.1, 0.1, 0.1, 2.0, 2.0, 2.0]
        mujoco.mj_forward(model, data)
        w = terrain.wrenches(data)[0]
        R = data.xmat[bid].reshape(3, 3)
        ref = r3.wrench(body, data.xpos[bid], data.xquat[bid], data.qvel[va:va + 3], R @ data.qvel[va + 3:va + 6],
                        POPPY, 0.0, point=data.xipos[bid], dynamic_lambda=1.1)
        assert np.abs(ref[:3]).max() > 1e-3
        np.testing.assert_allclose(w, ref, rtol=0, atol=1e-9)


def test_cluster_culling_and_float32_keep_the_wrench(monkeypatch):
    # partly buried, tilted, moving: the clusters out of the bed are skipped and the elements in
    # the bed gathered (the default), or the runs of touching clusters evaluated whole: both
    # give the wrench of the whole element loop (one cluster per body); float32 within 1e-4
    model, data, terrain = md.build("reverse-c", "poppy LP", stick=False)
    monkeypatch.setattr(am, "GATHER", False)
    runs = am.GranularTerrain(model, POPPY, bodies=md.terrain_bodies(), stick=False)
    monkeypatch.setattr(am, "CLUSTER", 10 ** 9)
    whole = am.GranularTerrain(model, POPPY, bodies=md.terrain_bodies(), stick=False)
    monkeypatch.undo()
    f32 = am.GranularTerrain(model, POPPY, bodies=md.terrain_bodies(), stick=False, precision="float32")
    assert len(terrain._cl) > 7 * 5 and len(whole._cl) == 7
    rng = np.random.default_rng(5)
    some_culled = False
    for _ in range(6):
        data.qpos[:3] = [0, 0, rng.uniform(0.0, 0.02)]
        q = np.array([1.0, *rng.normal(size=3) * 0.2])
        data.qpos[3:7] = q / np.linalg.norm(q)
        data.qpos[7:] = rng.uniform(-np.pi, np.pi, size=6)
        data.qvel[:] = rng.normal(size=model.nv) * 0.3
        mujoco.mj_forward(model, data)
        a, b, c = terrain.wrenches(data).copy(), whole.wrenches(data).copy(), f32.wrenches(data).copy()
        assert np.abs(b).max() > 0.01
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-12 * np.abs(b).max())
        np.testing.assert_allclose(runs.wrenches(data), b, rtol=0, atol=1e-12 * np.abs(b).max())
        np.testing.assert_allclose(c, b, rtol=0, atol=1e-4 * np.abs(b).max())
        some_culled |= bool((np.abs(b).sum(1) == 0).any())
    assert some_culled  # whole bodies above the bed were skipped too


def _net_wrenches(leg_n_along, max_edge, states):
    robot = dataclasses.replace(md.HEXAPOD, n_along=leg_n_along)
    model = mujoco.MjModel.from_xml_string(md.hexapod_mjcf("c", robot))
    data = mujoco.MjData(model)
    terrain = am.GranularTerrain(model, POPPY, bodies=md.terrain_bodies(), stick=False, max_edge=max_edge)
    out = []
    for q, v in states:
        data.qpos[:], data.qvel[:] = q, v
        mujoco.mj_forward(model, data)
        w = terrain.wrenches(data)
        arm = data.xipos[terrain.body_ids] - data.xipos[1]
        out.append(np.concatenate([w[:, :3].sum(0), w[:, 3:].sum(0) + np.cross(arm, w[:, :3]).sum(0)]))
    return np.array(out)


def test_demo_mesh_is_converged_against_a_finer_mesh():
    # the net terrain wrench on the robot (force; torque about the torso CoM) over a stride of
    # the gait, at the demo's mesh (legs: 12 segments, torso: default max_edge) against legs of
    # 48 segments and a torso with 8 mm edges: within 2 % (force) and 3 % (torque) RMS; half
    # the leg segments is clearly worse (the test can tell)
    model, data, terrain = md.build("c", "poppy LP")
    terrain.run(data, 1000, ctrl=md.gait_schedule(0.0, 1000, 0.001))
    states = []
    for _ in range(50):
        terrain.run(data, 10, ctrl=md.gait_schedule(data.time, 10, 0.001))
        states.append((data.qpos.copy(), data.qvel.copy()))
    fine = _net_wrenches(48, 0.008, states)

    def err(w):
        return (np.linalg.norm(w[:, :3] - fine[:, :3]) / np.linalg.norm(fine[:, :3]),
                np.linalg.norm(w[:, 3:] - fine[:, 3:]) / np.linalg.norm(fine[:, 3:]))

    eF, eT = err(_net_wrenches(md.HEXAPOD.n_along, None, states))
    assert eF < 0.02 and eT < 0.03
    cF, _ = err(_net_wrenches(md.HEXAPOD.n_along // 2, None, states))
    assert cF > 2 * eF
