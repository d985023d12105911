"""Convex pieces of the world's shapes that MuJoCo has no primitive for (it collides a mesh as its convex hull).

- a static mesh: each connected part that is convex is one piece; a concave part becomes one 1 cm slab under
  each triangle (exact, as pybullet's concave triangle mesh, but many geoms);
- a dynamic mesh: one piece per object of an OBJ file (pybullet's convex hull per object: how a
  VHACD-decomposed OBJ is used), one hull of all vertices for the other formats;
- a static polyline: the outline cut into convex polygons (exact), each extruded; a dynamic one: its hull.
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pytest_ddenv.world.meshes import load_mesh, polyline_polygon

Piece = tuple[NDArray[np.float64], NDArray[np.int64]]
"""Vertices (N, 3) and triangles (M, 3) of one convex piece."""
SLAB = 0.01
"""Thickness of the slab under each triangle of a concave static mesh (m)."""


@functools.lru_cache(maxsize=32)
def static_mesh_pieces(path: Path, scale: tuple[float, float, float]) -> tuple[Piece, ...]:
    """Convex pieces whose union is the static mesh's surface (see the module docstring)."""
    mesh: Any = load_mesh(path, scale)
    pieces: list[Piece] = []
    for part in mesh.split(only_watertight=False):
        hull = part.convex_hull
        if part.is_volume and abs(hull.volume - part.volume) <= 1e-3 * hull.volume:
            pieces.append((np.asarray(part.vertices, dtype=np.float64), np.asarray(part.faces, dtype=np.int64)))
            continue
        for triangle, normal in zip(part.triangles, part.face_normals, strict=True):
            vertices = np.vstack([triangle, triangle - normal * SLAB])
            pieces.append((vertices.astype(np.float64), np.array([[0, 1, 2], [3, 5, 4]], dtype=np.int64)))
    return tuple(pieces)


@functools.lru_cache(maxsize=32)
def dynamic_mesh_pieces(path: Path, scale: tuple[float, float, float]) -> tuple[Piece, ...]:
    """One piece per object of an OBJ file, else one of the whole mesh (MuJoCo takes each piece's hull)."""
    if path.suffix.lower() == ".obj":
        pieces = _obj_objects(path, scale)
        if pieces:
            return pieces
    mesh: Any = load_mesh(path, scale)
    return ((np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int64)),)


def _obj_objects(path: Path, scale: tuple[float, float, float]) -> tuple[Piece, ...]:
    vertices: list[list[float]] = []
    groups: list[list[list[int]]] = [[]]
    for line in path.read_text(errors="replace").splitlines():
        parts = line.split()
        if not parts:
            continue
        if parts[0] == "v":
            vertices.append([float(v) for v in parts[1:4]])
        elif parts[0] in ("o", "g") and groups[-1]:
            groups.append([])
        elif parts[0] == "f":
            index = [int(token.split("/")[0]) for token in parts[1:]]
            index = [i - 1 if i > 0 else len(vertices) + i for i in index]
            groups[-1].extend([index[0], index[k], index[k + 1]] for k in range(1, len(index) - 1))
    scaled = np.asarray(vertices, dtype=np.float64) * np.asarray(scale, dtype=np.float64)
    pieces: list[Piece] = []
    for faces in groups:
        if not faces:
            continue
        used = np.unique(np.asarray(faces))
        remap = {int(u): k for k, u in enumerate(used)}
        pieces.append((scaled[used], np.array([[remap[i] for i in face] for face in faces], dtype=np.int64)))
    return tuple(pieces)


def polyline_pieces(points: tuple[tuple[float, float], ...], height: float, static: bool) -> tuple[Piece, ...]:
    """The extruded outline: convex prisms whose union it is (static), or one prism (its hull, dynamic)."""
    polygon = polyline_polygon(points)
    outlines = _convex_polygons(polygon) if static else [np.asarray(polygon.exterior.coords)[:-1]]
    return tuple(_prism(outline, height) for outline in outlines)


def _convex_polygons(polygon: Any) -> list[NDArray[np.float64]]:
    """Ear-clipping triangles merged greedily while the union stays convex (Hertel-Mehlhorn): exact."""
    import mapbox_earcut
    import shapely
    from shapely.geometry.polygon import orient  # shapely.orient_polygons is 2.1+; the lowest allowed is 2.0

    if polygon.equals(polygon.convex_hull):
        return [np.asarray(polygon.exterior.coords)[:-1]]
    ring = np.asarray(polygon.exterior.coords, dtype=np.float64)[:-1]
    indices = mapbox_earcut.triangulate_float64(ring, np.array([len(ring)], dtype=np.uint32))
    pieces = [shapely.Polygon(ring[indices[k:k + 3]]) for k in range(0, len(indices), 3)]
    merged = True
    while merged:
        merged = False
        for i in range(len(pieces)):
            for j in range(i + 1, len(pieces)):
                if not (pieces[i].touches(pieces[j]) and pieces[i].intersection(pieces[j]).length > 1e-9):
                    continue
                union = shapely.union(pieces[i], pieces[j]).simplify(0)
                if isinstance(union, shapely.Polygon) and abs(union.area - union.convex_hull.area) < 1e-9:
                    pieces[i] = union
                    del pieces[j]
                    merged = True
                    break
            if merged:
                break
    return [np.asarray(orient(piece, sign=1.0).exterior.coords)[:-1] for piece in pieces]  # counter-clockwise


def _prism(outline: NDArray[np.float64], height: float) -> Piece:
    count = len(outline)
    bottom = np.column_stack([outline, np.zeros(count)])
    vertices = np.vstack([bottom, np.column_stack([outline, np.full(count, height)])])
    faces = []
    for i in range(1, count - 1):
        faces.append([0, i + 1, i])
        faces.append([count, count + i, count + i + 1])
    for i in range(count):
        j = (i + 1) % count
        faces.append([i, j, count + j])
        faces.append([i, count + j, count + i])
    return vertices.astype(np.float64), np.asarray(faces, dtype=np.int64)
