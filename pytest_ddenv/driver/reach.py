"""The first cut by reach: the static models nothing in the original run could have touched or sensed.

A static model never moves, so it changes a run only through something that reaches it: a part of the robot,
a laser ray, or a dynamic model. The original run (attempt 0) is the reference: in a world without the models
that none of these reached, the same run follows the same trajectory until something differs, and nothing
can differ before a removed model is reached. So the models farther than the robot's reach from every pose
of the original run (the run stops at its failure, or at the goal or the time limit) cannot change it:

- the robot: its footprint's full diagonal (a half diagonal plus as much again for its height), plus
  `DRIFT` for the other attempts' noise, plus half the largest gap between two recorded poses;
- the laser: `laser_range` more when the run has laser rays;
- a dynamic model: it may be pushed or fall, so every dynamic model is kept, and so is every static model
  within its possible travel: (sqrt(2 g h) + 2 x the robot's top speed) x the run's duration, h the height of
  the highest dynamic model's top above the ground (what it can gain by falling), plus its own size.

Distances are measured to each model's axis-aligned bounds (never more than to its shapes: a model kept by
mistake costs a little, one dropped by mistake is never the case). The cut is a candidate like any other:
the engine tries it in one probe, judged by the deflake rule (`reduce/engine.py`); when it does not
reproduce the failure the reduction goes on from the whole world.

Skipped (with the reason) for an arm, a run of a simulator of the user's own, no run at all or one with no
trajectory, or a world whose geometry cannot be measured.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from pytest_ddenv.errors import DdenvError
from pytest_ddenv.scenario.reported import REPORTED

if TYPE_CHECKING:
    from pytest_ddenv.sim import Run
    from pytest_ddenv.world.model import World

DRIFT = 1.0
"""Metres added to the robot's reach for the other attempts, whose noise moves them off attempt 0's path."""
CHUNK = 2048
"""Models measured at once (the (poses x models x 3) array stays small)."""


@dataclass(frozen=True)
class ReachCut:
    """The first cut of a world: `kept` the models within reach (original order: every dynamic model, every
    model within reach of the robot, its laser or a dynamic model), `dropped` the others; `reason` why the
    cut was not made (then `kept` is the whole world and `dropped` is empty)."""

    kept: tuple[str, ...]
    dropped: tuple[str, ...]
    robot_reach: float = 0.0
    """Metres from the robot's recorded poses within which static models are kept."""
    reason: str = ""

    @property
    def made(self) -> bool:
        return not self.reason and bool(self.dropped)


def reach_cut(world: World, run: Run | None) -> ReachCut:
    """The models of `world` within reach of its original run `run` (see the module's text)."""
    whole = world.names
    if run is None:
        return ReachCut(whole, (), reason="no run of the original world to bound the reach by")
    if run.robot_kind != "mobile":
        return ReachCut(whole, (), reason=f"the robot is {'an arm' if run.robot_kind == 'arm' else run.robot_kind}: "
                        "only a wheeled robot's reach is bounded")
    if run.engine == REPORTED:
        return ReachCut(whole, (), reason="the test ran a simulator of its own: its reach is unknown")
    points = np.asarray(run.positions, dtype=np.float64)
    if points.ndim != 2 or len(points) == 0 or not np.isfinite(points).all():
        return ReachCut(whole, (), reason="the original run recorded no trajectory")
    try:
        bounds = np.stack([world.bounds(name) for name in whole]) if whole else np.zeros((0, 2, 3))
    except (DdenvError, OSError, ValueError) as error:
        return ReachCut(whole, (), reason=f"the world's geometry cannot be measured ({error})")
    return _cut(world, run, points, bounds)


def _cut(world: World, run: Run, points: np.ndarray, bounds: np.ndarray) -> ReachCut:
    settings = run.settings
    length, width = (float(value) for value in run.footprint)
    gaps = np.linalg.norm(np.diff(points, axis=0), axis=1) if len(points) > 1 else np.zeros(1)
    robot = math.hypot(length, width) + DRIFT + float(gaps.max()) / 2
    reach = robot + (float(settings.laser_range) if settings.laser_rays > 0 else 0.0)
    near = _distances(points, bounds) <= reach
    dynamic = np.array([model.dynamic for model in world.models], dtype=bool)
    if dynamic.any():
        near |= dynamic | _near_dynamic(world, run, bounds, dynamic)
    kept = tuple(name for name, keep in zip(world.names, near, strict=True) if keep)
    dropped = tuple(name for name, keep in zip(world.names, near, strict=True) if not keep)
    return ReachCut(kept, dropped, robot_reach=reach)


def _near_dynamic(world: World, run: Run, bounds: np.ndarray, dynamic: np.ndarray) -> np.ndarray:
    """Static models within the possible travel of some dynamic model (its bounds grown by the travel)."""
    ground = world.ground.z if world.ground is not None else float(bounds[:, 0, 2].min())
    height = max(0.0, float(bounds[dynamic, 1, 2].max()) - ground)
    speeds = np.linalg.norm(np.asarray(run.velocities, dtype=np.float64)[:, :2], axis=1)
    robot_speed = max(float(run.settings.max_speed), float(speeds.max()) if len(speeds) else 0.0)
    travel = (math.sqrt(2 * 9.81 * height) + 2 * robot_speed) * float(run.sim_time)
    near = np.zeros(len(bounds), dtype=bool)
    for low, high in bounds[dynamic]:
        size = float(np.linalg.norm(high - low))
        near |= _box_gaps(low, high, bounds) <= travel + size
    return near


def _distances(points: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """(models,) the least distance from any point to each model's axis-aligned bounds (0 inside)."""
    result = np.empty(len(bounds))
    for start in range(0, len(bounds), CHUNK):
        low = bounds[start:start + CHUNK, 0][None]
        high = bounds[start:start + CHUNK, 1][None]
        at = points[:, None, :]
        outside = np.maximum(np.maximum(low - at, at - high), 0.0)
        result[start:start + CHUNK] = np.sqrt((outside ** 2).sum(axis=2)).min(axis=0)
    return result


def _box_gaps(low: np.ndarray, high: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """(models,) the gap between the box [low, high] and each model's bounds (0 where they overlap)."""
    gap = np.maximum(np.maximum(bounds[:, 0] - high, low - bounds[:, 1]), 0.0)
    distances: np.ndarray = np.sqrt((gap ** 2).sum(axis=1))
    return distances
