"""Scene builders: granular bed in a container, column collapse, rigid leg in a bed.

World frame (SI): x forward, z up, free surface at z = 0 for beds; particles on a square
lattice of spacing dx; each dummy-wall region has ``config.wall_layers`` layers (covers the
kernel support 2h = 2.6 dx). Initial stress is geostatic: sigma_zz = -rho g (depth),
sigma_xx = sigma_yy = K0 sigma_zz (Jaky 1944), unless ``initial="zero"``.
"""
from __future__ import annotations

import math

import numpy as np

from ..errors import InputError, positive
from ..geometry import Leg
from ..motion import Trajectory
from ..units import CM, G
from .materials import GranularMaterial, material as _material
from .state import LEG, SOIL, WALL, Particles, RigidBody, Scene, SPHConfig

#: Thickness of the standard legs (thesis ch. 2: 0.64 cm).
LEG_THICKNESS = 0.64 * CM


def lattice(x0: float, x1: float, z0: float, z1: float, dx: float) -> tuple[np.ndarray, np.ndarray]:
    """Square lattice of spacing dx in [x0, x1] x [z0, z1], anchored at the top (z1) and
    centred in x (so a free surface at z1 is exact); (M,) x and z."""
    nx = max(int(round((x1 - x0) / dx)), 1)
    nz = max(int(round((z1 - z0) / dx)), 1)
    xs = 0.5 * (x0 + x1) + (np.arange(nx) - 0.5 * (nx - 1)) * dx
    zs = z1 - (np.arange(nz) + 0.5) * dx
    X, Z = np.meshgrid(xs, zs)
    return X.ravel(), Z.ravel()


def snap(length: float, dx: float) -> float:
    """``length`` rounded to a whole number of particle spacings (>= 1)."""
    return max(int(round(length / dx)), 1) * dx


def container_walls(x0: float, x1: float, z_bottom: float, z_top: float, dx: float, layers: int,
                    left: bool = True, right: bool = True, x_floor_end: float | None = None):
    """Dummy particles of a floor below ``z_bottom`` and side walls at x0 (left) and x1 (right)
    reaching up to ``z_top``; (M,) x and z. x1 - x0 must be a whole number of spacings."""
    z_top = z_bottom + snap(z_top - z_bottom, dx)
    xe = x1 if x_floor_end is None else x_floor_end
    fx0 = x0 - (layers * dx if left else 0.0)
    fx1 = xe + (layers * dx if right else 0.0)
    parts = [lattice(fx0, fx1, z_bottom - layers * dx, z_bottom, dx)]
    if left:
        parts.append(lattice(x0 - layers * dx, x0, z_bottom, z_top, dx))
    if right:
        parts.append(lattice(x1, x1 + layers * dx, z_bottom, z_top, dx))
    return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])


def geostatic(z: np.ndarray, z_surface: float, mat: GranularMaterial, gravity: float = G):
    """Geostatic stress (tension positive), (M,) each: sxx, szz, sxz, syy."""
    szz = -mat.density * gravity * np.clip(z_surface - z, 0.0, None)
    sxx = mat.lateral_ratio * szz
    return sxx, szz, np.zeros_like(z), sxx.copy()


def _assemble(parts, mat, dx, surface_of=None):
    """parts: list of (x, z, kind); returns Particles with mass rho0 dx^2 (per unit depth)."""
    x = np.concatenate([p[0] for p in parts])
    z = np.concatenate([p[1] for p in parts])
    kind = np.concatenate([np.full(len(p[0]), p[2], np.int8) for p in parts])
    n = len(x)
    rho = np.full(n, mat.density)
    p = Particles(x=x, z=z, kind=kind, mass=rho * dx * dx, rho=rho)
    return p


def _set_stress(p: Particles, mat: GranularMaterial, z_surface, initial: str):
    if initial == "zero":
        return
    if initial != "geostatic":
        raise InputError("initial", f"must be 'geostatic' or 'zero', got {initial!r}")
    soil = p.kind == SOIL
    zs = z_surface(p.x[soil]) if callable(z_surface) else z_surface
    sxx, szz, sxz, syy = geostatic(p.z[soil], zs, mat)
    p.sxx[soil], p.szz[soil], p.sxz[soil], p.syy[soil] = sxx, szz, sxz, syy


# ------------------------------------------------------------------------------------ beds
def bed_scene(width: float = 0.2, depth: float = 0.1, dx: float = 5e-3,
              medium: str | GranularMaterial = "3 mm glass CP", initial: str = "geostatic",
              config: SPHConfig | None = None, **cfg_kw) -> Scene:
    """A bed at rest: x in [-width/2, width/2], z in [-depth, 0], walls on three sides."""
    positive("width", width, "m")
    positive("depth", depth, "m")
    cfg = config or SPHConfig(dx=dx, **cfg_kw)
    mat = _material(medium, cfg.dx)
    dx = cfg.dx
    width, depth = snap(width, dx), snap(depth, dx)
    sx, sz = lattice(-width / 2, width / 2, -depth, 0.0, dx)
    wx, wz = container_walls(-width / 2, width / 2, -depth, 0.5 * depth, dx, cfg.wall_layers)
    p = _assemble([(sx, sz, SOIL), (wx, wz, WALL)], mat, dx)
    _set_stress(p, mat, 0.0, initial)
    return Scene(p, mat, cfg, meta={"scene": "bed", "width_m": width, "depth_m": depth,
                                    "initial": initial}, depth_scale=depth)


def column_scene(aspect: float, base: float = 0.05, dx: float = 2.5e-3,
                 medium: str | GranularMaterial = "3 mm glass CP", config: SPHConfig | None = None,
                 **cfg_kw) -> Scene:
    """A 2D granular column of width ``base`` (L_i) and height aspect * base against a left wall
    on a rough floor, released at t = 0 (the gate of Lube et al. 2005 vanishes)."""
    a = positive("aspect", aspect)
    cfg = config or SPHConfig(dx=dx, **cfg_kw)
    mat = _material(medium, cfg.dx)
    dx = cfg.dx
    base = snap(base, dx)
    H = snap(a * base, dx)
    sx, sz = lattice(0.0, base, 0.0, H, dx)
    run = snap(base * (3.0 + 2.5 * a), dx)
    wx, wz = container_walls(0.0, run, 0.0, H + 4 * dx, dx, cfg.wall_layers, right=False,
                             x_floor_end=run)
    p = _assemble([(sx, sz, SOIL), (wx, wz, WALL)], mat, dx)
    _set_stress(p, mat, H, "geostatic")
    return Scene(p, mat, cfg, meta={"scene": "column", "aspect": a, "base_m": base},
                 depth_scale=max(H, base))


def slope_scene(angle: float, height: float = 0.06, dx: float = 4e-3,
                medium: str | GranularMaterial = "3 mm glass CP",
                config: SPHConfig | None = None, **cfg_kw) -> Scene:
    """A 2D wedge of granular material against a left wall on a rough floor: free surface
    z = height - x tan(angle) (``angle`` in rad, 0 < angle < 80 deg), geostatic stress from the
    local depth below it (not an equilibrium state of a slope: a slope near the friction angle
    creeps a little while its shear stresses build)."""
    from ..errors import in_range

    in_range("angle", angle, 1e-3, math.radians(80.0), "rad")
    positive("height", height, "m")
    cfg = config or SPHConfig(dx=dx, **cfg_kw)
    mat = _material(medium, cfg.dx)
    dx = cfg.dx
    height = snap(height, dx)
    foot = snap(height / math.tan(angle) + dx, dx)
    sx, sz = lattice(0.0, foot, 0.0, height, dx)
    keep = sz < height - sx * math.tan(angle)
    sx, sz = sx[keep], sz[keep]
    run = snap(3.0 * foot, dx)
    wx, wz = container_walls(0.0, run, 0.0, height + 4 * dx, dx, cfg.wall_layers, right=False,
                             x_floor_end=run)
    p = _assemble([(sx, sz, SOIL), (wx, wz, WALL)], mat, dx)
    _set_stress(p, mat, lambda x: height - x * math.tan(angle), "geostatic")
    return Scene(p, mat, cfg, meta={"scene": "slope", "angle_rad": angle, "height_m": height,
                                    "foot_m": foot}, depth_scale=height)


# ------------------------------------------------------------------------------------ legs
def _centre_line(leg: Leg, dx: float):
    """Points (m, 2) and unit tangents along the leg's centre line, hip to tip, spacing ~dx."""
    pts = np.asarray(leg.outline(4000) if not hasattr(leg, "points") else leg.points, float)
    seg = np.diff(pts, axis=0)
    sl = np.hypot(seg[:, 0], seg[:, 1])
    s = np.concatenate([[0.0], np.cumsum(sl)])
    L = s[-1]
    n = max(int(round(L / dx)), 2)
    q = (np.arange(n) + 0.5) * (L / n)
    P = np.stack([np.interp(q, s, pts[:, 0]), np.interp(q, s, pts[:, 1])], -1)
    eps = 0.25 * L / n
    qa = np.clip(q - eps, 0, L)
    qb = np.clip(q + eps, 0, L)
    T = (np.stack([np.interp(qb, s, pts[:, 0]), np.interp(qb, s, pts[:, 1])], -1)
         - np.stack([np.interp(qa, s, pts[:, 0]), np.interp(qa, s, pts[:, 1])], -1))
    T /= np.hypot(T[:, 0], T[:, 1])[:, None]
    return P, T, L


def centre_polyline(leg: Leg, dx: float) -> np.ndarray:
    """(2, m) body-frame centre line of the leg from hip to tip at spacing ~dx/2, ends
    included (for the side test of :func:`terradyn.sph.physics._side_one`)."""
    P, T, L = _centre_line(leg, 0.5 * dx)
    d = 0.5 * L / len(P)  # _centre_line gives mid-points: put the two ends back
    P = np.concatenate([P[:1] - d * T[:1], P, P[-1:] + d * T[-1:]])
    return np.ascontiguousarray(P.T)


def leg_particles(leg: Leg, dx: float, thickness: float = LEG_THICKNESS, layers: int = 3):
    """Body-frame dummy particles of a thin rigid leg.

    Each side of the leg has its own ``layers`` layers, starting dx/2 inside its surface (at
    thickness/2 from the centre line) and going inwards (past the other surface if the leg is
    thinner than the kernel support); a side's particles interact only with material on that
    side. Returns bx, bz, bnx, bnz (outward normal of the side), dcl (offset from the centre
    line along that normal), guard (1 except within 1.5 dx of either end, where the side
    planes do not bound the body), all (M,)."""
    positive("thickness", thickness, "m")
    P, T, L = _centre_line(leg, dx)
    q = (np.arange(len(P)) + 0.5) * (L / len(P))
    grd = ((q < L - 1.5 * dx) & (q > 1.5 * dx)).astype(float)
    Nn = np.stack([-T[:, 1], T[:, 0]], -1)
    out = []
    for side in (1.0, -1.0):
        n_out = side * Nn
        for k in range(layers):
            d = 0.5 * thickness - (k + 0.5) * dx
            pos = P + d * n_out
            out.append((pos[:, 0], pos[:, 1], n_out[:, 0], n_out[:, 1], np.full(len(P), d), grd))
    return tuple(np.concatenate([o[i] for o in out]) for i in range(6))


def _body_to_world(bx, bz, hip_x, hip_z, ang):
    c, s = math.cos(ang), math.sin(ang)
    return hip_x + c * bx + s * bz, hip_z - s * bx + c * bz


def contact_window(leg: Leg, traj: Trajectory, margin: float) -> tuple[int, int]:
    """First and last sample index where the leg is within ``margin`` (m) of the bed (z < 0);
    (-1, -1) if never."""
    P, _, _ = _centre_line(leg, 2e-3)
    c = np.cos(traj.angle)[:, None]
    s = np.sin(traj.angle)[:, None]
    z = traj.hip_z[:, None] - s * P[None, :, 0] + c * P[None, :, 1]
    touch = np.flatnonzero(z.min(axis=1) < margin)
    if len(touch) == 0:
        return -1, -1
    return max(int(touch[0]) - 1, 0), min(int(touch[-1]) + 1, len(traj) - 1)


def leg_scene(leg: Leg, traj: Trajectory, i0: int, medium: str | GranularMaterial = "3 mm glass CP",
              bed_width: float = 0.30, bed_depth: float = 0.10, thickness: float = LEG_THICKNESS,
              config: SPHConfig | None = None, **cfg_kw) -> Scene:
    """A bed (x centred on the hip's mean x) with the leg placed at trajectory sample ``i0``;
    granular particles that overlap the leg's body there are removed."""
    cfg = config or SPHConfig(**cfg_kw)
    mat = _material(medium, cfg.dx)
    dx = cfg.dx
    xc = float(np.mean(traj.hip_x))
    bed_width, bed_depth = snap(bed_width, dx), snap(bed_depth, dx)
    bx, bz, bnx, bnz, dcl, guard = leg_particles(leg, dx, thickness, cfg.wall_layers)
    sx, sz = lattice(xc - bed_width / 2, xc + bed_width / 2, -bed_depth, 0.0, dx)
    # remove material inside the leg's body at the start pose
    P, _, _ = _centre_line(leg, 0.25 * dx)
    wx0, wz0 = _body_to_world(P[:, 0], P[:, 1], traj.hip_x[i0], traj.hip_z[i0], traj.angle[i0])
    from scipy.spatial import cKDTree

    d, _ = cKDTree(np.stack([wx0, wz0], -1)).query(np.stack([sx, sz], -1))
    keep = d > 0.5 * thickness + 0.5 * dx
    sx, sz = sx[keep], sz[keep]
    wx, wz = container_walls(xc - bed_width / 2, xc + bed_width / 2, -bed_depth, 0.03, dx,
                             cfg.wall_layers)
    lx, lz = _body_to_world(bx, bz, traj.hip_x[i0], traj.hip_z[i0], traj.angle[i0])
    p = _assemble([(sx, sz, SOIL), (wx, wz, WALL), (lx, lz, LEG)], mat, dx)
    _set_stress(p, mat, 0.0, "geostatic")
    body = RigidBody(bx, bz, bnx, bnz, dcl, traj, float(traj.time[i0]), float(leg.width),
                     thickness, guard, centre=centre_polyline(leg, dx))
    return Scene(p, mat, cfg, leg=body,
                 meta={"scene": "leg", "leg": leg.describe(), "bed_width_m": bed_width,
                       "bed_depth_m": bed_depth, "thickness_m": thickness, "i0": int(i0)},
                 depth_scale=bed_depth)
