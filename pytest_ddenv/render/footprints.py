"""What each model looks like from above: its footprint (the real outline of each shape on the ground) and the
class it is drawn with (static or dynamic, high or low friction, terrain)."""

from __future__ import annotations

import functools
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from pytest_ddenv.world import geometry
from pytest_ddenv.world.files import resolve_mesh_path
from pytest_ddenv.world.geometry import FloatArray
from pytest_ddenv.world.meshes import load_heightmap, load_mesh
from pytest_ddenv.world.model import Model, Shape, World

HIGH_FRICTION = 5.0
LOW_FRICTION = 0.5
TERRAIN_EXTENT = 8.0
"""Models wider than this (m) are terrain: drawn, but they do not stretch the view."""

Category = Literal["static", "dynamic"]
Friction = Literal["high", "low"] | None


@dataclass(frozen=True)
class Shading:
    """A heightmap's heights drawn over its footprint: `heights` (rows, columns) in 0..1, row 0 at the
    +y edge, spanning `size` (x, y) centred on `center`, turned by `yaw`."""

    heights: FloatArray
    size: tuple[float, float]
    center: tuple[float, float]
    yaw: float


@dataclass(frozen=True)
class Footprint:
    """The top-down outline of one model: a polygon per shape (convex, except a polyline's own outline), in
    world x-y metres, and the shading of its upright heightmaps."""

    name: str
    polygons: tuple[FloatArray, ...]
    top: float
    """Highest z of the model (m)."""
    shading: tuple[Shading, ...] = ()

    @property
    def low(self) -> FloatArray:
        low: FloatArray = np.min([p.min(axis=0) for p in self.polygons], axis=0)
        return low

    @property
    def high(self) -> FloatArray:
        high: FloatArray = np.max([p.max(axis=0) for p in self.polygons], axis=0)
        return high

    @property
    def area(self) -> float:
        return float(sum(polygon_area(p) for p in self.polygons))

    @property
    def extent(self) -> float:
        return float(np.max(self.high - self.low))


def footprints(world: World) -> list[Footprint]:
    """The footprint of every model of `world`, in the world's order."""
    return [_footprint(model, world.source) for model in world.models]


@functools.lru_cache(maxsize=4096)
def _footprint(model: Model, source: str | None) -> Footprint:
    outlines: list[FloatArray] = []
    shading: list[Shading] = []
    top = -math.inf
    model_rotation, model_position = model.pose.rotation, model.pose.position
    for shape in model.shapes:
        rotation = model_rotation @ shape.pose.rotation
        position = model_position + model_rotation @ shape.pose.position
        outline, shape_top = _shape_outline(shape, source, rotation, position)
        outlines.append(outline)
        top = max(top, shape_top)
        if shape.kind == "heightmap" and rotation[2, 2] > 1.0 - 1e-9:
            shading.extend(_shading(shape, source, rotation, position))
    return Footprint(model.name, tuple(outlines), top, tuple(shading))


_SHADING_PIXELS = 200
"""Heightmaps are drawn with at most this many pixels a side."""


def _shading(shape: Shape, source: str | None, rotation: FloatArray, position: FloatArray) -> list[Shading]:
    assert shape.size is not None
    try:
        heights = load_heightmap(resolve_mesh_path(shape.mesh, source))
    except Exception:  # noqa: BLE001 - an unreadable image is drawn as its plain rectangle
        return []
    step = max(1, math.ceil(max(heights.shape) / _SHADING_PIXELS))
    yaw = math.atan2(rotation[1, 0], rotation[0, 0])
    return [Shading(heights[::step, ::step], (shape.size[0], shape.size[1]), (float(position[0]), float(position[1])),
                    yaw)]


def _shape_outline(shape: Shape, source: str | None, rotation: FloatArray,
                   position: FloatArray) -> tuple[FloatArray, float]:
    """The shape's outline on the ground plane (K, 2) and its highest z."""
    upright = abs(rotation[2, 2]) > 1.0 - 1e-9
    if shape.kind == "box" and upright:
        assert shape.size is not None
        half = np.array(shape.size, dtype=float) / 2.0
        corners = np.array([[-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], dtype=float) * half
        placed = position + corners @ rotation.T
        return placed[:, :2], float(position[2] + half[2])
    if shape.kind == "cylinder" and upright:
        assert shape.radius is not None and shape.length is not None
        return _circle(position[:2], shape.radius), float(position[2] + shape.length / 2.0)
    if shape.kind == "sphere":
        assert shape.radius is not None
        return _circle(position[:2], shape.radius), float(position[2] + shape.radius)
    if shape.kind == "capsule":  # a stadium: the hull of the circles around its projected end centres
        assert shape.radius is not None and shape.length is not None
        ends = position + np.outer([-0.5, 0.5], rotation[:, 2]) * shape.length
        circles = np.vstack([_circle(end[:2], shape.radius) for end in ends])
        return _convex_hull(circles), float(ends[:, 2].max() + shape.radius)
    placed = position + _shape_points(shape, source) @ rotation.T
    if shape.kind == "polyline" and upright:  # the outline itself, concave or not
        assert shape.points is not None
        count = len(shape.points)
        return placed[:count, :2], float(placed[:, 2].max())
    return _convex_hull(placed[:, :2]), float(placed[:, 2].max())


def _circle(center: FloatArray, radius: float, segments: int = 48) -> FloatArray:
    angles = np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False)
    return np.column_stack([center[0] + radius * np.cos(angles), center[1] + radius * np.sin(angles)])


def _shape_points(shape: Shape, source: str | None) -> FloatArray:
    """Points in the shape's frame whose convex hull is (or closely bounds) the shape."""
    if shape.kind == "box":
        assert shape.size is not None
        return geometry.box_corners(np.array(shape.size, dtype=float))
    if shape.kind == "cylinder":
        assert shape.radius is not None and shape.length is not None
        return geometry.cylinder_extent_points(shape.radius, shape.length, segments=48)
    if shape.kind == "sphere":
        assert shape.radius is not None
        return _sphere_points(shape.radius)
    if shape.kind == "cone":  # its base rim and tip
        assert shape.radius is not None and shape.length is not None
        rim = geometry.cylinder_extent_points(shape.radius, shape.length, segments=48)[48:]
        return np.vstack([rim, [[0.0, 0.0, shape.length / 2.0]]])
    if shape.kind == "polyline":  # the outline at z = 0, then at its height
        assert shape.points is not None and shape.height is not None
        outline = np.asarray(shape.points, dtype=np.float64)
        return np.vstack([np.column_stack([outline, np.zeros(len(outline))]),
                          np.column_stack([outline, np.full(len(outline), shape.height)])])
    if shape.kind == "heightmap":  # its rectangle, from z = 0 to its highest point
        assert shape.size is not None
        size_x, size_y, size_z = shape.size
        try:
            top = float(load_heightmap(resolve_mesh_path(shape.mesh, source)).max()) * size_z
        except Exception:  # noqa: BLE001 - an unreadable image is drawn as its full box
            top = size_z
        corners: FloatArray = geometry.box_corners(np.array([size_x, size_y, top])) + np.array([0.0, 0.0, top / 2.0])
        return corners
    try:
        mesh = load_mesh(resolve_mesh_path(shape.mesh, source), shape.scale)
        return np.asarray(mesh.vertices, dtype=np.float64)  # type: ignore[attr-defined]
    except Exception:  # noqa: BLE001 - an unreadable mesh still gets a visible marker
        return geometry.box_corners(np.full(3, 0.2))


def _sphere_points(radius: float, segments: int = 48) -> FloatArray:
    angles = np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False)
    ring = np.column_stack([radius * np.cos(angles), radius * np.sin(angles), np.zeros(segments)])
    return np.vstack([ring, [[0.0, 0.0, radius], [0.0, 0.0, -radius]]])


def _convex_hull(points: FloatArray) -> FloatArray:
    """Convex hull (K, 2) of planar points, counter-clockwise (Andrew's monotone chain)."""
    unique = np.unique(np.round(points, 9), axis=0)
    if len(unique) < 3:
        return _pad_degenerate(unique)

    def half(ordered: Iterable[FloatArray]) -> list[FloatArray]:
        chain: list[FloatArray] = []
        for point in ordered:
            while len(chain) >= 2 and _cross(chain[-2], chain[-1], point) <= 0:
                chain.pop()
            chain.append(point)
        return chain

    lower = half(unique)
    upper = half(unique[::-1])
    hull = np.array(lower[:-1] + upper[:-1])
    return hull if len(hull) >= 3 else _pad_degenerate(unique)


def _pad_degenerate(points: FloatArray) -> FloatArray:
    """A thin visible rectangle around points that have no area (a shape seen exactly edge-on)."""
    low, high = points.min(axis=0) - 0.01, points.max(axis=0) + 0.01
    return np.array([[low[0], low[1]], [high[0], low[1]], [high[0], high[1]], [low[0], high[1]]])


def _cross(o: FloatArray, a: FloatArray, b: FloatArray) -> float:
    return float((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]))


def polygon_area(polygon: FloatArray) -> float:
    """The area (m²) of a simple polygon (K, 2) (the shoelace formula)."""
    x, y = polygon[:, 0], polygon[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, 1)) - np.dot(y, np.roll(x, 1))))


# -- model classes -------------------------------------------------------------------------------------
def category(model: Model) -> Category:
    """'static' or 'dynamic' (a model that can be pushed)."""
    return "dynamic" if model.dynamic else "static"


def friction(model: Model) -> Friction:
    """'high' (mu > 5), 'low' (mu < 0.5) or None for ordinary friction."""
    if model.mu > HIGH_FRICTION:
        return "high"
    if model.mu < LOW_FRICTION:
        return "low"
    return None


def frictions_shown(world: World, prints: Sequence[Footprint]) -> dict[str, Friction]:
    """The friction class each model is drawn with: its own (`friction`), except terrain (wider than
    `TERRAIN_EXTENT`) when every terrain model has the same class: friction is then not what differs, and a
    high-friction ground would only colour the whole background."""
    terrain = {fp.name for fp in prints if fp.extent > TERRAIN_EXTENT}
    classes = {friction(model) for model in world.models if model.name in terrain}
    neutral = len(classes) == 1
    return {model.name: None if neutral and model.name in terrain else friction(model) for model in world.models}
