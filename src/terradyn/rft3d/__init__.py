"""3D resistive force theory: any body (a triangle mesh) in any rigid 6-DoF motion.

Model: Agarwal, Goldman & Kamrin, PNAS 120 e2214017120 (2023) (3D-RFT), see
:mod:`terradyn.rft3d.model`; optional dynamic term of Agarwal et al., Sci. Adv. 7 eabe0631
(2021).

Conventions (SI everywhere): world frame x forward, y left, z up; the bed's free surface is the
plane z = ``surface`` (default 0, bed below). Quaternions are **(w, x, y, z)** (scalar first,
as MuJoCo), unit norm (|q| - 1 within 1e-6, else :class:`~terradyn.errors.InputError`),
rotating body to world: a body point c sits at X + R(q) c. Velocities V (of the body-frame
origin) and angular velocities W are in the world frame. Forces and torques are those of the
medium on the body; torques are about ``point`` (world, m), by default the body-frame origin X.

API::

    body = plate(length=0.0762, width=0.0254, thickness=0.0064)   # or box, cylinder, sphere,
    body = leg3d("c"), wheel(), foot_sole(), preset(name)           # the standard legs, ...
    body = read_mesh("foot.stl", units="mm")                        # from_trimesh(mesh)
    body.centroids (n, 3) m, body.normals (n, 3) outward unit, body.areas (n,) m^2 (body frame)
    medium = medium3d("poppy LP", xi_from="plate")  # Medium3D(name, xi_n N/m^3, mu_surf, rho)
    medium = agarwal_medium(bulk_density, mu_internal, mu_surf)

    wrench(body, X, q, V, W, medium, surface=0.0, point=None, dynamic_lambda=None) -> (6,)
    wrench_batch(body, X (S,3), q (S,4), V (S,3), W (S,3), medium, surface=0.0 | (S,),
                 point=None | (3,) | (S,3), dynamic_lambda=None, parallel=None,
                 dtype=np.float64) -> (S, 6)
        # [Fx, Fy, Fz] N, [Tx, Ty, Tz] N m; compiled, serial for small work
    Evaluator(body, medium, dynamic_lambda=None, dtype=np.float64)(X, q, V, W, surface=0.0,
                                                                   point=None) -> (6,)
        # fastest single pose, for a physics engine's step
    element_tractions(body, X, q, V, W, medium, surface=0.0, point=None, dynamic_lambda=None,
                      surface_correction=None) -> dict
        # NumPy: traction (S,n,3) N/m^2, force (S,n,3) N, r, v, normal, depth, active, wrench

    simulate(body, motion, medium, **options) -> xarray.Dataset
        # along time (s): Fx, Fy, Fz (N), Tx, Ty, Tz (N m), attrs record the input;
        # options: model="agarwal"|"treers", surface, point, dynamic_lambda, stress_model
        #          (treers: any 2D coefficient set), surface_correction, parallel
    motions: RigidMotion(time, position, quaternion[, velocity, angular_velocity]),
             AxisRotation(axis, center, omega, angle_start, angle_end, n, position0, quaternion0),
             PlanarAs3D(planar_motion), read_motion3d_csv(path)
"""
from .api import MODELS, compute, element_frame, simulate, wrench_series
from .body import Body, box, cylinder, from_trimesh, plate, read_mesh, sphere
from .engine import (Evaluator, check_quaternions, element_tractions, rotation_matrices, wrench,
                     wrench_batch)
from .model import (AGARWAL2023, AgarwalPlanar, Medium3D, agarwal_medium, coefficients, generic_alpha, medium3d,
                    scaled_alpha, xi_n)
from .presets import PRESETS, foot_sole, leg3d, preset, standard_legs, wheel
from .motion import (AxisRotation, PlanarAs3D, Poses, RigidMotion, axis_angle_quat, planar_poses,
                     quat_multiply, read_motion3d_csv)

__all__ = [
    "MODELS", "compute", "element_frame", "simulate", "wrench_series", "Body", "box", "cylinder",
    "from_trimesh", "plate", "read_mesh", "sphere", "Evaluator", "check_quaternions",
    "element_tractions", "rotation_matrices", "wrench", "wrench_batch", "AGARWAL2023", "Medium3D",
    "agarwal_medium", "coefficients", "generic_alpha", "medium3d", "scaled_alpha", "xi_n",
    "AxisRotation", "PlanarAs3D", "Poses", "RigidMotion", "axis_angle_quat", "planar_poses",
    "quat_multiply", "read_motion3d_csv", "AgarwalPlanar", "PRESETS", "foot_sole", "leg3d",
    "preset", "standard_legs", "wheel",
]
