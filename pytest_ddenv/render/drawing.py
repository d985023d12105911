"""Drawing the parts of a top-down picture on matplotlib axes: models, start and goal, runs, failure poses, the
legend and the view."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from pytest_ddenv.render.canvas import DYNAMIC_EDGE, EDGE, FILL, HIGHLIGHT, OUTCOME_COLORS, PRECONDITION, wrap
from pytest_ddenv.render.footprints import (
    HIGH_FRICTION,
    LOW_FRICTION,
    TERRAIN_EXTENT,
    Footprint,
    Friction,
    Shading,
    category,
    frictions_shown,
    polygon_area,
)
from pytest_ddenv.world.geometry import FloatArray
from pytest_ddenv.world.model import Model, World

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes

    from pytest_ddenv.sim import Run

ROBOT_FOOTPRINT = (0.99, 0.67)
"""Length and width (m) of the robot outline drawn at a failure pose when no run says how big the robot is
(a Husky); runs draw their own robot's `Run.footprint`."""


# -- models --------------------------------------------------------------------------------------------
def draw_models(axes: Axes, world: World, prints: Sequence[Footprint], *, ghosted: frozenset[str] = frozenset(),
                highlighted: frozenset[str] = frozenset(), preconditioned: frozenset[str] = frozenset()) -> None:
    """Footprints, largest first so small models stay visible on top of slabs and terrain.

    Highlighted models get an orange halo under their outline, `preconditioned` ones (kept by a precondition,
    not shown needed) a dashed magenta one (their gids: "needed:NAME", "precondition:NAME"); ghosted ones are
    faint and dashed.
    """
    from matplotlib.collections import PatchCollection
    from matplotlib.patches import Polygon

    order = sorted(range(len(prints)), key=lambda i: (-prints[i].area, prints[i].top))
    shown = frictions_shown(world, prints)
    for layer, index in enumerate(order):
        model, footprint = world.models[index], prints[index]
        ghost, strong = footprint.name in ghosted, footprint.name in highlighted | preconditioned
        terrain = footprint.extent > TERRAIN_EXTENT
        zorder = 1 + layer * 0.001 + (0.5 if strong else 0.0)
        if strong:
            needed = footprint.name not in preconditioned
            halo = PatchCollection([Polygon(_largest(footprint), closed=True)], facecolor="none",
                                   edgecolor=HIGHLIGHT if needed else PRECONDITION, linewidth=5.0 if needed else 3.5,
                                   linestyle="-" if needed else "--", zorder=zorder - 0.0005)
            halo.set_gid(f"{'needed' if needed else 'precondition'}:{footprint.name}")
            axes.add_collection(halo)
        axes.add_collection(PatchCollection(
            [Polygon(polygon, closed=True) for polygon in footprint.polygons],
            facecolor=_fill(model, shown[model.name]),
            edgecolor="#9a9a9a" if ghost else DYNAMIC_EDGE if model.dynamic and shown[model.name] else EDGE,
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
    return max(footprint.polygons, key=polygon_area)


def _fill(model: Model, shown: Friction) -> str:
    return FILL[shown or category(model)]


# -- start, goal, runs and failure poses ---------------------------------------------------------------
def draw_scenario(axes: Axes, world: World) -> None:
    """The start (a triangle pointing where the robot faces) and the goal with its tolerance circle."""
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


def draw_run(axes: Axes, run: Run, color: str, label: str, *, underlay: bool = False,
             outcome: str | None = None) -> None:
    """A trajectory; an `underlay` is wide and translucent so a run drawn on top of it stays visible.
    `outcome` replaces the run's own outcome in the legend (the test's failure, when no predicate found it).
    An arm's run is its end effector's path, its failure pose a point (`tabletop.draw_gripper_failure`)."""
    positions = np.asarray(run.positions)
    if len(positions):
        axes.plot(positions[:, 0], positions[:, 1], color=color, linewidth=6.0 if underlay else 1.8,
                  alpha=0.35 if underlay else 1.0, solid_capstyle="round", zorder=6.5 if underlay else 7,
                  label=wrap(f"{label}: {outcome or _run_outcome(run)}"))
    if run.failure is not None and run.robot_kind == "arm":
        from pytest_ddenv.render.tabletop import draw_gripper_failure

        draw_gripper_failure(axes, run.failure.pose, color, dashed=underlay)
    elif run.failure is not None:
        draw_failure_pose(axes, run.failure.pose, color, footprint=run.footprint, dashed=underlay)


def robot_outline(pose: Sequence[float], footprint: tuple[float, float] = ROBOT_FOOTPRINT) -> FloatArray:
    """(4, 2): the corners of a robot's `footprint` (length, width in m) at `pose` (x, y, z, roll, pitch,
    yaw; x, y and yaw are used), front left first, counter-clockwise."""
    x, y, yaw = float(pose[0]), float(pose[1]), float(pose[5]) if len(pose) > 5 else 0.0
    length, width = (float(v) for v in footprint)
    corners = np.array([[length, width], [-length, width], [-length, -width], [length, -width]]) / 2.0
    rotation = np.array([[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]])
    outline: FloatArray = np.array([x, y]) + corners @ rotation.T
    return outline


def draw_failure_pose(axes: Axes, pose: Sequence[float], color: str, *,
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


def failure_legend_entries(axes: Axes, outcomes: Sequence[str]) -> None:
    """Invisible artists that give the legend one entry per outcome drawn (with its count)."""
    for outcome, color in OUTCOME_COLORS.items():
        count = sum(1 for o in outcomes if o == outcome)
        if count:
            axes.plot([], [], marker="X", markersize=10, color=color, markeredgecolor="white", linestyle="none",
                      label=f"{_POSE_LABELS[outcome]} ({count})")


def _run_outcome(run: Run) -> str:
    if run.failure is not None:
        return f"{run.failure.predicate} at t\u00a0=\u00a0{run.failure.time:.1f}\u00a0s"
    if run.reached_goal:
        done = "placed the target" if run.robot_kind == "arm" else "reached the goal"
        return done + (f" at t = {run.goal_time:.1f} s" if run.goal_time is not None else "")
    return f"no failure, goal not reached ({run.times[-1]:.1f} s)" if len(run.times) else "no failure"


# -- view and legend ---------------------------------------------------------------------------------
def fit_view(axes: Axes, world: World, prints: Sequence[Footprint], points: Sequence[FloatArray]) -> None:
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
    fit_box(axes, low - margin, high + margin)


def fit_box(axes: Axes, low: FloatArray, high: FloatArray) -> None:
    """Limits that show the box from `low` to `high` (x, y) at equal aspect, the axes labelled, a grid."""
    _fit_equal_aspect(axes, np.asarray(low, dtype=float), np.asarray(high, dtype=float))
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


def draw_legend(axes: Axes, world: World, prints: Sequence[Footprint], *, ghosted: bool = False,
                highlighted: bool = False, preconditioned: bool = False, arm: bool = False) -> None:
    """The legend, right of the axes: the runs and markers drawn, then one entry per kind of model shown
    (`arm`: the failure marks the end effector, not a robot's outline)."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    handles: list[Any] = list(axes.get_legend_handles_labels()[0])
    kinds = {category(m) for m in world.models}
    frictions = set(frictions_shown(world, prints).values())
    extents = [fp.extent for fp in prints]
    if highlighted:
        handles.append(Patch(facecolor="white", edgecolor=HIGHLIGHT, linewidth=2.5,
                             label="kept (needed for the failure)"))
    if preconditioned:
        handles.append(Patch(facecolor="white", edgecolor=PRECONDITION, linewidth=2.0, linestyle="--",
                             label=wrap("kept by a precondition (not shown needed for the failure)")))
    if ghosted:
        handles.append(Patch(facecolor=FILL["static"], edgecolor="#9a9a9a", alpha=0.25, linestyle="--",
                             label="removed by the reduction"))
    for kind, label in (("static", "static model"), ("dynamic", "dynamic model (movable)")):
        if kind in kinds:
            handles.append(Patch(facecolor=FILL[kind], edgecolor=EDGE, label=label))
    for level, label in (("high", f"high friction (μ > {HIGH_FRICTION:g})"),
                         ("low", f"low friction (μ < {LOW_FRICTION:g})")):
        if level in frictions:
            handles.append(Patch(facecolor=FILL[level], edgecolor=EDGE, label=label))
    if any(prints_extent > TERRAIN_EXTENT for prints_extent in extents):
        handles.append(Patch(facecolor=FILL["static"], alpha=0.45, edgecolor=EDGE,
                             label=f"terrain (wider than {TERRAIN_EXTENT:g} m, faded)"))
    if any(line.get_marker() == "X" for line in axes.get_lines()):
        handles.append(Line2D([], [], marker="X", color="#555555", linestyle="none", markersize=10,
                              label="failure point (end effector)" if arm else "failure pose (robot outline)"))
    axes.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0, fontsize=9,
                frameon=False)


def title_of(world: World, text: str | None) -> str:
    """`text`, else the default title of a picture of `world`."""
    name = world.name or (Path(world.source).stem if world.source else "world")
    return text if text is not None else f"{name}: {len(world)} models (top view)"
