"""Field-unit entry point (cm, deg) for 3D RFT, shared by the CLI and scripts: converts at the
edge and calls the SI API of :mod:`terradyn.rft3d`."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .errors import InputError, integer, positive
from .units import CM, DEG


def parse_vector(field: str, text: str, n: int, unit: str = "") -> np.ndarray:
    """'a,b,c' -> float array of length n; one-line InputError naming the field otherwise."""
    try:
        v = np.array([float(x) for x in str(text).split(",")])
    except ValueError:
        raise InputError(field, f"must be {n} comma-separated numbers{' in ' + unit if unit else ''}, got {text!r}") from None
    if len(v) != n or not np.isfinite(v).all():
        raise InputError(field, f"must be {n} comma-separated finite numbers{' in ' + unit if unit else ''}, got {text!r}")
    return v


def body_from_field_units(mesh: Path | None = None, mesh_units: str = "mm", open_surface: bool = False,
                          max_edge_cm: float | None = None, body: str = "c"):
    from .rft3d.body import read_mesh
    from .rft3d.presets import preset

    me = None if max_edge_cm is None else positive("max-edge-cm", max_edge_cm, "cm") * CM
    if mesh is not None:
        return read_mesh(mesh, mesh_units, require_closed=not open_surface, max_edge=me)
    b = preset(body)
    return b.refined(me) if me else b


def motion_from_field_units(motion: Path | None = None, axis: str = "0,1,0", center_cm: str = "0,0,2",
                            position_cm: str | None = None, quat: str = "1,0,0,0", omega: float = 0.2,
                            angle_start_deg: float = -135.0, angle_end_deg: float = 135.0,
                            n_angles: int = 271):
    from .rft3d.motion import AxisRotation, read_motion3d_csv

    if motion is not None:
        return read_motion3d_csv(motion)
    c = parse_vector("center-cm", center_cm, 3, "cm") * CM
    p0 = c if position_cm is None else parse_vector("position-cm", position_cm, 3, "cm") * CM
    q0 = parse_vector("quat", quat, 4)
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
    b = body_from_field_units(mesh, mesh_units, open_surface, max_edge_cm, body)
    mot = motion_from_field_units(motion, axis, center_cm, position_cm, quat, omega,
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
