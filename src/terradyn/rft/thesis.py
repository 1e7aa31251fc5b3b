"""The thesis's closed-form RFT kinematics for the rotating-leg test (brief section 2.2).

Kept as an independent reference for the general engine. The closed forms are written in the
thesis's frame, in which the tip moves towards +x at theta = 0 (the mirror image of
terradyn's world frame); a mirror changes no forces' magnitudes, and the thesis's horizontal
force sum(alpha_x |z| A) is terradyn's Fx (thrust positive).

What the comparison shows (tests/test_rft_thesis.py, docs/rft.md):

* At the same element nodes the engine reproduces the closed forms to round-off for the flat,
  C and reverse C legs: for a pure rotation about a fixed hip the "pendulum" velocity
  (perpendicular to the element-to-hip line) is exact.
* The closed forms place the C and reverse-C elements at alpha_i = i pi / n, i = 1..n: a
  one-sided (right-endpoint) rule that puts an element on the hip and none at the tip. Its
  error falls as 1/n; the engine's midpoint rule falls as 1/n^2.
* The closed-form angles leave the measured domain [-pi/2, pi/2]^2 (beta reaches pi + 3pi/4,
  gamma beyond -pi/2): harmless for the Fourier fit, which is pi-periodic in beta and obeys the
  mirror symmetry by construction, but a measured grid must be read through the symmetry
  relations (:func:`terradyn.media.wrap_angles`), which the engine always does; a plain grid
  lookup clamped to the domain gives wrong forces there.
* For a moving hip (any motion but a pure rotation) there is no closed form; the engine uses
  v = v_hip + omega x r.
"""
from __future__ import annotations

import numpy as np

from ..errors import choice, integer, positive
from ..media import StressModel

SHAPES = ("flat", "c", "reverse-c")


def closed_form_angles(shape: str, theta, n: int, length: float, hip_height: float,
                       nodes: str = "thesis"):
    """beta, gamma (rad), depth below the surface (m, clipped at 0) and element length (m)
    for the rotating-leg test; theta (S,) rad; arrays (S, n).

    ``nodes="thesis"``: alpha_i = i pi / n as in the thesis; ``"midpoint"``: (i - 1/2) pi / n.
    """
    choice("leg", shape, SHAPES)
    n = integer("elements", n, 1)
    L = positive("length", length, "m")
    th = np.asarray(theta, dtype=float)[:, None]
    i = np.arange(1, n + 1)[None, :]
    intr = th <= 0
    a = abs(th)
    if shape == "flat":
        li = (L / n) * (i - 0.5)
        mag_b = np.pi / 2 - a
        beta = np.where(intr, mag_b, -mag_b)
        gamma = np.where(intr, np.pi / 2 - mag_b, -(np.pi / 2 - mag_b))
        below_hip = li * np.sin(mag_b)  # the intrusion magnitude, for both halves
        ds = np.full(n, L / n)
    else:
        R = L / 2
        al = (i if nodes == "thesis" else i - 0.5) * np.pi / n
        if shape == "c":
            beta = np.where(intr, al - a, al + th)
            gamma = np.where(intr, -(al / 2 - a), -(al / 2 + th))
        else:
            beta = np.where(intr, -(al + a), -(al - th))
            gamma = np.where(intr, al / 2 + a, al / 2 - th)
        below_hip = R * (np.cos(th) + np.cos(np.abs(beta)))
        ds = np.full(n, np.pi * R / n)
    depth = np.maximum(below_hip - hip_height, 0.0)
    return beta, gamma, depth, ds


def closed_form_forces(shape: str, theta, model: StressModel, n: int = 100,
                       length: float = 0.0762, width: float = 0.0254, hip_height: float = 0.02,
                       nodes: str = "thesis", lookup: str = "symmetric"):
    """Net (Fx, Fz) in N, each (S,), from the closed forms.

    ``lookup="symmetric"`` evaluates the stress model at the closed-form angles (every
    terradyn stress model applies the symmetry relations); ``"clamped"`` clamps the angles to
    the measured domain first, as a plain grid lookup would.
    """
    choice("lookup", lookup, ("symmetric", "clamped"))
    beta, gamma, depth, ds = closed_form_angles(shape, theta, n, length, hip_height, nodes)
    if lookup == "clamped":
        beta = np.clip(beta, -np.pi / 2, np.pi / 2)
        gamma = np.clip(gamma, -np.pi / 2, np.pi / 2)
    ax, az = model.alpha(beta, gamma)
    load = depth * ds * width
    return (ax * load).sum(1), (az * load).sum(1)
