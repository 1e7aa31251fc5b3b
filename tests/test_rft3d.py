"""3D RFT (Agarwal, Goldman & Kamrin 2023): engine paths, closed forms, symmetries, bad input."""
import numpy as np
import pytest

from terradyn import rft3d as r3
from terradyn.errors import InputError
from terradyn.rft3d import model as m3

MED = r3.medium3d("poppy LP")


def _random_poses(S, rng, depth=0.03):
    X = rng.normal(0, 0.02, (S, 3))
    X[:, 2] -= depth
    q = rng.normal(size=(S, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return X, q, rng.normal(size=(S, 3)), rng.normal(size=(S, 3))


@pytest.mark.parametrize("dyn", [None, 1.1])
def test_compiled_kernel_matches_numpy_reference(dyn):
    rng = np.random.default_rng(1)
    body = r3.plate(max_edge=0.006)
    X, q, V, W = _random_poses(40, rng)
    ref = r3.element_tractions(body, X, q, V, W, MED, dynamic_lambda=dyn)["wrench"]
    scale = np.abs(ref).max()
    for par in (False, True):
        got = r3.wrench_batch(body, X, q, V, W, MED, dynamic_lambda=dyn, parallel=par)
        np.testing.assert_allclose(got, ref, atol=1e-12 * scale)


def test_poses_above_the_surface_are_skipped_exactly():
    """The kernel skips a pose whose bounding sphere is above the surface: poses straddling the
    surface still match the NumPy reference, and one fully above gives exactly zero."""
    rng = np.random.default_rng(11)
    body = r3.foot_sole()
    X, q, V, W = _random_poses(60, rng, depth=0.0)
    X[:, 2] = rng.uniform(-0.05, 0.3, 60)
    ref = r3.element_tractions(body, X, q, V, W, MED)["wrench"]
    got = r3.wrench_batch(body, X, q, V, W, MED)
    np.testing.assert_allclose(got, ref, atol=1e-12 * np.abs(ref).max())
    assert (np.abs(ref).sum(1) == 0).sum() > 10 and (np.abs(ref).sum(1) > 0).sum() > 10
    assert not np.any(r3.wrench(body, [0, 0, 0.2], [1, 0, 0, 0], [0, 0, -1], [0, 0, 0], MED))


def test_single_precision_paths_agree_with_double():
    rng = np.random.default_rng(5)
    body = r3.foot_sole()
    X, q, V, W = _random_poses(20, rng, depth=0.005)
    ref = r3.wrench_batch(body, X, q, V, W, MED)
    scale = np.abs(ref).max()
    np.testing.assert_allclose(r3.wrench_batch(body, X, q, V, W, MED, dtype=np.float32), ref,
                               atol=1e-5 * scale)
    ev = r3.Evaluator(body, MED, dtype=np.float32)
    np.testing.assert_allclose(ev(X[3], q[3], V[3], W[3]), ref[3], atol=1e-5 * scale)
    np.testing.assert_allclose(r3.Evaluator(body, MED)(X[3], q[3], V[3], W[3]), ref[3],
                               atol=1e-12 * scale)


def test_horizontal_plate_pushed_down_closed_form():
    """A buried horizontal plate pushed straight down: bottom face alpha_z(down) xi_n depth A,
    side walls only their friction-capped tangential stress (closed form too)."""
    L, B, t, d = 0.0762, 0.0254, 0.0064, 0.05
    body = r3.plate(L, B, t)
    Fz = r3.wrench(body, [0, 0, -d], [1, 0, 0, 0], [0, 0, -0.01], [0, 0, 0], MED)[2]
    z = np.array([0.0, 0.0, 1.0])
    bottom = m3.generic_alpha(-z, -z)[2] * MED.xi_n * (d + t / 2) * L * B
    wall = m3.generic_alpha(np.array([1.0, 0, 0]), -z)  # same for every wall by symmetry
    an = abs(wall[0])
    side_z = min(abs(wall[2]), MED.mu_surf * an) * MED.xi_n * d * 2 * (L + B) * t
    assert Fz == pytest.approx(bottom + side_z, rel=1e-9)


def test_unnormalised_quaternion_is_refused():
    with pytest.raises(InputError, match="unit quaternion"):
        r3.wrench(r3.sphere(), [0, 0, -0.02], [1, 0.1, 0, 0], [0, 0, -1], [0, 0, 0], MED)


# ------------------------------------------------------------------------------------------
# The two disputed coefficients (brief 7.1)
# ------------------------------------------------------------------------------------------
def _leading_sample(n_samples=20000, seed=3):
    rng = np.random.default_rng(seed)
    n = rng.normal(size=(n_samples, 3))
    v = rng.normal(size=(n_samples, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    flip = np.einsum("ij,ij->i", n, v) < 0
    n[flip] *= -1  # leading elements only
    return n, v


def test_settled_f3_entry_resists_motion_almost_everywhere():
    """With f3 x2 x3^2 = -0.02730 the generic stress opposes the motion on all but ~0.4 % of
    leading orientations (0.07 % of directions uniform on the sphere here, 0.7 % on a uniform
    beta-gamma-psi grid); the other port's -0.20770 fails 15-20 times as often (1.2 %, 13 %)."""
    n, v = _leading_sample()
    chosen = np.mean(np.einsum("ij,ij->i", m3.generic_alpha(n, v), v) >= 0)
    other = np.mean(np.einsum("ij,ij->i", m3.generic_alpha(n, v, m3.coefficients(
        {"f3 x2 x3^2": m3.ALTERNATIVES["f3 x2 x3^2"]})), v) >= 0)
    assert m3.coefficients()[m3.DISPUTED["f3 x2 x3^2"]] == -0.02730
    assert chosen < 0.002
    assert other > 0.01
    assert other > 10 * chosen


def test_settled_f3_entry_pulls_a_rising_plate_down_like_li2013():
    """A buried horizontal plate pulled straight up: Li 2013 measured a downward force in all
    five media; the chosen entry gives it, the alternative pushes the plate up."""
    body = r3.plate()
    up = ([0, 0, -0.05], [1, 0, 0, 0], [0, 0, 0.01], [0, 0, 0])
    assert r3.wrench(body, *up, MED)[2] < 0
    alt = m3.coefficients({"f3 x2 x3^2": m3.ALTERNATIVES["f3 x2 x3^2"]})
    assert r3.wrench_batch(body, *up, MED, coef=alt)[0, 2] > 0
    for name in ("poppy CP", "0.3 mm glass LP", "3 mm glass CP"):
        assert r3.wrench(body, *up, r3.medium3d(name))[2] < 0


def test_f2_entry_choice_changes_forces_by_less_than_0_5_percent():
    rng = np.random.default_rng(7)
    body = r3.sphere(subdivisions=2)
    X, q, V, W = _random_poses(60, rng)
    a = r3.wrench_batch(body, X, q, V, W, MED)
    b = r3.wrench_batch(body, X, q, V, W, MED,
                        coef=m3.coefficients({"f2 x3 x2^2": m3.ALTERNATIVES["f2 x3 x2^2"]}))
    F = np.linalg.norm(a[:, :3], axis=1)
    assert np.max(np.linalg.norm(a[:, :3] - b[:, :3], axis=1)[F > 0] / F[F > 0]) < 5e-3


# ------------------------------------------------------------------------------------------
# Symmetries, convergence, closed forms
# ------------------------------------------------------------------------------------------
def _scene(rng):
    body = r3.foot_sole() if hasattr(r3, "foot_sole") else r3.box(0.05, 0.03, 0.01)
    X = np.array([0.01, -0.02, -0.004])
    q = r3.axis_angle_quat(np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8]), 0.4)
    V = np.array([0.05, 0.02, -0.03])
    W = np.array([0.2, -0.4, 0.3])
    return body, X, q, V, W


@pytest.mark.parametrize("model", ["agarwal", "treers"])
def test_invariance_under_rotation_about_the_vertical(model):
    body, X, q, V, W = _scene(None)
    poses = lambda X, q, V, W: r3.Poses(np.zeros(1), X[None], q[None], V[None], W[None])  # noqa: E731
    med = MED if model == "agarwal" else "poppy LP"
    w0, _, _ = r3.compute(body, _Fixed(poses(X, q, V, W)), med, model)
    for phi in (0.7, 2.5):
        Rz = r3.rotation_matrices(r3.axis_angle_quat([0, 0, 1.0], phi))
        qz = r3.quat_multiply(r3.axis_angle_quat([0, 0, 1.0], phi), q)
        w1, _, _ = r3.compute(body, _Fixed(poses(Rz @ X, qz, Rz @ V, Rz @ W)), med, model)
        np.testing.assert_allclose(w1[0, :3], Rz @ w0[0, :3], atol=1e-9 * np.abs(w0).max())
        np.testing.assert_allclose(w1[0, 3:], Rz @ w0[0, 3:], atol=1e-9 * np.abs(w0).max())


class _Fixed:
    def __init__(self, p):
        self.p = p

    def poses(self):
        return self.p

    def describe(self):
        return {"kind": "fixed"}


@pytest.mark.parametrize("model", ["agarwal", "treers"])
def test_mirror_symmetry(model):
    """Mirror the scene in y (body, pose and motion): Fy, Tx, Tz change sign, the rest stays."""
    import trimesh

    body, X, q, V, W = _scene(None)
    R = r3.rotation_matrices(q)
    M = np.diag([1.0, -1.0, 1.0])
    world = trimesh.Trimesh(body.vertices @ R.T, body.faces, process=False)
    mirrored = trimesh.Trimesh(body.vertices @ R.T @ M, body.faces[:, ::-1], process=False)
    b0 = r3.from_trimesh(world)
    b1 = r3.from_trimesh(mirrored)
    med = MED if model == "agarwal" else "poppy LP"
    one = lambda X, V, W: _Fixed(r3.Poses(np.zeros(1), X[None], np.array([[1.0, 0, 0, 0]]), V[None], W[None]))  # noqa: E731
    w0 = r3.compute(b0, one(X, V, W), med, model)[0][0]
    w1 = r3.compute(b1, one(M @ X, M @ V, -(M @ W)), med, model)[0][0]
    expect = np.concatenate([M @ w0[:3], -(M @ w0[3:])])
    np.testing.assert_allclose(w1, expect, atol=1e-9 * np.abs(w0).max())
    assert abs(w0[1]) > 1e-3 * np.abs(w0[:3]).max()  # the scene is not trivially symmetric


def test_mesh_refinement_converges_for_a_sphere():
    """A sphere pushed down and sideways at depth: the net force converges as the icosphere is
    refined (each change at most half the previous one)."""
    F = []
    for k in (1, 2, 3, 4):
        w = r3.wrench(r3.sphere(0.02, k), [0, 0, -0.04], [1, 0, 0, 0], [0.03, 0, -0.04], [0, 0, 0], MED)
        F.append(w[:3])
    d = [np.linalg.norm(F[i + 1] - F[i]) for i in range(3)]
    assert d[1] < 0.5 * d[0] and d[2] < 0.5 * d[1]
    assert d[2] < 0.01 * np.linalg.norm(F[-1])


def test_torque_point_moves_torque_by_r_cross_f():
    body, X, q, V, W = _scene(None)
    a = r3.wrench(body, X, q, V, W, MED)
    P = np.array([0.1, 0.2, -0.3])
    b = r3.wrench(body, X, q, V, W, MED, point=P)
    np.testing.assert_allclose(b[:3], a[:3])
    np.testing.assert_allclose(b[3:], a[3:] + np.cross(X - P, a[:3]), atol=1e-12)


def test_treers_mode_accepts_every_2d_coefficient_set(tmp_path):
    """Li's fits, the measured grids (any interpolator), generic x zeta, a user's grid."""
    from terradyn.media import generic, packaged_tables, stress_model

    body = r3.leg3d("c", n_along=30, n_width=2)
    mot = r3.PlanarAs3D(__import__("terradyn").standard_rotation(n_theta=31))
    tab = packaged_tables("cubic")["poppy LP"]
    out = {}
    for name, sm in (("fit", stress_model("poppy LP")), ("table", tab), ("generic", generic(0.248))):
        ds = r3.simulate(body, mot, "poppy LP", model="treers", stress_model=sm)
        out[name] = ds.Fz.values
        assert ds.Fz.max() > 0.5
    # a user's grid from a file: the measured grid scaled by 1.5 gives 1.5 x the forces
    from terradyn.media import read_tables

    lines = ["medium,beta_rad,gamma_rad,alpha_z_N_per_cm3,alpha_x_N_per_cm3"]
    for i, b in enumerate(tab.beta):
        for j, g in enumerate(tab.gamma):
            lines.append(f"mine,{b},{g},{1.5 * tab.alpha_z[i, j] / 1e6},{1.5 * tab.alpha_x[i, j] / 1e6}")
    (tmp_path / "grid.csv").write_text("\n".join(lines) + "\n")
    mine = read_tables(tmp_path / "grid.csv", "cubic")["mine"]
    ds = r3.simulate(body, mot, "poppy LP", model="treers", stress_model=mine)
    np.testing.assert_allclose(ds.Fz.values, 1.5 * out["table"], rtol=1e-9, atol=1e-12)
    # fit, measured grid and generic x zeta describe the same medium: within 40 % at the peak
    for name in ("table", "generic"):
        assert out[name].max() == pytest.approx(out["fit"].max(), rel=0.4)


# ------------------------------------------------------------------------------------------
# Reduction to the 2D engine
# ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("shape", ["flat", "c", "reverse-c"])
def test_thin_3d_leg_reduces_to_the_2d_engine(shape):
    """A leg uniform across its width rotating in its own plane: as its thickness goes to 0
    the 3D result tends to the 2D engine's (Agarwal mode: with the planar restriction of the
    same law; Treers mode: with Li's fit), the difference shrinking ~ with the thickness."""
    import terradyn as td

    mot = td.standard_rotation(n_theta=91)
    med = r3.medium3d("poppy LP")
    ref = {"agarwal": td.rft.simulate(td.make_leg(shape), mot, r3.AgarwalPlanar(med)),
           "treers": td.rft.simulate(td.make_leg(shape), mot, td.FITS["poppy LP"])}
    for model, m in (("agarwal", med), ("treers", "poppy LP")):
        errs = []
        for t in (1e-3, 2e-4):
            ds = r3.simulate(r3.leg3d(shape, thickness=t, n_along=100, n_width=1),
                             r3.PlanarAs3D(mot), m, model=model)
            s2 = ref[model]
            scale = max(np.abs(s2.Fz).max(), np.abs(s2.Fx).max())
            errs.append(max(np.abs(ds.Fz.values - s2.Fz.values).max(),
                            np.abs(ds.Fx.values - s2.Fx.values).max()) / scale)
            np.testing.assert_allclose(-ds.Ty.values, s2.torque.values,
                                       atol=(0.1 if t > 5e-4 else 0.03) * np.abs(s2.torque).max())
            assert np.abs(ds.Fy).max() < 1e-6 * scale
        assert errs[1] < 0.015
        assert errs[1] < 0.4 * errs[0]


def test_standard_3d_legs_against_li2013_measurements():
    """The three legs as 3D bodies (0.64 cm thick) against Li 2013 Fig. S5 (two media):
    Treers mode stays as close to the measurements as the 2D engine it extends, and Agarwal
    3D-RFT (xi_n from the measured plate) is closer than the 2D engine on average, mostly
    through the reverse-C lift the 2D fits overestimate (docs/rft3d.md has the table)."""
    from terradyn.rft3d import studies

    df = studies.legs_vs_experiment(n_theta=136)
    mean = df.groupby("model").rms_frac.mean()
    assert mean["3D Treers mode, Li fit"] < 1.2 * mean["2D engine, Li fit"]
    assert mean["3D Agarwal, xi_n from plate"] < mean["2D engine, Li fit"]
    peaks = df[df.model == "3D Agarwal, xi_n from plate"]
    ratio = peaks.peak_model_N / peaks.peak_measured_N
    assert ratio.between(0.6, 2.0).all()
    # xi_n from tan(repose angle) over-predicts these media several-fold (reported, not used)
    assert mean["3D Agarwal, xi_n from friction"] > 1.0


# ------------------------------------------------------------------------------------------
# Dynamic RFT
# ------------------------------------------------------------------------------------------
def test_dynamic_term_vanishes_at_low_speed_and_scales_as_v_squared():
    body = r3.leg3d("flat", n_along=20, n_width=2)
    X, q = [0, 0, -0.01], [1, 0, 0, 0]
    d = np.array([1.0, 0.0, -0.3]) / np.linalg.norm([1.0, 0.0, -0.3])
    extra = []
    for v in (1e-3, 0.5, 1.0, 2.0):
        qs = r3.wrench(body, X, q, v * d, [0, 0, 0], MED)
        dy = r3.wrench(body, X, q, v * d, [0, 0, 0], MED, dynamic_lambda=1.1)
        extra.append(dy[:3] - qs[:3])
        if v == 1e-3:
            assert np.linalg.norm(extra[-1]) < 1e-5 * np.linalg.norm(qs[:3])
    extra = np.array(extra[1:])
    assert np.linalg.norm(extra[0]) > 0.01 * np.linalg.norm(qs[:3]) / 4  # not trivially zero
    np.testing.assert_allclose(extra[1], 4.0 * extra[0], atol=1e-12, rtol=1e-9)
    np.testing.assert_allclose(extra[2], 16.0 * extra[0], atol=1e-12, rtol=1e-9)


def test_plate_drag_form_closed_form():
    """A vertical plate dragged broadside at depth: F = K |z| + lambda rho A v^2 exactly, with
    K from the quasi-static law (Agarwal et al. 2021's plate-drag form)."""
    L, B, t, depth = 0.0381, 0.0254, 0.001, 0.05
    body = r3.box(t, B, L, max_edge=0.004)
    lam, v = 1.1, 0.8
    X = [0, 0, -depth]
    F0 = r3.wrench(body, X, [1, 0, 0, 0], [v, 0, 0], [0, 0, 0], MED)[0]
    F1 = r3.wrench(body, X, [1, 0, 0, 0], [v, 0, 0], [0, 0, 0], MED, dynamic_lambda=lam)[0]
    assert F1 - F0 == pytest.approx(-lam * MED.bulk_density * (B * L) * v ** 2, rel=1e-9)
    Fslow = r3.wrench(body, X, [1, 0, 0, 0], [1e-3, 0, 0], [0, 0, 0], MED)[0]
    assert F0 == pytest.approx(Fslow, rel=1e-12)  # K |z|: rate independent


def test_2d_engine_dynamic_option():
    import terradyn as td
    from terradyn.rft.engine import net_forces

    leg = td.flat_leg()
    rho = td.MEDIA["poppy LP"].bulk_density
    res = {}
    for w in (0.2, 20.0, 40.0):
        traj = td.Rotation(w, 0.02, -1.0, 1.0, 41).trajectory()
        res[w] = (np.array(net_forces(leg, traj, td.FITS["poppy LP"])),
                  np.array(net_forces(leg, traj, td.FITS["poppy LP"], dynamic=(1.1, rho))))
    slow = res[0.2]
    assert np.abs(slow[1] - slow[0]).max() < 1e-3 * np.abs(slow[0]).max()
    d20 = res[20.0][1] - res[20.0][0]
    d40 = res[40.0][1] - res[40.0][0]
    np.testing.assert_allclose(d40, 4 * d20, atol=1e-9 * np.abs(d40).max())
    assert np.abs(d20).max() > 0.01 * np.abs(res[20.0][0]).max()


def test_speed_onset_near_the_froude_scale():
    from terradyn.rft3d import studies

    df = studies.speed_onset(np.geomspace(0.5, 100, 12))
    on = df.attrs["onset"]
    g = df.attrs["froude_omega_rad_s"]
    for shape in ("flat", "c", "reverse-c"):
        assert on[shape] is not None and 0.2 * g < on[shape] < 3 * g
        slow = df[(df.leg == shape)].peak_ratio.iloc[0]
        assert slow - 1 < 1e-3


# ------------------------------------------------------------------------------------------
# Motions
# ------------------------------------------------------------------------------------------
def test_axis_rotation_velocities_are_exact_and_match_a_sampled_motion():
    rot = r3.AxisRotation(axis=(0.2, 1.0, 0.3), center=(0.01, 0.0, 0.02), omega=0.7,
                          angle_start=-1.0, angle_end=1.0, n=401, position0=(0.03, -0.01, 0.0))
    p = rot.poses()
    sampled = r3.RigidMotion(p.time, p.position, p.quaternion).poses()
    np.testing.assert_allclose(sampled.velocity[5:-5], p.velocity[5:-5], atol=1e-8)
    np.testing.assert_allclose(sampled.angular_velocity[5:-5], p.angular_velocity[5:-5], atol=1e-8)
    np.testing.assert_allclose(np.linalg.norm(p.angular_velocity, axis=1), 0.7)


# ------------------------------------------------------------------------------------------
# Bad input
# ------------------------------------------------------------------------------------------
def test_bad_meshes_are_named():
    import trimesh

    box = trimesh.creation.box(extents=(0.02, 0.02, 0.02))
    with pytest.raises(InputError, match="empty"):
        r3.from_trimesh(trimesh.Trimesh(np.zeros((0, 3)), np.zeros((0, 3), int)))
    v = box.vertices.copy()
    v[3, 1] = np.nan
    with pytest.raises(InputError, match="not finite"):
        r3.from_trimesh(trimesh.Trimesh(v, box.faces, process=False))
    f = box.faces.copy()
    f[0] = [f[0, 0], f[0, 0], f[0, 1]]
    with pytest.raises(InputError, match="degenerate"):
        r3.from_trimesh(trimesh.Trimesh(box.vertices, f, process=False))
    f = box.faces.copy()
    f[0] = f[0, ::-1]
    with pytest.raises(InputError, match="inconsistent normals"):
        r3.from_trimesh(trimesh.Trimesh(box.vertices, f, process=False))
    with pytest.raises(InputError, match="not closed"):
        r3.from_trimesh(trimesh.Trimesh(box.vertices, box.faces[:-1], process=False))
    with pytest.raises(InputError, match="inward"):
        r3.from_trimesh(trimesh.Trimesh(box.vertices, box.faces[:, ::-1], process=False))
    open_sheet = r3.from_trimesh(trimesh.Trimesh(box.vertices, box.faces[:-2], process=False),
                                 require_closed=False)
    assert len(open_sheet) == 10


def test_presets_are_closed_solids_and_the_wheel_is_periodic():
    """Every preset is a closed, outward mesh of the stated size; a grousered wheel turning in
    place feels the same wrench every grouser pitch (12 grousers: 30 deg), and no side force."""
    for name in r3.PRESETS:
        b = r3.preset(name)
        tm = b.mesh()
        assert tm.is_watertight and tm.volume > 0
    foot = r3.foot_sole()
    lo, hi = foot.vertices.min(0), foot.vertices.max(0)
    np.testing.assert_allclose(hi[:2] - lo[:2], [0.25, 0.085], rtol=1e-9)
    assert 1800 <= len(foot) <= 2200
    legs = r3.standard_legs()
    for b in legs.values():
        np.testing.assert_allclose(np.ptp(b.vertices[:, 1]), 0.0254)
    np.testing.assert_allclose(legs["flat"].mesh().volume, 0.0762 * 0.0254 * 0.0064, rtol=1e-9)
    wheel = r3.wheel()
    rot = r3.AxisRotation(axis=(0, 1, 0), center=(0, 0, 0.045), omega=2.0, angle_start=0.0,
                          angle_end=np.pi / 3, n=3, position0=(0, 0, 0.045))
    ds = r3.simulate(wheel, rot, MED)
    np.testing.assert_allclose(ds.isel(time=2).to_array().values, ds.isel(time=0).to_array().values,
                               atol=1e-9 * float(np.abs(ds.Fz).max()))
    assert float(np.abs(ds.Fy).max()) < 1e-6 * float(np.abs(ds.Fz).max())
    assert float(ds.Fz[0]) > 0.1


def test_plate_drag_form_against_the_shipped_sph():
    """The comparison uses the repository's SPH legs at 0.2-1.1 rad/s: dynamic RFT predicts a
    change below 1 % there (the v^2 term is negligible at these speeds)."""
    from terradyn.rft3d import studies

    res = studies.plate_drag_vs_sph()
    if "error" in res:
        pytest.skip("datasets/sph_legs_speeds.nc not in this checkout")
    for shape, r in res["legs"].items():
        assert r["omega_high_rad_s"] > 5 * r["omega_low_rad_s"]
        assert 0 <= r["dynamic_rft_change_frac"] < 0.01
        assert r["sph_peak_low_N"] > 1
        assert 0 < r["sph_trend_se_frac_per_rad_s"] < 0.5 and abs(r["sph_trend_frac_per_rad_s"]) < 1
    assert 0.5 < res["plate_crossover_speed_m_s"] < 5


def test_surface_correction_hooks_shift_the_free_surface():
    """A constant delta_h is the same as lowering the free surface by delta_h (z~ = z + delta_h),
    in the 3D engine and in the 2D engine."""
    import terradyn as td
    from terradyn.rft.engine import net_forces

    body = r3.leg3d("c", n_along=20, n_width=2)
    mot = r3.PlanarAs3D(td.standard_rotation(n_theta=31))
    a = r3.simulate(body, mot, MED, surface_correction=lambda r, v: np.full(r.shape[:2], 0.004))
    b = r3.simulate(body, mot, MED, surface=-0.004)
    np.testing.assert_allclose(a.Fz.values, b.Fz.values, rtol=1e-12, atol=1e-12)
    traj = td.standard_rotation(n_theta=31).trajectory()
    fit = td.FITS["poppy LP"]
    c = net_forces(td.c_leg(), traj, fit, surface_correction=lambda st: np.full(st.depth.shape, 0.004))
    d = net_forces(td.c_leg(), traj, fit, surface=-0.004)
    np.testing.assert_allclose(c, d, rtol=1e-9, atol=1e-12)
    assert np.abs(d[1]).max() > 0.5
