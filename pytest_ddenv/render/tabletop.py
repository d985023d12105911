"""The parts of a top-down picture that differ for an arm on a table: the view zoomed to the table, the arm's
base, the place region, the target's path and the end effector's failure point.

An arm's run records the end effector's pose in `Run.poses` (its path is drawn as a mobile robot's
trajectory) and the target's path in `Run.target_path`; the arm's base stays at the scenario's start.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from pytest_ddenv.render.footprints import Footprint
from pytest_ddenv.world.geometry import FloatArray
from pytest_ddenv.world.model import World

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes

    from pytest_ddenv.sim import Run

ARM_BASE_RADIUS = 0.11
"""Radius (m) of the circle drawn at an arm's base (a Franka Panda's link 0 is about 0.22 m across)."""
ARM_REACH = 1.0
"""Without a table, an arm picture shows the models within this distance (m) of the arm's base."""
TABLE_MARGIN = 0.08
"""Metres of view around the table, the arm's base, the place region and the paths."""
TARGET_PATH_COLOR = "#1f77b4"


def is_arm_picture(world: World, runs: Sequence[Run | None] = ()) -> bool:
    """Whether `world` (or one of `runs`) is an arm's: a run recorded as an arm's, a scenario with a table or
    a target (only arms have them), or a scenario whose robot is an arm (`sim.arm.robot.robot_kind`; a robot
    that cannot be made here is taken for a mobile one)."""
    if any(run is not None and run.robot_kind == "arm" for run in runs):
        return True
    scenario = world.scenario
    if scenario is None:
        return False
    if scenario.table is not None or scenario.target is not None:
        return True
    from pytest_ddenv.sim.arm.robot import robot_kind

    try:
        return robot_kind(scenario.robot, world.source) == "arm"
    except Exception:  # noqa: BLE001 - a robot of the user's that cannot be made here: drawn as a mobile robot
        return False


def table_view(world: World, prints: Sequence[Footprint], points: Sequence[FloatArray]
               ) -> tuple[FloatArray, FloatArray]:
    """(low, high) x-y corners of an arm picture's view: the table's footprint (without a table, the models
    within `ARM_REACH` of the arm's base), the arm's base, the place region and `points` (the paths and
    failure points), with a margin; models elsewhere in the world are left out of the view."""
    boxes: list[FloatArray] = [np.asarray(p, dtype=float).reshape(-1, 2) for p in points if len(p)]
    scenario = world.scenario
    by_name = {fp.name: fp for fp in prints}
    if scenario is not None:
        base = np.array([scenario.start.x, scenario.start.y])
        boxes.append(np.stack([base - ARM_BASE_RADIUS, base + ARM_BASE_RADIUS]))
        goal, tolerance = np.asarray(scenario.goal[:2], dtype=float), scenario.goal_tolerance
        boxes.append(np.stack([goal - tolerance, goal + tolerance]))
        table = by_name.get(scenario.table) if scenario.table is not None else None
        if table is not None:
            boxes.append(np.stack([table.low, table.high]))
        else:
            boxes += [np.stack([fp.low, fp.high]) for fp in prints
                      if float(np.linalg.norm((fp.low + fp.high) / 2.0 - base)) <= ARM_REACH]
    if not boxes:
        boxes.append(np.array([[-0.5, -0.5], [0.5, 0.5]]))
    stacked = np.vstack(boxes)
    low, high = stacked.min(axis=0) - TABLE_MARGIN, stacked.max(axis=0) + TABLE_MARGIN
    return low, high


def in_view(footprint: Footprint, low: FloatArray, high: FloatArray) -> bool:
    """Whether any of `footprint` lies inside the view from `low` to `high`."""
    return bool(np.all(footprint.high >= low) and np.all(footprint.low <= high))


def draw_arm_scenario(axes: Axes, world: World) -> None:
    """The arm's base (a circle at the scenario's start, a tick where it faces) and the place region (the
    goal's centre and its tolerance circle)."""
    scenario = world.scenario
    if scenario is None:
        return
    from matplotlib.patches import Circle

    start = scenario.start
    axes.add_patch(Circle((start.x, start.y), ARM_BASE_RADIUS, facecolor="#f2c01a", edgecolor="black",
                          linewidth=1.2, zorder=6))
    axes.plot([start.x, start.x + ARM_BASE_RADIUS * np.cos(start.yaw)],
              [start.y, start.y + ARM_BASE_RADIUS * np.sin(start.yaw)], color="black", linewidth=1.2, zorder=6.1)
    axes.plot([start.x], [start.y], marker="o", markersize=5, color="black", linestyle="none", zorder=6.2,
              label="arm base")
    goal_x, goal_y, _ = scenario.goal
    axes.add_patch(Circle((goal_x, goal_y), scenario.goal_tolerance, facecolor="#ffd70033", edgecolor="#b8860b",
                          linestyle="--", linewidth=1.4, zorder=5))
    axes.plot([goal_x], [goal_y], marker="*", markersize=14, color="#ffd700", markeredgecolor="black",
              linestyle="none", zorder=6, label="place region")


def draw_target_path(axes: Axes, run: Run, label: str, *, underlay: bool = False) -> FloatArray:
    """The target's recorded path (dashed; an `underlay` wide and faint) and a square where it ended; returns
    its x-y points (none when the run recorded no target)."""
    path = run.target_path
    if path is None or not len(path):
        return np.zeros((0, 2))
    points = np.asarray(path, dtype=float)[:, :2]
    axes.plot(points[:, 0], points[:, 1], color=TARGET_PATH_COLOR, linestyle="--", linewidth=4.0 if underlay else 1.5,
              alpha=0.35 if underlay else 1.0, zorder=6.4 if underlay else 6.9, label=label)
    axes.plot(points[-1:, 0], points[-1:, 1], marker="s", markersize=7, color=TARGET_PATH_COLOR,
              markeredgecolor="white", linestyle="none", zorder=7)
    return points


def draw_gripper_failure(axes: Axes, pose: Sequence[float], color: str, *, dashed: bool = False) -> None:
    """The end effector at the failure: a cross in a ring 10 cm across."""
    from matplotlib.patches import Circle

    x, y = float(pose[0]), float(pose[1])
    axes.add_patch(Circle((x, y), 0.05, fill=False, edgecolor=color, linewidth=1.6, zorder=8,
                          linestyle="--" if dashed else "-"))
    axes.plot([x], [y], marker="X", markersize=13, color=color, markeredgecolor="white", linestyle="none", zorder=9)
