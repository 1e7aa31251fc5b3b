"""Field-unit adapters (cm, deg, mm) shared by the command line, the studies and scripts:
they check inputs in the user's units, convert at the edge and build the SI objects.

Messages quote values back in the units they were given (``length-cm: must be > 0 cm,
got -7``); options that have no effect with the others raise an
:class:`terradyn.models.IgnoredOptionWarning` (the CLI prints it as one line); sizes
that would need more memory than the machine has are refused before any allocation
(:func:`terradyn.errors.check_memory`).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import xarray as xr

from .errors import InputError, check_memory, finite, integer, positive
from .geometry import Leg, make_leg, read_leg_csv
from .motion import Rotation, read_motion_csv
from .units import CM, DEG

#: The default leg of every command that takes one.
DEFAULT_LEG = "c"
#: Bytes per (sample x element) of an RFT evaluation (states, velocities, forces in float64).
RFT_BYTES_PER_EVAL = 8 * 24


def leg_from_field_units(leg: str = DEFAULT_LEG, leg_file: Path | None = None,
                         curvature: float | None = None, length_cm: float | None = None,
                         width_cm: float | None = None, elements: int = 100) -> Leg:
    """A leg from CLI-style inputs: a preset (with optional curvature, length and width in
    cm) or a polyline CSV; unset sizes take the preset's defaults."""
    from .models import ignored

    for name, v in (("length-cm", length_cm), ("width-cm", width_cm)):
        if v is not None:
            positive(name, v, "cm")
    if curvature is not None:
        finite("curvature", curvature)
        if not -1.0 <= curvature <= 1.0:
            raise InputError("curvature", f"must be in [-1, 1], got {curvature!r}")
    integer("elements", elements, 2)
    check_memory("elements", elements * 64, f"{elements:,} elements")
    if leg_file is not None:
        if curvature is not None:
            raise InputError("curvature", "cannot be combined with --leg-file")
        if length_cm is not None:
            ignored("length-cm", "has no effect with --leg-file (the polyline sets the length)")
        return read_leg_csv(leg_file, (width_cm if width_cm is not None else 2.54) * CM, elements)
    if leg == "foot" and curvature is not None:
        ignored("curvature", "has no effect with --leg foot (the foot is a flat sole)")
        curvature = None
    return make_leg(leg, None if length_cm is None else length_cm * CM,
                    None if width_cm is None else width_cm * CM, elements, curvature)


def motion_from_field_units(foot: bool = False, motion_file: Path | None = None,
                            omega: float = 0.2, hip_height_cm: float | None = None,
                            theta_start_deg: float | None = None,
                            theta_end_deg: float | None = None, n_theta: int = 271):
    """A planar motion CSV, or a rotation whose unset values follow the standard test
    (h = 2 cm, -135..135 deg) or, for the foot, the thesis's foot test (h = 0, 0..3 deg)."""
    from .models import ignored

    if motion_file is not None:
        for name, v in (("hip-height-cm", hip_height_cm), ("theta-start-deg", theta_start_deg),
                        ("theta-end-deg", theta_end_deg)):
            if v is not None:
                ignored(name, "has no effect with --motion-file (the file gives the motion)")
        return read_motion_csv(motion_file)
    positive("omega", omega, "rad/s")
    for name, v in (("hip-height-cm", hip_height_cm), ("theta-start-deg", theta_start_deg),
                    ("theta-end-deg", theta_end_deg)):
        if v is not None:
            finite(name, v, name.rsplit("-", 1)[-1])
    integer("n-theta", n_theta, 2)
    check_memory("n-theta", n_theta * 8 * 16, f"{n_theta:,} angles")
    h = hip_height_cm if hip_height_cm is not None else (0.0 if foot else 2.0)
    t0 = theta_start_deg if theta_start_deg is not None else (0.0 if foot else -135.0)
    t1 = theta_end_deg if theta_end_deg is not None else (3.0 if foot else 135.0)
    if t0 == t1:
        raise InputError("theta-end-deg", f"equals theta-start-deg ({t0:g} deg): an empty range")
    return Rotation(omega, h * CM, t0 * DEG, t1 * DEG, n_theta)


def check_rft_size(n_samples: int, n_elements: int, field: str = "n-theta") -> None:
    """Refuse an RFT evaluation of ``n_samples`` x ``n_elements`` that would not fit in memory."""
    check_memory(field, n_samples * n_elements * RFT_BYTES_PER_EVAL,
                 f"{n_samples:,} samples x {n_elements:,} elements")


def series_from_field_units(model: str = "rft", leg: str = DEFAULT_LEG, leg_file: Path | None = None,
                            curvature: float | None = None, length_cm: float | None = None,
                            width_cm: float | None = None, hip_height_cm: float | None = None,
                            omega: float = 0.2, theta_start_deg: float | None = None,
                            theta_end_deg: float | None = None, n_theta: int = 271,
                            elements: int = 100, medium: str = "3 mm glass CP",
                            motion_file: Path | None = None, **options) -> xr.Dataset:
    """A force series of a registered model from field-unit inputs; defaults follow the leg
    (standard test for flat/c/reverse-c, the thesis's foot test for the foot). ``options``:
    the model's options (:mod:`terradyn.models`)."""
    from . import models

    m = models.get(model)
    shape = leg_from_field_units(leg, leg_file, curvature, length_cm, width_cm, elements)
    motion = motion_from_field_units(leg == "foot" and leg_file is None, motion_file, omega,
                                     hip_height_cm, theta_start_deg, theta_end_deg, n_theta)
    if model == "rft":
        check_rft_size(len(motion.trajectory().time) if motion_file is not None else n_theta,
                       shape.n_elements)
    return m.simulate(shape, motion, medium, **options)


def rft_series(**kw) -> xr.Dataset:
    """RFT force series from field-unit inputs (:func:`series_from_field_units`)."""
    return series_from_field_units("rft", **kw)


# ------------------------------------------------------------------ 3D RFT (terradyn.rft3d)
def parse_vector(field: str, text: str, n: int, unit: str = "") -> np.ndarray:
    """'a,b,c' -> float array of length n; one-line InputError naming the field otherwise."""
    try:
        v = np.array([float(x) for x in str(text).split(",")])
    except ValueError:
        raise InputError(field, f"must be {n} comma-separated numbers{' in ' + unit if unit else ''}, got {text!r}") from None
    if len(v) != n or not np.isfinite(v).all():
        raise InputError(field, f"must be {n} comma-separated finite numbers{' in ' + unit if unit else ''}, got {text!r}")
    return v


def body3d_from_field_units(mesh: Path | None = None, mesh_units: str = "mm", open_surface: bool = False,
                          max_edge_cm: float | None = None, body: str = "c"):
    from .rft3d.body import read_mesh
    from .rft3d.presets import preset

    me = None if max_edge_cm is None else positive("max-edge-cm", max_edge_cm, "cm") * CM
    if mesh is not None:
        return read_mesh(mesh, mesh_units, require_closed=not open_surface, max_edge=me)
    b = preset(body)
    return b.refined(me) if me else b


def motion3d_from_field_units(motion: Path | None = None, axis: str = "0,1,0", center_cm: str = "0,0,2",
                            position_cm: str | None = None, quat: str = "1,0,0,0", omega: float = 0.2,
                            angle_start_deg: float = -135.0, angle_end_deg: float = 135.0,
                            n_angles: int = 271):
    from .rft3d.motion import AxisRotation, read_motion3d_csv

    if motion is not None:
        return read_motion3d_csv(motion)
    c = parse_vector("center-cm", center_cm, 3, "cm") * CM
    p0 = c if position_cm is None else parse_vector("position-cm", position_cm, 3, "cm") * CM
    q0 = parse_vector("quat", quat, 4)
    from .rft3d.engine import check_quaternions

    check_quaternions(q0[None, :], "quat")  # named as the user typed it
    positive("omega", omega, "rad/s")
    if angle_end_deg <= angle_start_deg:
        raise InputError("angle-end-deg", f"must be > --angle-start-deg ({angle_start_deg:g} deg), got {angle_end_deg:g}")
    return AxisRotation(tuple(parse_vector("axis", axis, 3)), tuple(c), omega,
                        angle_start_deg * DEG, angle_end_deg * DEG, integer("n-angles", n_angles, 2),
                        tuple(p0), tuple(q0))


def rft3d_series(mesh=None, mesh_units="mm", open_surface=False, max_edge_cm=None, body="c",
                 motion=None, axis="0,1,0", center_cm="0,0,2", position_cm=None, quat="1,0,0,0",
                 omega=0.2, angle_start_deg=-135.0, angle_end_deg=135.0, n_angles=271,
                 surface_cm=0.0, medium="3 mm glass CP", model="agarwal", xi_from="plate",
                 mu_surf=None, alpha="fit", table_file=None, dynamic_lambda=None,
                 frame_deg=None, want_frame=False, want_elements=False):
    """(force series, per-element frame or None, body[, per-element dataset]) from field-unit
    inputs; the 4th item only with ``want_elements``."""
    from .errors import choice, finite
    from .media import MEDIA, stress_model
    from .rft3d import api
    from .rft3d.model import DEFAULT_MU_SURF, medium3d

    choice("model", model, api.MODELS)
    choice("medium", medium, list(MEDIA))
    if model == "agarwal":
        if alpha != "fit" or table_file is not None:
            raise InputError("alpha", "--alpha/--table-file apply with --model treers only")
        med = medium3d(medium, DEFAULT_MU_SURF if mu_surf is None else mu_surf, xi_from)
        sm = None
    else:
        if xi_from != "plate" or (mu_surf is not None and mu_surf != DEFAULT_MU_SURF):
            raise InputError("xi-from", "--xi-from/--mu-surf apply with --model agarwal only")
        med = medium
        sm = stress_model(medium, alpha, None, "linear", table_file)
    if dynamic_lambda is not None:
        positive("lambda", dynamic_lambda)
    b = body3d_from_field_units(mesh, mesh_units, open_surface, max_edge_cm, body)
    mot = motion3d_from_field_units(motion, axis, center_cm, position_cm, quat, omega,
                                  angle_start_deg, angle_end_deg, n_angles)
    surface = finite("surface-cm", surface_cm, "cm") * CM
    w, p, el = api.compute(b, mot, med, model, surface, None, dynamic_lambda, sm,
                           elements=want_frame or want_elements)
    ds = api.wrench_series(w, p, b, mot, med, model, surface, None, dynamic_lambda, sm)
    frame = None
    if want_frame:
        if frame_deg is not None:
            if p.angle is None:
                raise InputError("frame-deg", "applies to rotations only (not with --motion)")
            j = int(np.argmin(np.abs(p.angle / DEG - frame_deg)))
        else:
            j = int(np.argmax(np.linalg.norm(w[:, :3], axis=1)))
        frame = {k: v[j] for k, v in el.items()}
        from .rft3d.engine import rotation_matrices

        frame["vertices"] = p.position[j] + b.vertices @ rotation_matrices(p.quaternion[j]).T
        frame["frame_x"] = float(p.angle[j] / DEG) if p.angle is not None else float(p.time[j])
    if want_elements:
        return ds, frame, b, api.element_dataset(el, p, b, ds)
    return ds, frame, b
