"""3D bodies driven by any 2D RFT coefficient set, after Treers, Cao & Stuart (IEEE RA-L 6(2),
2021, doi:10.1109/LRA.2021.3057052).

What is implemented (per leading, submerged element; NumPy):

1. The element's plane of motion is the vertical plane through its velocity v (unit
   horizontal direction e_r = v_h / |v_h|; for vertical motion the horizontal part of the normal;
   e_t = z x e_r is out of the plane).
2. The element's cross-section in that plane is a 2D plate with normal n_p = n - (n . e_t) e_t:
   attack angle beta from its tangent, intrusion angle gamma from v (in-plane by
   construction). Any 2D stress model of the package gives (alpha_x, alpha_z) there: Li's fits,
   the measured grids, a user's grid (``terradyn.media.stress_model``).
3. The 2D stress is split into its part along the in-plane normal (mapped onto the element's
   true normal n, so a yawed plate is also pushed sideways) and its in-plane tangential part.
4. Out-of-plane orientation: with sin(phi) = |n . e_t| (phi = 0: the normal lies in the plane of
   motion, the 2D case; phi -> 90 deg: the element slides along itself) the stress is scaled by
   Treers' normalised out-of-plane function f23(phi) = F23(phi) / F23(0),
   F23 = b1 atanh(b2 cos(phi) - b3) + b4 with (b1, b2, b3, b4) = (1.99, 1.61, 0.97, 4.31).

A body uniform across its width moving in its own plane therefore reduces to the 2D engine's
result exactly for its faces whose normals lie in that plane (phi = 0), differing only by the 3D
body's thickness (end caps and edges; tested). This is our reading of the brief's description
(an in-plane part from 2D coefficients and an out-of-plane part with its own scaling), not a
reproduction of Treers' code or of their calibration data.
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from .body import Body
from .engine import dynamic_traction, element_kinematics, net_of

#: Treers et al. (2021) out-of-plane scaling constants (b1..b4) of F23.
TREERS_B = (1.99, 1.61, 0.97, 4.31)


def f23(phi) -> np.ndarray:
    """Treers' normalised in-plane scale factor at out-of-plane angle phi (rad), 1 at phi = 0."""
    b1, b2, b3, b4 = TREERS_B
    F = b1 * np.arctanh(b2 * np.cos(phi) - b3) + b4
    return F / (b1 * np.arctanh(b2 - b3) + b4)


def _stress_model(model):
    if isinstance(model, str):
        from ..media import stress_model

        return stress_model(model)
    if not hasattr(model, "alpha"):
        raise InputError("stress_model", "must be a 2D stress model (alpha(beta, gamma)) or a medium name")
    return model


def treers_elements(body: Body, poses, model, surface=0.0, point=None,
                    dynamic_lambda: float | None = None, surface_correction=None,
                    bulk_density: float | None = None) -> dict:
    """Per-element result (the dict of :func:`terradyn.rft3d.element_tractions`) of ``body`` at
    ``poses`` (a :class:`~terradyn.rft3d.motion.Poses`) with a 2D stress model (or medium
    name). ``dynamic_lambda`` needs ``bulk_density`` (kg/m^3; default: the Li 2013 medium's
    when ``model`` is a medium name)."""
    sm = _stress_model(model)
    k = element_kinematics(body, poses.position, poses.quaternion, poses.velocity,
                           poses.angular_velocity, surface, point, surface_correction)
    act = k["active"]
    t = np.zeros_like(k["r"])
    if act.any():
        n = k["normal"][act]
        v = k["vhat"][act]
        d = k["depth"][act]
        vh = v[:, :2]
        hn = np.linalg.norm(vh, axis=1)
        nh = n[:, :2]
        nhn = np.linalg.norm(nh, axis=1)
        er = np.where((hn > 1e-9)[:, None], vh / np.maximum(hn, 1e-300)[:, None],
                      np.where((nhn > 1e-9)[:, None], nh / np.maximum(nhn, 1e-300)[:, None],
                               [1.0, 0.0]))
        e_r = np.column_stack([er, np.zeros(len(er))])
        e_t = np.column_stack([-er[:, 1], er[:, 0], np.zeros(len(er))])
        nt = np.einsum("ij,ij->i", n, e_t)
        npl = n - nt[:, None] * e_t  # in-plane part of the normal
        npn = np.linalg.norm(npl, axis=1)
        ok = npn > 1e-9  # an element sliding exactly along itself has no 2D cross-section
        u = npl / np.maximum(npn, 1e-300)[:, None]
        ux, uz = np.einsum("ij,ij->i", u, e_r), u[:, 2]
        beta = np.arctan2(-ux, uz)  # tangent (uz, -ux) angle from the horizontal
        beta = np.mod(beta + np.pi / 2, np.pi) - np.pi / 2
        gamma = np.arctan2(-v[:, 2], np.einsum("ij,ij->i", v, e_r))
        ax, az = sm.alpha(beta, gamma)
        s2d = -np.asarray(ax)[:, None] * e_r + np.asarray(az)[:, None] * np.array([0.0, 0.0, 1.0])
        sn = np.einsum("ij,ij->i", s2d, u)
        stress = sn[:, None] * n + (s2d - sn[:, None] * u)  # normal part along the true normal
        phi = np.arcsin(np.clip(np.abs(nt), 0.0, 1.0))
        stress *= (f23(phi) * ok)[:, None] * d[:, None]
        t[act] = stress
    if dynamic_lambda:
        rho = bulk_density
        if rho is None:
            from ..media import MEDIA

            if not (isinstance(model, str) and model in MEDIA):
                raise InputError("bulk_density", "dynamic RFT with a custom 2D stress model needs the bulk density (kg/m^3)")
            rho = MEDIA[model].bulk_density
        t += dynamic_traction(k, dynamic_lambda * rho)
    return net_of(body, k, t)
