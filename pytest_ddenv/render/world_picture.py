"""The top-down pictures of a world: `plot_world` (a world with runs and failure poses) and `plot_reduction`
(the original world with the removed models ghosted and the kept ones highlighted, and both failing runs)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from pytest_ddenv.render.canvas import OUTCOME_COLORS, RUN_COLORS, WORLD_SIZE, models_text, new_figure, save
from pytest_ddenv.render.drawing import (
    ROBOT_FOOTPRINT,
    draw_failure_pose,
    draw_legend,
    draw_models,
    draw_run,
    draw_scenario,
    failure_legend_entries,
    fit_box,
    fit_view,
    title_of,
)
from pytest_ddenv.render.footprints import Footprint, footprints
from pytest_ddenv.render.labels import label_models
from pytest_ddenv.render.tabletop import (
    draw_arm_scenario,
    draw_gripper_failure,
    draw_target_path,
    in_view,
    is_arm_picture,
    table_view,
)
from pytest_ddenv.world.geometry import FloatArray
from pytest_ddenv.world.model import World

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from pytest_ddenv.sim import Run


def plot_world(world: World, runs: Sequence[Run] = (), *, path: str | Path, title: str | None = None,
               failure_poses: Sequence[Sequence[float]] = (), failure_outcomes: Sequence[str] = (),
               robot_footprint: tuple[float, float] | None = None, run_colors: Sequence[str] = ()) -> Path:
    """Write a top-down picture of `world` with `runs` (trajectories, failure poses) to `path` (PNG).

    `failure_poses` marks extra failure poses (x, y, z, roll, pitch, yaw) without trajectories, e.g. from
    a probe log, drawn with the first run's robot footprint (a Husky's without runs); `failure_outcomes`
    (one per pose: "fail", "other", ...) colours them by outcome (same failure red, another failure orange)
    with a legend entry each. `robot_footprint` (length, width) outlines them when there is no run (the
    world's own robot; default a Husky's). `run_colors`: the runs' colours (default: red, purple, ...).
    Models the runs touched when they failed are labelled.
    """
    return save(draw_world(world, runs, title=title, failure_poses=failure_poses,
                           failure_outcomes=failure_outcomes, robot_footprint=robot_footprint,
                           run_colors=run_colors), path)


def draw_world(world: World, runs: Sequence[Run] = (), *, title: str | None = None,
               failure_poses: Sequence[Sequence[float]] = (), failure_outcomes: Sequence[str] = (),
               robot_footprint: tuple[float, float] | None = None, run_colors: Sequence[str] = ()) -> Figure:
    """The figure of `plot_world` (close it with `matplotlib.pyplot.close` when done). An arm's world
    (`tabletop.is_arm_picture`) is shown zoomed to its table, with the arm's base, the place region, the end
    effector's and the target's paths."""
    arm = is_arm_picture(world, runs)
    figure, axes = new_figure(WORLD_SIZE)
    prints = footprints(world)
    draw_models(axes, world, prints)
    (draw_arm_scenario if arm else draw_scenario)(axes, world)
    colors = tuple(run_colors) or RUN_COLORS
    points: list[FloatArray] = []
    for index, run in enumerate(runs):
        draw_run(axes, run, colors[index % len(colors)], f"seed {run.seed}" + (": end effector" if arm else ""))
        if arm:
            points.append(draw_target_path(axes, run, f"seed {run.seed}: target"))
    footprint = runs[0].footprint if runs else robot_footprint or ROBOT_FOOTPRINT  # the poses' robot
    outcomes = list(failure_outcomes) or ["fail"] * len(failure_poses)
    if len(outcomes) != len(failure_poses):
        raise ValueError(f"failure_outcomes has {len(outcomes)} entries for {len(failure_poses)} failure poses")
    for pose, outcome in zip(failure_poses, outcomes, strict=True):
        color = OUTCOME_COLORS.get(outcome, OUTCOME_COLORS["fail"])
        if arm:
            draw_gripper_failure(axes, pose, color)
        else:
            draw_failure_pose(axes, pose, color, footprint=footprint)
    if failure_outcomes:
        failure_legend_entries(axes, outcomes)
    points += [np.asarray(run.positions)[:, :2] for run in runs] + [np.asarray(p)[:2] for p in failure_poses]
    shown = _fit(axes, world, prints, points, arm)
    touched = [name for name in shown if any(run.failure and name in run.failure.touched for run in runs)]
    axes.set_title(title_of(world, title), fontsize=12)
    draw_legend(axes, world, prints, arm=arm)
    label_models(axes, figure, prints, touched)
    return figure


def _fit(axes: Axes, world: World, prints: Sequence[Footprint], points: Sequence[FloatArray], arm: bool
         ) -> list[str]:
    """Set the view (an arm's: zoomed to its table) and return the names of the models in it."""
    if not arm:
        fit_view(axes, world, prints, points)
        return list(world.names)
    low, high = table_view(world, prints, points)
    fit_box(axes, low, high)
    return [fp.name for fp in prints if in_view(fp, low, high)]


def plot_reduction(world: World, minimal: Sequence[str], *, path: str | Path, original_run: Run | None = None,
                   minimal_run: Run | None = None, failure_pose: Sequence[float] | None = None,
                   title: str | None = None, failure_text: str | None = None,
                   precondition_kept: Sequence[str] = ()) -> Path:
    """Write the original world with removed models ghosted and the `minimal` models highlighted and labelled.

    Models of `minimal` in `precondition_kept` (kept by a precondition, such as the one under the robot's
    start, not shown needed for the failure) get a style of their own, with its own legend entry.

    `original_run` (wide, translucent) and `minimal_run` (thin, on top) are drawn with their failure poses;
    without an original run, `failure_pose` (the reference failure's pose) is marked instead. Each failure pose
    is outlined with the robot's own `Run.footprint` (the minimal run's for `failure_pose`, else a Husky's).
    `failure_text` labels both runs with the test's own failure (e.g. "AssertionError at test_x.py:12") when
    it was not found by a predicate.
    """
    figure = draw_reduction(world, minimal, original_run=original_run, minimal_run=minimal_run,
                            failure_pose=failure_pose, title=title, failure_text=failure_text,
                            precondition_kept=precondition_kept)
    return save(figure, path)


def draw_reduction(world: World, minimal: Sequence[str], *, original_run: Run | None = None,
                   minimal_run: Run | None = None, failure_pose: Sequence[float] | None = None,
                   title: str | None = None, failure_text: str | None = None,
                   precondition_kept: Sequence[str] = ()) -> Figure:
    """The figure of `plot_reduction` (close it with `matplotlib.pyplot.close` when done)."""
    kept = frozenset(minimal)
    preconditioned = kept & frozenset(precondition_kept)
    removed = frozenset(world.names) - kept
    arm = is_arm_picture(world, (original_run, minimal_run))
    figure, axes = new_figure(WORLD_SIZE)
    prints = footprints(world)
    draw_models(axes, world, prints, ghosted=removed, highlighted=kept - preconditioned, preconditioned=preconditioned)
    (draw_arm_scenario if arm else draw_scenario)(axes, world)
    points: list[FloatArray] = []
    path = ", end effector" if arm else ""
    if original_run is not None:
        draw_run(axes, original_run, RUN_COLORS[0], f"original run{path} ({models_text(len(world))})",
                 underlay=True, outcome=failure_text)
        points.append(np.asarray(original_run.positions)[:, :2])
        if arm:
            points.append(draw_target_path(axes, original_run, "target in the original run", underlay=True))
    elif failure_pose is not None:
        if arm:
            draw_gripper_failure(axes, failure_pose, RUN_COLORS[0])
        else:
            footprint = minimal_run.footprint if minimal_run is not None else ROBOT_FOOTPRINT
            draw_failure_pose(axes, failure_pose, RUN_COLORS[0], footprint=footprint)
        points.append(np.asarray(failure_pose, dtype=float)[:2])
    if minimal_run is not None:
        draw_run(axes, minimal_run, RUN_COLORS[1], f"minimal world run{path} ({models_text(len(kept))})",
                 outcome=failure_text)
        points.append(np.asarray(minimal_run.positions)[:, :2])
        if arm:
            points.append(draw_target_path(axes, minimal_run, "target in the minimal world run"))
    shown = _fit(axes, world, prints, points, arm)
    default = f"{title_of(world, None).split(':')[0]}: {len(world)} → {models_text(len(kept))}"
    axes.set_title(title or default, fontsize=12)
    draw_legend(axes, world, prints, ghosted=bool(removed), highlighted=bool(kept - preconditioned),
                preconditioned=bool(preconditioned), arm=arm)
    label_models(axes, figure, prints, [name for name in shown if name in kept])
    return figure
