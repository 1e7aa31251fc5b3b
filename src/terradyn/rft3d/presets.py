"""Preset 3D bodies: the three standard legs, a wheel with grousers, a human foot sole.

All are closed triangle meshes (solids) in their body frame (SI, m), checked like any mesh:

* :func:`leg3d` - a 2D leg of :mod:`terradyn.geometry` (flat, c, reverse-c, any arc or
  polyline) swept into a solid strip: its centreline in the x-z plane, ``thickness`` across
  it (default 0.64 cm), ``width`` along y (default 2.54 cm), the hip at the origin. Driven by
  :class:`~terradyn.rft3d.motion.PlanarAs3D` it is the 2D engine's leg with real thickness.
* :func:`wheel` - a cylinder (axis y, centre at the origin) with radial plate grousers.
* :func:`foot_sole` - a sole about 25 x 8.5 cm (heel to toe along +x from the origin, width
  along y, thickness along z centred on z = 0), the 3D analogue of :func:`terradyn.geometry.foot`.
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError, integer, positive
from ..geometry import STANDARD_WIDTH, Leg, make_leg
from ..units import CM
from .body import Body, from_trimesh

#: Thickness of the standard legs (Li 2013): 0.64 cm.
STANDARD_THICKNESS = 0.64 * CM


def _tm(v, f):
    import trimesh

    return trimesh.Trimesh(np.asarray(v, float), np.asarray(f, np.int64), process=False)


def _outward(v, f):
    """Faces with outward winding (a consistently wound closed mesh: flip all if inside out)."""
    tm = _tm(v, f)
    return f[:, ::-1].copy() if tm.volume < 0 else f


def _loop_quads(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Triangles joining two closed loops of vertex indices a, b (same length)."""
    a2, b2 = np.roll(a, -1), np.roll(b, -1)
    return np.concatenate([np.stack([a, a2, b2], 1), np.stack([a, b2, b], 1)])


def _strip_quads(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Triangles joining two open rows of vertex indices a, b (same length)."""
    return np.concatenate([np.stack([a[:-1], a[1:], b[1:]], 1), np.stack([a[:-1], b[1:], b[:-1]], 1)])


# ------------------------------------------------------------------------------------------
# Legs
# ------------------------------------------------------------------------------------------
def leg3d(leg: Leg | str = "c", thickness: float = STANDARD_THICKNESS, width: float | None = None,
          n_along: int = 60, n_width: int = 8) -> Body:
    """A 2D leg swept into a solid: centreline (x, z) from the hip (origin) to the tip,
    ``thickness`` (m) normal to it in the x-z plane, ``width`` (m, default the leg's own) along
    y; ``n_along`` stations, ``n_width`` elements across the width."""
    if isinstance(leg, str):
        leg = make_leg(leg)
    t = positive("thickness", thickness, "m")
    w = positive("width", leg.width if width is None else width, "m")
    na = integer("n_along", n_along, 2)
    nw = integer("n_width", n_width, 1)
    c = leg.outline(na + 1)  # (na+1, 2) hip to tip
    d = np.gradient(c, axis=0)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    nu = np.column_stack([-d[:, 1], d[:, 0]])  # in-plane normal of the centreline
    # cross-section loop in (offset along nu, y): outer face, +y side, inner face, -y side
    ys = np.linspace(-w / 2, w / 2, nw + 1)
    loop = ([(t / 2, y) for y in ys] + [(-t / 2, y) for y in ys[::-1]])
    loop = np.array(loop)
    M = len(loop)
    verts = []
    for i in range(len(c)):
        p = c[i] + loop[:, :1] * nu[i]
        verts.append(np.column_stack([p[:, 0], loop[:, 1], p[:, 1]]))
    V = np.concatenate(verts)
    idx = np.arange(len(c) * M).reshape(len(c), M)
    faces = [_loop_quads(idx[i], idx[i + 1]) for i in range(len(c) - 1)]
    # end caps: the loop is two rows (outer, inner) of nw+1 points -> a strip
    for k, row in enumerate((idx[0], idx[-1])):
        cap = _strip_quads(row[:nw + 1], row[nw + 1:][::-1])
        faces.append(cap if k else cap[:, ::-1])  # the two ends face opposite ways
    F = np.concatenate(faces)
    F = _outward(V, F)
    name = getattr(leg, "name", "leg")
    return from_trimesh(_tm(V, F), f"{name}-3d", require_closed=True, field=f"leg {name}",
                        info={"leg": leg.describe(), "thickness_m": t, "width_m": w,
                              "n_along": na, "n_width": nw})


def standard_legs(**kw) -> dict[str, Body]:
    """The three legs of the standard rotating-leg test (flat, c, reverse-c; chord 7.62 cm,
    width 2.54 cm, thickness 0.64 cm) as 3D bodies."""
    return {s: leg3d(s, **kw) for s in ("flat", "c", "reverse-c")}


# ------------------------------------------------------------------------------------------
# Star-shaped profiles extruded: wheel, sole
# ------------------------------------------------------------------------------------------
def _extrude_star(profile: np.ndarray, depth: float, n_depth: int, rings: int):
    """A closed mesh from a closed 2D profile (M, 2), star-shaped about the origin (every ray
    from the origin meets it once), extruded from -depth/2 to depth/2 along the third axis.
    Caps are ``rings`` concentric scaled copies of the profile (quads between, a fan at the
    centre). Returns vertices (V, 3) with the profile in columns 0, 1 and the extrusion in 2."""
    M = len(profile)
    zs = np.linspace(-depth / 2, depth / 2, n_depth + 1)
    V = [np.column_stack([profile, np.full(M, z)]) for z in zs]
    idx = [np.arange(M) + k * M for k in range(len(zs))]
    F = [_loop_quads(idx[k], idx[k + 1]) for k in range(n_depth)]
    nv = len(zs) * M
    for end, (z, outer) in enumerate(((zs[0], idx[0]), (zs[-1], idx[-1]))):
        cap = []
        prev = outer
        for r in range(rings - 1, 0, -1):
            V.append(np.column_stack([profile * (r / rings), np.full(M, z)]))
            cur = np.arange(M) + nv
            nv += M
            cap.append(_loop_quads(prev, cur))
            prev = cur
        V.append(np.array([[0.0, 0.0, z]]))
        cap.append(np.stack([prev, np.roll(prev, -1), np.full(M, nv)], 1))
        nv += 1
        cap = np.concatenate(cap)
        F.append(cap if end else cap[:, ::-1])  # the two caps face opposite ways
    V = np.concatenate(V)
    F = np.concatenate(F)
    return V, _outward(V, F)


def wheel(radius: float = 0.05, width: float = 0.04, n_grousers: int = 12,
          grouser_height: float = 0.008, grouser_thickness: float = 0.003, n_rim: int = 240,
          n_width: int = 6) -> Body:
    """A wheel: a cylinder of ``radius`` and ``width`` (m), axis along y through the origin,
    with ``n_grousers`` radial plate grousers (``grouser_height`` above the rim,
    ``grouser_thickness`` along the rim; 0 grousers: a plain wheel). It rolls in the x-z plane:
    spin about +y."""
    R = positive("radius", radius, "m")
    B = positive("width", width, "m")
    ng = integer("n_grousers", n_grousers, 0)
    h = positive("grouser_height", grouser_height, "m") if ng else 0.0
    tg = positive("grouser_thickness", grouser_thickness, "m") if ng else 0.0
    if ng and ng * tg >= 2 * np.pi * R * 0.8:
        raise InputError("n_grousers", f"{ng} grousers of {tg * 100:g} cm do not fit on a rim of radius {R * 100:g} cm")
    nr = integer("n_rim", n_rim, 8)
    phi = np.linspace(0, 2 * np.pi, nr, endpoint=False)
    r = np.full(nr, R)
    pts = []
    if ng:
        half = tg / (2 * R)  # half angular width of a grouser at the rim
        centres = 2 * np.pi * np.arange(ng) / ng
        for k, c in enumerate(centres):
            nxt = centres[(k + 1) % ng] + (2 * np.pi if k == ng - 1 else 0)
            # the grouser: a rectangle (constant thickness) from R to R + h
            for rr in np.linspace(R, R + h, 4):
                pts.append((c - tg / (2 * rr), rr))
            for rr in np.linspace(R + h, R, 4):
                pts.append((c + tg / (2 * rr), rr))
            arc = np.linspace(c + half, nxt - half, max(2, nr // ng), endpoint=False)[1:]
            pts.extend((a, R) for a in arc)
        phi, r = np.array(pts).T
    prof = np.column_stack([r * np.cos(phi), r * np.sin(phi)])
    # remove consecutive duplicates (the grouser's first/last corner on the rim)
    keep = np.linalg.norm(prof - np.roll(prof, 1, axis=0), axis=1) > 1e-12
    prof = prof[keep]
    V, F = _extrude_star(prof, B, integer("n_width", n_width, 1), rings=4)
    V = V[:, [0, 2, 1]]  # profile in x-z, extrusion along y
    F = F[:, ::-1]  # swapping two axes mirrors the mesh: keep the winding outward
    return from_trimesh(_tm(V, F), "wheel", require_closed=True, field="wheel",
                        info={"radius_m": R, "width_m": B, "n_grousers": ng,
                              "grouser_height_m": h, "grouser_thickness_m": tg})


def sole_outline(length: float = 0.25, width: float = 0.085, n: int = 80) -> np.ndarray:
    """(n, 2) outline (x, y) of a foot sole, heel at x = 0 and toe at x = length, widest
    (``width``) at the ball, about 0.7 of the length from the heel; the heel ~0.65 x width."""
    s = np.linspace(0, 2 * np.pi, n, endpoint=False)
    u = 0.5 * (1 - np.cos(s))  # 0 (heel) .. 1 (toe)
    g = np.interp(u, [0.0, 0.3, 0.7, 1.0], [0.7, 0.8, 1.05, 0.9])  # width modulation
    y = np.sin(s) * g
    return np.column_stack([u * length, y * (0.5 * width / np.abs(y).max())])


def foot_sole(length: float = 0.25, width: float = 0.085, thickness: float = 0.01,
              n_outline: int = 80, rings: int = 6) -> Body:
    """A human foot sole (about 25 x 8.5 cm, ~2,000 triangles by default): heel at the origin,
    toe at x = length, width along y, thickness along z centred on z = 0."""
    L = positive("length", length, "m")
    B = positive("width", width, "m")
    t = positive("thickness", thickness, "m")
    prof = sole_outline(L, B, integer("n_outline", n_outline, 8))
    cx = 0.45 * L  # the profile is star-shaped about a point inside the arch
    V, F = _extrude_star(prof - [cx, 0.0], t, 1, integer("rings", rings, 1))
    V[:, 0] += cx
    return from_trimesh(_tm(V, F), "foot-sole", require_closed=True, field="foot sole",
                        info={"length_m": L, "width_m": B, "thickness_m": t})


PRESETS = ("plate", "flat", "c", "reverse-c", "cylinder", "sphere", "wheel", "foot")


def preset(name: str) -> Body:
    """A preset body by name (see :data:`PRESETS`) with its default dimensions."""
    from ..errors import choice
    from .body import cylinder, plate, sphere

    choice("body", name, PRESETS)
    if name in ("flat", "c", "reverse-c"):
        return leg3d(name)
    return {"plate": plate, "cylinder": cylinder, "sphere": sphere, "wheel": wheel,
            "foot": foot_sole}[name]()


__all__ = ["STANDARD_THICKNESS", "STANDARD_WIDTH", "leg3d", "standard_legs", "wheel", "foot_sole",
           "sole_outline", "preset", "PRESETS"]
