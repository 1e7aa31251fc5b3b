import numpy as np
import pytest

import terradyn as td
from terradyn.errors import InputError
from terradyn.geometry import ArcLeg, PolylineLeg, read_leg_csv
from terradyn.motion import PlanarMotion, Rotation, read_motion_csv
from terradyn.units import CM, DEG


@pytest.mark.parametrize("k,length", [(0.0, 7.62 * CM), (1.0, np.pi * 3.81 * CM),
                                      (-1.0, np.pi * 3.81 * CM)])
def test_arc_length_and_area(k, length):
    leg = ArcLeg(2.54 * CM, 64, 7.62 * CM, k)
    el = leg.elements()
    assert el.lengths.sum() == pytest.approx(length, rel=1e-12)
    assert el.areas.sum() == pytest.approx(length * 2.54 * CM, rel=1e-12)
    np.testing.assert_allclose(np.hypot(*el.tangents.T), 1.0)


def test_arcs_run_from_hip_to_tip_and_bulge_the_right_way():
    for leg, sign in ((td.c_leg(), -1), (td.reverse_c_leg(), 1)):
        out = leg.outline(101)
        np.testing.assert_allclose(out[0], [0, 0], atol=1e-12)
        np.testing.assert_allclose(out[-1], [0, -7.62 * CM], atol=1e-12)
        # C bulges towards -x (the way the tip moves at theta = 0), reverse C towards +x
        assert np.sign(out[50, 0]) == sign
        assert abs(out[50, 0]) == pytest.approx(3.81 * CM, rel=1e-9)


def test_small_curvature_tends_to_the_flat_plate():
    flat = td.flat_leg(n=20).elements()
    near = ArcLeg(2.54 * CM, 20, 7.62 * CM, 1e-9).elements()
    np.testing.assert_allclose(near.centers, flat.centers, atol=1e-10)
    np.testing.assert_allclose(near.tangents, flat.tangents, atol=1e-8)


def test_straight_polyline_equals_flat_leg():
    poly = PolylineLeg(2.54 * CM, 40, np.array([[0, 0], [0, -3 * CM], [0, -7.62 * CM]]))
    flat = td.flat_leg(n=40).elements()
    e = poly.elements()
    np.testing.assert_allclose(e.centers, flat.centers, atol=1e-12)
    np.testing.assert_allclose(np.abs(e.tangents[:, 1]), 1.0)
    np.testing.assert_allclose(e.areas, flat.areas)


def test_polyline_validation():
    w = 2.54 * CM
    with pytest.raises(InputError, match="folds back"):
        PolylineLeg(w, 10, np.array([[0, 0], [0, -2], [0, -1.0]]))
    with pytest.raises(InputError, match="crosses itself"):
        PolylineLeg(w, 10, np.array([[0, 0], [1, -1], [1, 0], [0, -1.0]]))
    with pytest.raises(InputError, match="coincide"):
        PolylineLeg(w, 10, np.array([[0, 0], [0, 0], [0, -1.0]]))
    with pytest.raises(InputError, match="non-finite"):
        PolylineLeg(w, 10, np.array([[0, 0], [np.nan, -1.0]]))
    with pytest.raises(InputError, match="elements"):
        PolylineLeg(w, 1, np.array([[0, 0], [0, -1.0]]))
    with pytest.raises(InputError, match="width"):
        PolylineLeg(0, 10, np.array([[0, 0], [0, -1.0]]))


def test_leg_csv(tmp_path):
    p = tmp_path / "leg.csv"
    p.write_text("x_cm,z_cm\n0,0\n-1,-3\n0,-7\n")
    leg = read_leg_csv(p)
    assert leg.arc_length == pytest.approx((np.hypot(1, 3) + np.hypot(1, 4)) * CM)
    p.write_text("x,z\n0,0\n")
    with pytest.raises(InputError, match="x_cm,z_cm"):
        read_leg_csv(p)
    p.write_text("x_cm,z_cm\n0,0\n1,oops\n")
    with pytest.raises(InputError, match="line 3"):
        read_leg_csv(p)


def test_preset_validation():
    with pytest.raises(InputError, match="leg"):
        td.make_leg("spoon")
    with pytest.raises(InputError, match="curvature"):
        td.make_leg("c", curvature=1.5)
    with pytest.raises(InputError, match="length"):
        td.make_leg("flat", length=-1)


def test_foot_points_forward_from_the_ankle():
    out = td.foot(25 * CM).outline(3)
    np.testing.assert_allclose(out[0], [0, 0], atol=1e-12)
    np.testing.assert_allclose(out[-1], [25 * CM, 0], atol=1e-12)


def test_rotation_trajectory_and_validation():
    tr = Rotation(0.5, 0.02, -1.0, 1.0, 11).trajectory()
    np.testing.assert_allclose(np.diff(tr.time), 0.2 / 0.5)
    assert (tr.angular_velocity == 0.5).all()
    back = Rotation(0.5, 0.02, 1.0, -1.0, 11).trajectory()
    assert (back.angular_velocity == -0.5).all() and back.time[-1] == pytest.approx(4.0)
    with pytest.raises(InputError, match="empty"):
        Rotation(0.2, 0.02, 0.3, 0.3, 10)
    with pytest.raises(InputError, match="omega"):
        Rotation(0.0)
    with pytest.raises(InputError, match="n-theta"):
        Rotation(n_theta=1)


def test_planar_motion_velocities_are_exact_for_smooth_motion():
    t = np.linspace(0, 2, 201)
    m = PlanarMotion(t, 0.1 * np.sin(t), 0.02 + 0.01 * t ** 2, 0.3 * t ** 3)
    tr = m.trajectory()
    np.testing.assert_allclose(tr.hip_vx[5:-5], 0.1 * np.cos(t[5:-5]), rtol=1e-5, atol=1e-7)
    np.testing.assert_allclose(tr.hip_vz, 0.02 * t, atol=1e-9)
    np.testing.assert_allclose(tr.angular_velocity, 0.9 * t ** 2, atol=1e-9)


def test_planar_motion_validation(tmp_path):
    with pytest.raises(InputError, match="increasing"):
        PlanarMotion([0, 1, 1], [0, 0, 0], [0, 0, 0], [0, 0, 0])
    with pytest.raises(InputError, match="samples"):
        PlanarMotion([0, 1, 2], [0, 0], [0, 0, 0], [0, 0, 0])
    p = tmp_path / "m.csv"
    p.write_text("time_s,hip_x_cm,hip_z_cm,angle_deg\n0,0,2,-30\n1,1,2,0\n2,2,2,30\n")
    tr = read_motion_csv(p).trajectory()
    assert tr.hip_vx == pytest.approx(np.full(3, 0.01))
    assert tr.angular_velocity == pytest.approx(np.full(3, 30 * DEG))
    p.write_text("time_s,hip_x_cm\n0,0\n")
    with pytest.raises(InputError, match="missing column"):
        read_motion_csv(p)
