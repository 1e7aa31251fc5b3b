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
