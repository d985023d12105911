"""Pictures of worlds, runs and reductions (matplotlib, headless).

Three pictures, all top-down and to scale in metres (see docs/pictures.md):

- `plot_world`: every model's footprint (the real outline of each shape projected on the ground), static,
  dynamic and unusual-friction models shown apart, the start and the goal, and one or more trajectories
  with the failure pose marked.
- `plot_reduction`: the original world with the removed models ghosted and the kept models highlighted and
  labelled, the original failing trajectory and the minimal world's failing trajectory.
- `plot_progress`: world size against the number of probes, accepted steps marked (the paper's Fig. 2).

`write_reduction_pictures` writes the last two into an artifacts folder. matplotlib is imported lazily with
the Agg backend, so importing this module is cheap and no display is ever needed.
"""

from __future__ import annotations

import functools
import json
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from pytest_ddenv import geometry
from pytest_ddenv.geometry import FloatArray
from pytest_ddenv.world import (
    Model,
    Shape,
    World,
    load_heightmap,
    load_mesh,
    resolve_mesh_path,
)

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from pytest_ddenv.artifacts import ArtifactPaths
    from pytest_ddenv.reduce import Reduction
    from pytest_ddenv.sim import Run
    from pytest_ddenv.stages import StagesOutcome

__all__ = [
    "DPI",
    "PROGRESS_SIZE",
    "WORLD_SIZE",
    "Footprint",
    "Shading",
    "category",
    "draw_progress",
    "draw_reduction",
    "draw_world",
    "footprints",
    "friction",
    "plot_progress",
    "plot_reduction",
    "plot_world",
    "probe_sizes_from_log",
    "robot_outline",
    "write_reduction_pictures",
]

DPI = 100
WORLD_SIZE = (1000, 800)
"""Pixel size (width, height) of world and reduction pictures."""
PROGRESS_SIZE = (900, 500)
"""Pixel size (width, height) of progress pictures."""

HIGH_FRICTION = 5.0
LOW_FRICTION = 0.5
ROBOT_FOOTPRINT = (0.99, 0.67)
"""Length and width (m) of the robot outline drawn at a failure pose when no run says how big the robot is
(a Husky); runs draw their own robot's `Run.footprint`."""
TERRAIN_EXTENT = 8.0
"""Models wider than this (m) are terrain: drawn, but they do not stretch the view."""
MAX_LABELS = 14

Category = Literal["static", "dynamic"]
Friction = Literal["high", "low"] | None

_FILL = {"static": "#b0b0b0", "dynamic": "#5b9bd5", "high": "#eb9486", "low": "#8fd3e8"}
_EDGE = "#404040"
_DYNAMIC_EDGE = "#1f4e96"
_HIGHLIGHT = "#ff8c00"
_RUN_COLORS = ("#d62728", "#7b2cbf", "#ff7f0e", "#2ca02c", "#8c564b", "#e377c2")
_OUTCOME_COLORS = {"fail": "#d62728", "other": "#ff7f0e", "pass": "#2ca02c", "error": "#000000"}


# -- footprints ----------------------------------------------------------------------------------------
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
        return float(sum(_polygon_area(p) for p in self.polygons))

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


def _polygon_area(polygon: FloatArray) -> float:
    x, y = polygon[:, 0], polygon[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, 1)) - np.dot(y, np.roll(x, 1))))


# -- model categories --------------------------------------------------------------------------------
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


# -- matplotlib plumbing -------------------------------------------------------------------------------
def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def _figure(size: tuple[int, int]) -> tuple[Figure, Axes]:
    plt = _pyplot()
    figure = plt.figure(figsize=(size[0] / DPI, size[1] / DPI), dpi=DPI)
    axes = figure.add_axes((0.07, 0.08, 0.62, 0.84))
    return figure, axes


def _save(figure: Figure, path: str | Path) -> Path:
    plt = _pyplot()
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    temporary = target.with_name(f".{target.name}.tmp.png")
    try:
        figure.savefig(temporary, dpi=DPI, format="png", metadata={"Software": "pytest-ddenv"})
        temporary.replace(target)
    finally:
        plt.close(figure)
        temporary.unlink(missing_ok=True)
    return target


# -- drawing -------------------------------------------------------------------------------------------
def _draw_models(axes: Axes, world: World, prints: Sequence[Footprint], *, ghosted: frozenset[str] = frozenset(),
                 highlighted: frozenset[str] = frozenset()) -> None:
    """Footprints, largest first so small models stay visible on top of slabs and terrain.

    Highlighted models get an orange halo under their outline; ghosted ones are faint and dashed.
    """
    from matplotlib.collections import PatchCollection
    from matplotlib.patches import Polygon

    order = sorted(range(len(prints)), key=lambda i: (-prints[i].area, prints[i].top))
    shown = frictions_shown(world, prints)
    for layer, index in enumerate(order):
        model, footprint = world.models[index], prints[index]
        ghost, strong = footprint.name in ghosted, footprint.name in highlighted
        terrain = footprint.extent > TERRAIN_EXTENT
        zorder = 1 + layer * 0.001 + (0.5 if strong else 0.0)
        if strong:
            axes.add_collection(PatchCollection([Polygon(_largest(footprint), closed=True)], facecolor="none",
                                                edgecolor=_HIGHLIGHT, linewidth=5.0, zorder=zorder - 0.0005))
        axes.add_collection(PatchCollection(
            [Polygon(polygon, closed=True) for polygon in footprint.polygons],
            facecolor=_fill(model, shown[model.name]),
            edgecolor="#9a9a9a" if ghost else _DYNAMIC_EDGE if model.dynamic and shown[model.name] else _EDGE,
            linewidth=0.7 if len(footprint.polygons) == 1 else 0.4,
            linestyle="--" if ghost else "-",
            alpha=0.15 if ghost else 0.45 if terrain else 0.9,
            zorder=zorder,
        ))
        for shading in footprint.shading:
            _draw_shading(axes, shading, alpha=0.1 if ghost else 0.5, zorder=zorder + 0.0002)


def _draw_shading(axes: Axes, shading: Shading, *, alpha: float, zorder: float) -> None:
    """A heightmap's heights in grey (black low, white high) over its rectangle."""
    from matplotlib.transforms import Affine2D

    half_x, half_y = shading.size[0] / 2.0, shading.size[1] / 2.0
    placement = Affine2D().rotate(shading.yaw).translate(*shading.center)
    axes.imshow(shading.heights, cmap="gray", vmin=0.0, vmax=1.0, origin="upper", interpolation="bilinear",
                extent=(-half_x, half_x, -half_y, half_y), alpha=alpha, zorder=zorder,
                transform=placement + axes.transData)


def _largest(footprint: Footprint) -> FloatArray:
    return max(footprint.polygons, key=_polygon_area)


def _fill(model: Model, shown: Friction) -> str:
    return _FILL[shown or category(model)]


def frictions_shown(world: World, prints: Sequence[Footprint]) -> dict[str, Friction]:
    """The friction class each model is drawn with: its own (`friction`), except terrain (wider than
    `TERRAIN_EXTENT`) when every terrain model has the same class: friction is then not what differs, and a
    high-friction ground would only colour the whole background."""
    terrain = {fp.name for fp in prints if fp.extent > TERRAIN_EXTENT}
    classes = {friction(model) for model in world.models if model.name in terrain}
    neutral = len(classes) == 1
    return {model.name: None if neutral and model.name in terrain else friction(model) for model in world.models}


def _draw_scenario(axes: Axes, world: World) -> None:
    scenario = world.scenario
    if scenario is None:
        return
    from matplotlib.patches import Circle

    start = scenario.start
    axes.plot([start.x], [start.y], marker=(3, 0, math.degrees(start.yaw) - 90.0), markersize=14,
              color="#2ca02c", markeredgecolor="black", linestyle="none", zorder=6, label="start")
    goal_x, goal_y, _ = scenario.goal
    axes.add_patch(Circle((goal_x, goal_y), scenario.goal_tolerance, fill=False, edgecolor="#b8860b",
                          linestyle=":", linewidth=1.2, zorder=5))
    axes.plot([goal_x], [goal_y], marker="*", markersize=18, color="#ffd700", markeredgecolor="black",
              linestyle="none", zorder=6, label="goal")


def _draw_run(axes: Axes, run: Run, color: str, label: str, *, underlay: bool = False,
              outcome: str | None = None) -> None:
    """A trajectory; an `underlay` is wide and translucent so a run drawn on top of it stays visible.
    `outcome` replaces the run's own outcome in the legend (the test's failure, when no predicate found it)."""
    positions = np.asarray(run.positions)
    if len(positions):
        axes.plot(positions[:, 0], positions[:, 1], color=color, linewidth=6.0 if underlay else 1.8,
                  alpha=0.35 if underlay else 1.0, solid_capstyle="round", zorder=6.5 if underlay else 7,
                  label=_wrap(f"{label}: {outcome or _run_outcome(run)}"))
    if run.failure is not None:
        _draw_failure_pose(axes, run.failure.pose, color, footprint=run.footprint, dashed=underlay)


def _wrap(text: str, width: int = 36) -> str:
    import textwrap

    return "\n".join(textwrap.wrap(text, width=width, subsequent_indent="  "))


def _models(count: int) -> str:
    return f"{count} model" if count == 1 else f"{count} models"


def robot_outline(pose: Sequence[float], footprint: tuple[float, float] = ROBOT_FOOTPRINT) -> FloatArray:
    """(4, 2): the corners of a robot's `footprint` (length, width in m) at `pose` (x, y, z, roll, pitch,
    yaw; x, y and yaw are used), front left first, counter-clockwise."""
    x, y, yaw = float(pose[0]), float(pose[1]), float(pose[5]) if len(pose) > 5 else 0.0
    length, width = (float(v) for v in footprint)
    corners = np.array([[length, width], [-length, width], [-length, -width], [length, -width]]) / 2.0
    rotation = np.array([[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]])
    outline: FloatArray = np.array([x, y]) + corners @ rotation.T
    return outline


def _draw_failure_pose(axes: Axes, pose: Sequence[float], color: str, *,
                       footprint: tuple[float, float] = ROBOT_FOOTPRINT, dashed: bool = False) -> None:
    """The robot's outline (its `footprint`) at the failure pose, a line to its front and a cross at its centre."""
    from matplotlib.patches import Polygon

    outline = robot_outline(pose, footprint)
    x, y = float(pose[0]), float(pose[1])
    axes.add_patch(Polygon(outline, closed=True, fill=False, edgecolor=color, linewidth=1.6, zorder=8,
                           linestyle="--" if dashed else "-"))
    nose = (outline[0] + outline[3]) / 2.0
    axes.plot([x, nose[0]], [y, nose[1]], color=color, linewidth=1.6, zorder=8)
    axes.plot([x], [y], marker="X", markersize=13, color=color, markeredgecolor="white", linestyle="none", zorder=9)


_POSE_LABELS = {"fail": "probe failed the same way", "other": "probe failed another way",
                "pass": "probe passed", "error": "probe errored"}


def _failure_legend_entries(axes: Axes, outcomes: Sequence[str]) -> None:
    """Invisible artists that give the legend one entry per outcome drawn (with its count)."""
    for outcome, color in _OUTCOME_COLORS.items():
        count = sum(1 for o in outcomes if o == outcome)
        if count:
            axes.plot([], [], marker="X", markersize=10, color=color, markeredgecolor="white", linestyle="none",
                      label=f"{_POSE_LABELS[outcome]} ({count})")


def _run_outcome(run: Run) -> str:
    if run.failure is not None:
        return f"{run.failure.predicate} at t\u00a0=\u00a0{run.failure.time:.1f}\u00a0s"
    if run.reached_goal:
        return "reached the goal" + (f" at t = {run.goal_time:.1f} s" if run.goal_time is not None else "")
    return f"no failure, goal not reached ({run.times[-1]:.1f} s)" if len(run.times) else "no failure"


def _view(axes: Axes, world: World, prints: Sequence[Footprint], points: Sequence[FloatArray]) -> None:
    """Limits that show the start, goal, trajectories and every model except huge terrain, equal aspect. A
    world of terrain only (a minimal world of two ground slabs) is framed on its scenario and runs, so a
    0.5 m gap between two 20 m slabs is not a hairline."""
    boxes: list[FloatArray] = [np.asarray(p, dtype=float).reshape(-1, 2) for p in points if len(p)]
    small = [fp for fp in prints if fp.extent <= TERRAIN_EXTENT]
    if small or (not boxes and world.scenario is None):  # terrain frames the view only if nothing else can
        boxes += [np.stack([fp.low, fp.high]) for fp in (small or prints)]
    if world.scenario is not None:
        goal = world.scenario.goal
        tolerance = world.scenario.goal_tolerance
        boxes.append(np.array([[goal[0] - tolerance, goal[1] - tolerance], [goal[0] + tolerance, goal[1] + tolerance]]))
        boxes.append(np.array([[world.scenario.start.x, world.scenario.start.y]]))
    if not boxes:
        boxes.append(np.array([[-1.0, -1.0], [1.0, 1.0]]))
    stacked = np.vstack(boxes)
    low, high = stacked.min(axis=0), stacked.max(axis=0)
    margin = max(0.5, 0.06 * float(np.max(high - low)))
    _fit_equal_aspect(axes, low - margin, high + margin)
    axes.set_xlabel("x (m)")
    axes.set_ylabel("y (m)")
    axes.grid(True, color="#dddddd", linewidth=0.6, zorder=0)
    axes.set_axisbelow(True)


def _fit_equal_aspect(axes: Axes, low: FloatArray, high: FloatArray) -> None:
    """Grow the shorter side of the view so one metre is as long on x as on y for the axes' box."""
    box = axes.get_window_extent()
    box_ratio = box.height / box.width
    center, span = (low + high) / 2.0, high - low
    if span[1] / span[0] < box_ratio:
        span[1] = span[0] * box_ratio
    else:
        span[0] = span[1] / box_ratio
    axes.set_xlim(center[0] - span[0] / 2.0, center[0] + span[0] / 2.0)
    axes.set_ylim(center[1] - span[1] / 2.0, center[1] + span[1] / 2.0)
    axes.set_aspect("equal", adjustable="box")


def _legend(axes: Axes, world: World, prints: Sequence[Footprint], *, ghosted: bool = False,
            highlighted: bool = False) -> None:
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    handles: list[Any] = list(axes.get_legend_handles_labels()[0])
    kinds = {category(m) for m in world.models}
    frictions = set(frictions_shown(world, prints).values())
    extents = [fp.extent for fp in prints]
    if highlighted:
        handles.append(Patch(facecolor="white", edgecolor=_HIGHLIGHT, linewidth=2.5,
                             label="kept (needed for the failure)"))
    if ghosted:
        handles.append(Patch(facecolor=_FILL["static"], edgecolor="#9a9a9a", alpha=0.25, linestyle="--",
                             label="removed by the reduction"))
    for kind, label in (("static", "static model"), ("dynamic", "dynamic model (movable)")):
        if kind in kinds:
            handles.append(Patch(facecolor=_FILL[kind], edgecolor=_EDGE, label=label))
    for level, label in (("high", f"high friction (μ > {HIGH_FRICTION:g})"),
                         ("low", f"low friction (μ < {LOW_FRICTION:g})")):
        if level in frictions:
            handles.append(Patch(facecolor=_FILL[level], edgecolor=_EDGE, label=label))
    if any(prints_extent > TERRAIN_EXTENT for prints_extent in extents):
        handles.append(Patch(facecolor=_FILL["static"], alpha=0.45, edgecolor=_EDGE,
                             label=f"terrain (wider than {TERRAIN_EXTENT:g} m, faded)"))
    if any(line.get_marker() == "X" for line in axes.get_lines()):
        handles.append(Line2D([], [], marker="X", color="#555555", linestyle="none", markersize=10,
                              label="failure pose (robot outline)"))
    axes.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0, fontsize=9,
                frameon=False)


def _title(world: World, text: str | None) -> str:
    name = world.name or (Path(world.source).stem if world.source else "world")
    return text if text is not None else f"{name}: {len(world)} models (top view)"


# -- labels --------------------------------------------------------------------------------------------
def _label_models(axes: Axes, figure: Figure, prints: Sequence[Footprint], names: Sequence[str]) -> None:
    """Name each model with a leader line, placing labels so none overlaps another, leaves the axes, or
    covers a small labelled model or a marker (start, goal, failure) when a free place exists."""
    by_name = {fp.name: fp for fp in prints}
    chosen = [name for name in names if name in by_name]
    shown, hidden = chosen[:MAX_LABELS], chosen[MAX_LABELS:]
    renderer = figure.canvas.get_renderer()  # type: ignore[attr-defined]
    frame = axes.get_window_extent(renderer)
    obstacles = _marker_boxes(axes) + [_display_box(axes, by_name[name]) for name in shown
                                       if by_name[name].extent <= TERRAIN_EXTENT / 4]
    placed: list[Any] = []
    for name in shown:
        anchor = _anchor(by_name[name], axes)
        text = f"{_short(name)}\ntop {by_name[name].top:.2f} m"
        placed.append(_place_label(axes, renderer, frame, placed, obstacles, text, anchor))
    if hidden:
        axes.text(0.99, 0.01, f"+{len(hidden)} more kept models (see summary.json)", transform=axes.transAxes,
                  ha="right", va="bottom", fontsize=8, color="#333333")


def _short(name: str, limit: int = 30) -> str:
    """A long model name with its middle elided (the full names are in summary.json)."""
    if len(name) <= limit:
        return name
    keep = (limit - 1) // 2
    return f"{name[:keep]}…{name[-keep:]}"


def _marker_boxes(axes: Axes) -> list[Any]:
    """Display boxes around the start, goal and failure markers, the goal's tolerance circle and the robot
    outlines at failure poses: what a label must not hide."""
    from matplotlib.patches import Circle, Polygon
    from matplotlib.transforms import Bbox

    boxes = []
    for line in axes.get_lines():
        if line.get_linestyle() not in ("None", "none", ""):
            continue
        for x, y in axes.transData.transform(np.column_stack(line.get_data()).astype(float)):
            boxes.append(Bbox.from_extents(x - 10, y - 10, x + 10, y + 10))
    for patch in axes.patches:
        if isinstance(patch, Circle) or (isinstance(patch, Polygon) and not patch.get_fill()):
            boxes.append(patch.get_window_extent())
    return boxes


def _display_box(axes: Axes, footprint: Footprint) -> Any:
    from matplotlib.transforms import Bbox

    corners = axes.transData.transform(np.stack([footprint.low, footprint.high]))
    return Bbox.from_extents(*corners.min(axis=0), *corners.max(axis=0))


def _anchor(footprint: Footprint, axes: Axes) -> tuple[float, float]:
    """A point of the model inside the view: its centre, or the centre of its visible part."""
    x0, x1 = axes.get_xlim()
    y0, y1 = axes.get_ylim()
    low = np.maximum(footprint.low, [x0, y0])
    high = np.minimum(footprint.high, [x1, y1])
    point = (low + high) / 2.0 if np.all(high > low) else (footprint.low + footprint.high) / 2.0
    return float(point[0]), float(point[1])


_DIRECTIONS = [(math.cos(a), math.sin(a)) for a in np.radians([45, 135, -45, -135, 90, -90, 0, 180,
                                                                      20, 160, -20, -160, 70, 110, -70, -110])]
_OFFSETS = [(round(dx * r, 1), round(dy * r, 1)) for r in (30, 50, 75, 105, 140, 180) for dx, dy in _DIRECTIONS]
_LABEL_PAD = 4.0
"""Pixels around a label's text taken by its rounded box."""


def _place_label(axes: Axes, renderer: Any, frame: Any, placed: list[Any], obstacles: Sequence[Any], text: str,
                 anchor: tuple[float, float]) -> Any:
    """Try offsets around the anchor, nearest first; take the first free one, else the least crowded.

    Returns the display box the label's text occupies.
    """
    from matplotlib.text import Text

    best: tuple[float, tuple[float, float], Any] | None = None
    for dx, dy in _OFFSETS:
        trial = axes.annotate(text, xy=anchor, xytext=(dx, dy), textcoords="offset points",
                              **_label_style(dx, dy))
        box = trial.get_window_extent(renderer).padded(_LABEL_PAD)  # no arrow yet: the text box only
        trial.remove()
        if not (frame.x0 <= box.x0 and box.x1 <= frame.x1 and frame.y0 <= box.y0 and box.y1 <= frame.y1):
            continue
        cost = 100.0 * sum(box.overlaps(other) for other in placed) + sum(box.overlaps(o) for o in obstacles)
        if best is None or cost < best[0]:
            best = (cost, (dx, dy), box)
        if cost == 0:
            break
    offset = best[1] if best is not None else _OFFSETS[0]
    label = axes.annotate(text, xy=anchor, xytext=offset, textcoords="offset points", **_label_style(*offset),
                          arrowprops={"arrowstyle": "-", "color": _EDGE, "linewidth": 0.8, "shrinkA": 0,
                                      "shrinkB": 0})
    return best[2] if best is not None else Text.get_window_extent(label, renderer).padded(_LABEL_PAD)


def _label_style(dx: float, dy: float) -> dict[str, Any]:
    return {
        "fontsize": 8.5,
        "zorder": 11,
        "ha": "left" if dx > 1e-6 else "right" if dx < -1e-6 else "center",
        "va": "bottom" if dy > 1e-6 else "top" if dy < -1e-6 else "center",
        "multialignment": "left",
        "bbox": {"boxstyle": "round,pad=0.2", "facecolor": "white", "edgecolor": _EDGE, "alpha": 0.9},
    }


# -- public pictures ----------------------------------------------------------------------------------
def plot_world(world: World, runs: Sequence[Run] = (), *, path: str | Path, title: str | None = None,
               failure_poses: Sequence[Sequence[float]] = (), failure_outcomes: Sequence[str] = (),
               robot_footprint: tuple[float, float] | None = None) -> Path:
    """Write a top-down picture of `world` with `runs` (trajectories, failure poses) to `path` (PNG).

    `failure_poses` marks extra failure poses (x, y, z, roll, pitch, yaw) without trajectories, e.g. from
    a probe log, drawn with the first run's robot footprint (a Husky's without runs); `failure_outcomes`
    (one per pose: "fail", "other", ...) colours them by outcome (same failure red, another failure orange)
    with a legend entry each. `robot_footprint` (length, width) outlines them when there is no run (the
    world's own robot; default a Husky's). Models the runs touched when they failed are labelled.
    """
    return _save(draw_world(world, runs, title=title, failure_poses=failure_poses,
                            failure_outcomes=failure_outcomes, robot_footprint=robot_footprint), path)


def draw_world(world: World, runs: Sequence[Run] = (), *, title: str | None = None,
               failure_poses: Sequence[Sequence[float]] = (), failure_outcomes: Sequence[str] = (),
               robot_footprint: tuple[float, float] | None = None) -> Figure:
    """The figure of `plot_world` (close it with `matplotlib.pyplot.close` when done)."""
    figure, axes = _figure(WORLD_SIZE)
    prints = footprints(world)
    _draw_models(axes, world, prints)
    _draw_scenario(axes, world)
    for index, run in enumerate(runs):
        _draw_run(axes, run, _RUN_COLORS[index % len(_RUN_COLORS)], f"seed {run.seed}")
    footprint = runs[0].footprint if runs else robot_footprint or ROBOT_FOOTPRINT  # the poses' robot
    outcomes = list(failure_outcomes) or ["fail"] * len(failure_poses)
    if len(outcomes) != len(failure_poses):
        raise ValueError(f"failure_outcomes has {len(outcomes)} entries for {len(failure_poses)} failure poses")
    for pose, outcome in zip(failure_poses, outcomes, strict=True):
        _draw_failure_pose(axes, pose, _OUTCOME_COLORS.get(outcome, _OUTCOME_COLORS["fail"]), footprint=footprint)
    if failure_outcomes:
        _failure_legend_entries(axes, outcomes)
    points = [np.asarray(run.positions)[:, :2] for run in runs] + [np.asarray(p)[:2] for p in failure_poses]
    _view(axes, world, prints, points)
    touched = [name for name in world.names if any(run.failure and name in run.failure.touched for run in runs)]
    axes.set_title(_title(world, title), fontsize=12)
    _legend(axes, world, prints)
    _label_models(axes, figure, prints, touched)
    return figure


def plot_reduction(world: World, minimal: Sequence[str], *, path: str | Path, original_run: Run | None = None,
                   minimal_run: Run | None = None, failure_pose: Sequence[float] | None = None,
                   title: str | None = None, failure_text: str | None = None) -> Path:
    """Write the original world with removed models ghosted and the `minimal` models highlighted and labelled.

    `original_run` (wide, translucent) and `minimal_run` (thin, on top) are drawn with their failure poses;
    without an original run, `failure_pose` (the reference failure's pose) is marked instead. Each failure pose
    is outlined with the robot's own `Run.footprint` (the minimal run's for `failure_pose`, else a Husky's).
    `failure_text` labels both runs with the test's own failure (e.g. "AssertionError at test_x.py:12") when
    it was not found by a predicate.
    """
    figure = draw_reduction(world, minimal, original_run=original_run, minimal_run=minimal_run,
                            failure_pose=failure_pose, title=title, failure_text=failure_text)
    return _save(figure, path)


def draw_reduction(world: World, minimal: Sequence[str], *, original_run: Run | None = None,
                   minimal_run: Run | None = None, failure_pose: Sequence[float] | None = None,
                   title: str | None = None, failure_text: str | None = None) -> Figure:
    """The figure of `plot_reduction` (close it with `matplotlib.pyplot.close` when done)."""
    kept = frozenset(minimal)
    removed = frozenset(world.names) - kept
    figure, axes = _figure(WORLD_SIZE)
    prints = footprints(world)
    _draw_models(axes, world, prints, ghosted=removed, highlighted=kept)
    _draw_scenario(axes, world)
    points: list[FloatArray] = []
    if original_run is not None:
        _draw_run(axes, original_run, _RUN_COLORS[0], f"original run ({_models(len(world))})", underlay=True,
                  outcome=failure_text)
        points.append(np.asarray(original_run.positions)[:, :2])
    elif failure_pose is not None:
        footprint = minimal_run.footprint if minimal_run is not None else ROBOT_FOOTPRINT
        _draw_failure_pose(axes, failure_pose, _RUN_COLORS[0], footprint=footprint)
        points.append(np.asarray(failure_pose, dtype=float)[:2])
    if minimal_run is not None:
        _draw_run(axes, minimal_run, _RUN_COLORS[1], f"minimal world run ({_models(len(kept))})",
                  outcome=failure_text)
        points.append(np.asarray(minimal_run.positions)[:, :2])
    _view(axes, world, prints, points)
    default = f"{_title(world, None).split(':')[0]}: {len(world)} → {_models(len(kept))}"
    axes.set_title(title or default, fontsize=12)
    _legend(axes, world, prints, ghosted=bool(removed), highlighted=True)
    _label_models(axes, figure, prints, [name for name in world.names if name in kept])
    return figure


def plot_progress(steps: Sequence[tuple[int, int]], *, path: str | Path, probes: int | None = None,
                  probe_sizes: Sequence[tuple[int, int, str]] = (), title: str | None = None,
                  note: str | None = None) -> Path:
    """Write world size against the number of probes (the paper's Fig. 2) to `path`.

    `steps`: (probes so far, size) at the start and after each accepted step (`Reduction.steps`);
    `probes`: total probes (extends the last step); `probe_sizes`: (probe number, candidate size, outcome)
    of every simulation, drawn as small dots coloured by outcome; `note`: text under the legend.
    """
    return _save(draw_progress(steps, probes=probes, probe_sizes=probe_sizes, title=title, note=note), path)


def draw_progress(steps: Sequence[tuple[int, int]], *, probes: int | None = None,
                  probe_sizes: Sequence[tuple[int, int, str]] = (), title: str | None = None,
                  note: str | None = None) -> Figure:
    """The figure of `plot_progress` (close it with `matplotlib.pyplot.close` when done)."""
    from matplotlib.lines import Line2D
    from matplotlib.ticker import MaxNLocator

    plt = _pyplot()
    figure: Figure = plt.figure(figsize=(PROGRESS_SIZE[0] / DPI, PROGRESS_SIZE[1] / DPI), dpi=DPI)
    axes = figure.add_axes((0.08, 0.12, 0.62, 0.78))
    steps = [(int(p), int(s)) for p, s in steps] or [(0, 0)]
    total = max(probes if probes is not None else 0, steps[-1][0], max((p for p, _, _ in probe_sizes), default=0))
    xs = [p for p, _ in steps] + [total]
    ys = [s for _, s in steps] + [steps[-1][1]]
    axes.step(xs, ys, where="post", color="#1f77b4", linewidth=2.2, zorder=3)
    handles: list[Any] = [Line2D([], [], color="#1f77b4", linewidth=2.2, label="current world size")]
    if len(steps) > 1:
        axes.plot([p for p, _ in steps[1:]], [s for _, s in steps[1:]], "o", color="#1f77b4",
                  markeredgecolor="black", markersize=7, zorder=4)
        handles.append(Line2D([], [], marker="o", color="#1f77b4", markeredgecolor="black", linestyle="none",
                              label="accepted step\n(a smaller world fails)"))
    handles += _probe_dots(axes, probe_sizes)
    axes.set_xlim(0, max(total, 1) * 1.03)
    axes.set_ylim(-0.5, max(ys + [s for _, s, _ in probe_sizes]) * 1.08 + 0.5)
    axes.xaxis.set_major_locator(MaxNLocator(integer=True))
    axes.yaxis.set_major_locator(MaxNLocator(integer=True))
    axes.set_xlabel("probes (simulations run)")
    axes.set_ylabel("world size (models)")
    axes.grid(True, color="#dddddd", linewidth=0.6)
    axes.set_axisbelow(True)
    axes.set_title(title or f"{steps[0][1]} → {_models(steps[-1][1])} in {total} probes", fontsize=12)
    axes.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0, fontsize=9,
                frameon=False)
    if note:
        axes.text(1.02, 0.0, note, transform=axes.transAxes, ha="left", va="bottom", fontsize=9)
    return figure


def _probe_dots(axes: Axes, probe_sizes: Sequence[tuple[int, int, str]]) -> list[Any]:
    from matplotlib.lines import Line2D

    handles: list[Any] = []
    labels = {"fail": "probe: same failure", "other": "probe: other failure", "pass": "probe: passed",
              "error": "probe: error"}
    for outcome, color in _OUTCOME_COLORS.items():
        chosen = [(p, s) for p, s, o in probe_sizes if o == outcome]
        if not chosen:
            continue
        axes.scatter([p for p, _ in chosen], [s for _, s in chosen], s=18, color=color, alpha=0.8, zorder=5,
                     linewidths=0)
        handles.append(Line2D([], [], marker="o", color=color, alpha=0.7, linestyle="none", markersize=5,
                              label=labels[outcome]))
    return handles


# -- artifacts ----------------------------------------------------------------------------------------
def write_reduction_pictures(world: World, reduction: Reduction, paths: ArtifactPaths, *,
                             original_run: Run | None = None, minimal_run: Run | None = None) -> list[Path]:
    """Write `paths.reduction_png` and `paths.progress_png`; return the paths written.

    Without `original_run`, the reference failure pose is read from `paths.summary` when it exists. The
    per-probe dots of the progress picture come from the run log `paths.log` when it exists.
    """
    failure_pose = None if original_run is not None else _reference_pose(paths.summary)
    failure_text = _reference_text(paths.summary)
    name = world.name or (Path(world.source).stem if world.source else "world")
    status = "1-minimal" if reduction.one_minimal else (reduction.incomplete_reason or "incomplete")
    reduction_title = (f"{name}: {reduction.original_size} → {_models(reduction.minimal_size)} "
                       f"({reduction.probes} probes, {status})")
    probe_sizes = probe_sizes_from_log(paths.log)
    steps = steps_from_log(paths.log) if probe_sizes else None
    written = [
        plot_reduction(world, reduction.minimal, path=paths.reduction_png, original_run=original_run,
                       minimal_run=minimal_run, failure_pose=failure_pose, title=reduction_title,
                       failure_text=failure_text),
        plot_progress(steps or reduction.steps, path=paths.progress_png,
                      probes=len(probe_sizes) if steps else reduction.probes, probe_sizes=probe_sizes,
                      title=f"{name}: world size during the reduction ({status})",
                      note=_progress_note(reduction)),
    ]
    return written


def write_stage_pictures(staged: StagesOutcome, paths: ArtifactPaths, *, minimal_run: Run | None = None) -> list[Path]:
    """`simplified.png` (the world the stages left: the kept shapes, simplified models and the shortened
    start, with the minimal world's failing run) and `passing.png` (the nearest passing world), when found."""
    written: list[Path] = []
    runs = () if minimal_run is None else (minimal_run,)
    if staged.changed and staged.final is not None:
        rate = "" if staged.final_rate is None else f", fails {staged.final_rate[0]}/{staged.final_rate[1]} fresh runs"
        written.append(plot_world(staged.final, runs, path=paths.directory / "simplified.png",
                                  title=f"after the stages: kept shapes, simpler values, start{rate}"))
    if staged.passing is not None:
        found = staged.result("passing")
        difference = "; ".join(found.details.get("difference", [])) if found is not None else ""
        written.append(plot_world(staged.passing, runs, path=paths.directory / "passing.png",
                                  title=_wrap(f"nearest passing world: {difference}", 60)))
    return written


def _progress_note(reduction: Reduction) -> str:
    fails, runs = reduction.failure_rate
    lines = [f"{reduction.probes} probes ({reduction.cache_hits} cached, {reduction.skipped} skipped)",
             f"{reduction.wall_time:.0f} s wall time"]
    if runs:
        lines.append(f"minimal world fails {fails}/{runs} seeds")
    return "\n".join(lines)


def _last_reduction(log: Path) -> list[dict[str, Any]]:
    """The model-level records of the last reduction in a run log (from its last ``start``)."""
    try:
        lines = log.read_text(encoding="utf-8").splitlines()
    except OSError:
        return []
    records: list[dict[str, Any]] = []
    for line in lines:
        try:
            record = json.loads(line)
        except ValueError:
            continue
        if isinstance(record, dict) and "stage" not in record:  # the stages after the models are not drawn here
            if record.get("event") == "start":
                records = []
            records.append(record)
    return records


def _is_reduction_probe(record: dict[str, Any]) -> bool:
    return record.get("event") == "probe" and record.get("purpose", "reduce") == "reduce"


def probe_sizes_from_log(log: Path) -> list[tuple[int, int, str]]:
    """(probe number, candidate size, outcome) of the reduction probes of the last reduction in a run log."""
    probes = [r for r in _last_reduction(log) if _is_reduction_probe(r)]
    return [(number, int(r.get("size", len(r.get("candidate", ())))), str(r.get("outcome", "")))
            for number, r in enumerate(probes, start=1)]


def steps_from_log(log: Path) -> list[tuple[int, int]]:
    """(probe number, size) of the start and of every adopted world (``step``, ``back-off``) of the last
    reduction in a run log, on the same probe numbering as `probe_sizes_from_log`: a step is drawn at the
    last probe logged before it, the one that justified it. Empty when the log has no start."""
    steps: list[tuple[int, int]] = []
    probes = 0
    for record in _last_reduction(log):
        if record.get("event") == "start":
            steps.append((0, len(record.get("elements", ())) + len(record.get("keep", ()))))
        elif _is_reduction_probe(record):
            probes += 1
        elif record.get("event") in ("step", "back-off") and isinstance(record.get("candidate"), list):
            steps.append((probes, len(record["candidate"])))
    return steps


def _reference_text(summary: Path) -> str | None:
    """The reduced failure in its own words when no predicate found it ("AssertionError at test_x.py:12")."""
    try:
        reference = json.loads(summary.read_text(encoding="utf-8"))["reference_failure"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    if not isinstance(reference, dict) or reference.get("signature") is not None:
        return None
    return f"{reference.get('exception_type', 'an exception')} at {reference.get('location', '?')}"


def _reference_pose(summary: Path) -> list[float] | None:
    try:
        data = json.loads(summary.read_text(encoding="utf-8"))
        pose = data["reference_failure"]["signature"]["pose"]
        return [float(v) for v in pose]
    except (OSError, ValueError, KeyError, TypeError):
        return None
