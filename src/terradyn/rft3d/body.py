"""3D bodies for RFT: closed triangle meshes -> surface elements.

A :class:`Body` holds, in its own body frame (SI, m), one element per mesh triangle: centroid
``centroids`` (n, 3), outward unit normal ``normals`` (n, 3) (the area-weighted normal
``normals * areas[:, None]`` is the triangle's vector area) and ``areas`` (n,) m^2, plus the
mesh (``vertices`` (V, 3), ``faces`` (n, 3)) for figures. Meshes are read and made with
`trimesh <https://trimesh.org>`_; every mesh is checked (not empty, finite vertices, no
degenerate triangles, consistent winding, closed and outward where a solid is needed) and bad
ones raise :class:`~terradyn.errors.InputError` naming what is wrong.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError, integer, positive

#: Triangles with area below this fraction of the mean area count as degenerate.
DEGENERATE_FRACTION = 1e-10


@dataclass(frozen=True, eq=False)
class Body:
    """Surface elements of a rigid body in its body frame (see module docstring)."""

    centroids: np.ndarray
    normals: np.ndarray
    areas: np.ndarray
    vertices: np.ndarray
    faces: np.ndarray
    name: str = "body"
    info: dict | None = None

    def __len__(self) -> int:
        return len(self.areas)

    @property
    def vector_areas(self) -> np.ndarray:
        """Area-weighted normals (n, 3), m^2."""
        return self.normals * self.areas[:, None]

    def packed(self) -> np.ndarray:
        """(7, n) float64 rows cx, cy, cz, nx, ny, nz, area for the compiled kernels (cached)."""
        p = self.__dict__.get("_packed")
        if p is None:
            p = np.ascontiguousarray(np.vstack([self.centroids.T, self.normals.T, self.areas]))
            self.__dict__["_packed"] = p
        return p

    def bounding_sphere(self) -> tuple[float, float, float, float]:
        """A sphere (centre x, y, z, radius; m, body frame) holding every element centroid
        (cached)."""
        b = self.__dict__.get("_bound")
        if b is None:
            c = 0.5 * (self.centroids.min(0) + self.centroids.max(0))
            r = float(np.linalg.norm(self.centroids - c, axis=1).max()) * (1 + 1e-9) + 1e-12
            b = self.__dict__["_bound"] = (*map(float, c), r)
        return b

    def mesh(self):
        """The body as a :class:`trimesh.Trimesh`."""
        import trimesh

        return trimesh.Trimesh(self.vertices, self.faces, process=False)

    def describe(self) -> dict:
        lo, hi = self.vertices.min(0), self.vertices.max(0)
        return {"shape": self.name, "kind": "mesh", "triangles": len(self), "area_m2": float(self.areas.sum()),
                "bounds_m": [lo.tolist(), hi.tolist()], **(self.info or {})}

    def refined(self, max_edge: float) -> "Body":
        """The same surface split until no edge is longer than ``max_edge`` (m)."""
        return from_trimesh(_subdivide(self.mesh(), max_edge), self.name, require_closed=False,
                            info=self.info)


def _subdivide(mesh, max_edge: float):
    import trimesh

    max_edge = positive("max-edge", max_edge, "m")
    v, f = trimesh.remesh.subdivide_to_size(mesh.vertices, mesh.faces, max_edge, max_iter=30)
    return trimesh.Trimesh(v, f, process=False)


def from_trimesh(mesh, name: str = "mesh", require_closed: bool = True, field: str = "mesh",
                 info: dict | None = None) -> Body:
    """Elements of a :class:`trimesh.Trimesh` (vertices in m, body frame), after checks.

    ``require_closed``: the mesh must be watertight with outward normals (a solid); open
    surfaces (a sheet, a sole) pass with ``False`` and keep their winding's normals."""
    v = np.asarray(getattr(mesh, "vertices", []), float)
    f = np.asarray(getattr(mesh, "faces", []), dtype=np.int64)
    if f.size == 0 or v.size == 0:
        raise InputError(field, "is empty: a body needs at least one triangle")
    if f.ndim != 2 or f.shape[1] != 3:
        raise InputError(field, f"faces must be triangles (k, 3), got shape {f.shape}")
    if not np.isfinite(v).all():
        i = int(np.argwhere(~np.isfinite(v).all(1))[0, 0])
        raise InputError(field, f"vertex {i} is not finite (NaN or inf); all coordinates must be finite numbers")
    if f.min() < 0 or f.max() >= len(v):
        raise InputError(field, f"face indices must lie in [0, {len(v) - 1}]")
    tri = v[f]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    dbl = np.linalg.norm(cross, axis=1)
    bad = dbl <= DEGENERATE_FRACTION * dbl.mean() if dbl.mean() > 0 else np.ones(len(f), bool)
    if bad.any():
        raise InputError(field, f"{int(bad.sum())} degenerate triangle(s) (zero area, e.g. face "
                                f"{int(np.argmax(bad))}); every triangle needs three distinct, non-collinear vertices")
    import trimesh

    tm = trimesh.Trimesh(v, f, process=False)
    if not tm.is_winding_consistent:
        raise InputError(field, "inconsistent normals: neighbouring triangles are wound in opposite "
                                "senses; all faces must be ordered the same way (counter-clockwise seen from outside)")
    if require_closed:
        if not tm.is_watertight:
            raise InputError(field, "is not closed (watertight): a solid body needs a closed surface "
                                    "(or pass an open surface where allowed)")
        if tm.volume <= 0:
            raise InputError(field, "normals point inward (negative enclosed volume); faces must be "
                                    "counter-clockwise seen from outside")
    areas = 0.5 * dbl
    normals = cross / dbl[:, None]
    return Body(np.ascontiguousarray(tri.mean(1)), np.ascontiguousarray(normals), areas,
                v, f, name, info)


MESH_UNITS = {"m": 1.0, "cm": 1e-2, "mm": 1e-3}


def read_mesh(path: str | Path, units: str = "m", require_closed: bool = True,
              max_edge: float | None = None) -> Body:
    """A body from an STL, OBJ or PLY file (read with trimesh); ``units`` of the file's
    coordinates (m, cm, mm); optional refinement to ``max_edge`` (m)."""
    import trimesh

    from ..errors import choice

    choice("mesh-units", units, list(MESH_UNITS))
    path = Path(path)
    if not path.is_file():
        raise InputError("mesh", f"file not found: {path}")
    if path.suffix.lower() not in (".stl", ".obj", ".ply", ".off", ".glb", ".gltf"):
        raise InputError("mesh", f"{path}: unknown mesh format {path.suffix!r}; allowed: .stl, .obj, .ply, .off, .glb")
    try:
        tm = trimesh.load(str(path), force="mesh", process=False)
    except Exception as e:  # noqa: BLE001 - any parser failure is bad input
        raise InputError("mesh", f"{path}: cannot be read as a mesh ({type(e).__name__}: {e})") from None
    v = np.asarray(getattr(tm, "vertices", np.zeros((0, 3))), float) * MESH_UNITS[units]
    f = np.asarray(getattr(tm, "faces", np.zeros((0, 3), int)))
    if len(f) and np.isfinite(v).all():
        tm2 = trimesh.Trimesh(v, f, process=False)
        tm2.merge_vertices()  # STL stores each triangle's corners separately: share them
    else:  # empty or non-finite: let the checks of from_trimesh name the problem
        tm2 = type("Raw", (), {"vertices": v, "faces": f})()
    body = from_trimesh(tm2, path.stem, require_closed, field=f"mesh {path.name}",
                        info={"file": str(path), "file_units": units})
    return body.refined(max_edge) if max_edge else body


# ------------------------------------------------------------------------------------------
# Presets (body frame: origin at the body's reference point, z up)
# ------------------------------------------------------------------------------------------
def _finish(tm, name: str, max_edge: float | None, info: dict) -> Body:
    if max_edge:
        tm = _subdivide(tm, max_edge)
    return from_trimesh(tm, name, require_closed=True, info=info)


def box(lx: float, ly: float, lz: float, max_edge: float | None = None, name: str = "box") -> Body:
    """A box centred at the origin with edges lx, ly, lz (m) along x, y, z."""
    import trimesh

    dims = [positive(k, v, "m") for k, v in (("lx", lx), ("ly", ly), ("lz", lz))]
    me = max_edge if max_edge is not None else max(dims) / 10
    return _finish(trimesh.creation.box(extents=dims), name, me,
                   {"lx_m": dims[0], "ly_m": dims[1], "lz_m": dims[2], "max_edge_m": me})


def plate(length: float = 0.0762, width: float = 0.0254, thickness: float = 0.0064,
          max_edge: float | None = None) -> Body:
    """A flat plate (a thin box) centred at the origin: length along x, width along y,
    thickness along z (m). Default: the standard flat leg's plate, 7.62 x 2.54 x 0.64 cm."""
    me = max_edge if max_edge is not None else min(length, width) / 6
    return box(length, width, thickness, me, name="plate")


def cylinder(radius: float = 0.0127, height: float = 0.0508, sections: int = 32,
             max_edge: float | None = None) -> Body:
    """A cylinder centred at the origin, axis along z (m)."""
    import trimesh

    r = positive("radius", radius, "m")
    h = positive("height", height, "m")
    s = integer("sections", sections, 3)
    me = max_edge if max_edge is not None else min(2 * np.pi * r / s * 1.5, h / 4)
    return _finish(trimesh.creation.cylinder(radius=r, height=h, sections=s), "cylinder", me,
                   {"radius_m": r, "height_m": h, "sections": s})


def sphere(radius: float = 0.0127, subdivisions: int = 3) -> Body:
    """An icosphere centred at the origin (m); 20 x 4^subdivisions triangles."""
    import trimesh

    r = positive("radius", radius, "m")
    k = integer("subdivisions", subdivisions, 0)
    return _finish(trimesh.creation.icosphere(subdivisions=k, radius=r), "sphere", None,
                   {"radius_m": r, "subdivisions": k})
