"""A `Run` from what a test's own simulator reported (`robot_world.report(...)`), validated strictly."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from pytest_ddenv.errors import ScenarioError
from pytest_ddenv.oracle.predicates import FailureSignature
from pytest_ddenv.sim.run import Run
from pytest_ddenv.sim.settings import RunSettings
from pytest_ddenv.validation import expected
from pytest_ddenv.world.model import World

REPORTED = "reported"
"""The predicate name of a failure a test reported with `robot_world.report(..., failure_pose=...)`."""


def reported_run(
    world: World,
    times: Any,
    poses: Any,
    *,
    seed: int,
    failure_pose: Sequence[float] | None,
    failure_time: float | None,
    touched: Sequence[str] | Mapping[str, float],
    sensed: Mapping[str, float],
    reached_goal: bool,
    detail: str,
    footprint: tuple[float, float],
) -> Run:
    """See `RobotWorld.report` for the meaning of every argument."""
    stamps = _array(times, "times").reshape(-1)
    count = len(stamps)
    if count == 0:
        raise ScenarioError(expected("at least one sample", times, "report(times=...)"), field="times")
    if np.any(np.diff(stamps) < 0):
        raise ScenarioError(expected("times that do not decrease", stamps.tolist(), "report(times=...)"), field="times")
    full = _poses(_array(poses, "poses"), count)
    end = float(stamps[-1])
    failure = None
    if failure_pose is not None:
        where = _array(failure_pose, "failure_pose").reshape(-1)
        if where.shape[0] not in (2, 3, 6):
            raise ScenarioError(expected("2, 3 or 6 numbers (x, y[, z ...])", where.tolist(),
                                         "report(failure_pose=...)"), field="failure_pose")
        pose = np.zeros(6)
        pose[: min(3, len(where))] = where[:3]
        if len(where) == 6:
            pose[3:] = where[3:]
        when = end if failure_time is None else float(failure_time)
        names = tuple(sorted(touched)) if touched else ()
        failure = FailureSignature(REPORTED, when, tuple(float(v) for v in pose), names, detail)
    first_touch = _times_of(world, touched, end, "touched")
    first_sensed = _times_of(world, sensed, end, "sensed")
    return Run(
        seed=int(seed), settings=RunSettings(), world_name=world.name, model_names=world.names, robot=REPORTED,
        footprint=(float(footprint[0]), float(footprint[1])), times=stamps, poses=full,
        velocities=_velocities(stamps, full), wheel_contacts=np.zeros((count, 0)), first_touch=first_touch,
        last_touch=dict(first_touch), first_sensed=first_sensed, reached_goal=bool(reached_goal),
        goal_time=end if reached_goal else None, failure=failure, sim_time=end, wall_time=0.0, steps=0,
        pybullet_version="", engine=REPORTED,  # your simulator ran it, not one of ours
    )


def _array(value: Any, field: str) -> np.ndarray:
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ScenarioError(expected("numbers", value, f"report({field}=...)"), field=field) from None
    if not np.all(np.isfinite(array)):
        raise ScenarioError(expected("finite numbers", value, f"report({field}=...)", got="NaN or infinite values"),
                            field=field)
    return array


def _poses(poses: np.ndarray, count: int) -> np.ndarray:
    if poses.ndim != 2 or poses.shape[0] != count or poses.shape[1] not in (2, 3, 6):
        raise ScenarioError(expected(f"shape ({count}, 2), ({count}, 3) or ({count}, 6) to match times", poses,
                                     "report(poses=...)", got=f"shape {poses.shape}"), field="poses")
    full = np.zeros((count, 6))
    if poses.shape[1] == 6:
        full[:] = poses
    else:
        full[:, :2] = poses[:, :2]
        if poses.shape[1] == 3:
            full[:, 5] = poses[:, 2]
    return full


def _velocities(times: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """Finite-difference linear velocity and yaw rate (for the trajectory-segment partition)."""
    velocities = np.zeros((len(times), 6))
    if len(times) < 2:
        return velocities
    steps = np.diff(times)
    steps[steps <= 0] = np.inf
    velocities[1:, 0] = np.diff(poses[:, 0]) / steps
    velocities[1:, 1] = np.diff(poses[:, 1]) / steps
    velocities[1:, 5] = np.diff(np.unwrap(poses[:, 5])) / steps
    return velocities


def _times_of(world: World, models: Sequence[str] | Mapping[str, float], default: float,
              field: str) -> dict[str, float]:
    if isinstance(models, str):
        raise ScenarioError(expected("a list of model names (or name -> time), not a string", models,
                                     f"report({field}=...)"), field=field)
    times = dict(models) if isinstance(models, Mapping) else {name: default for name in models}
    unknown = sorted(set(times) - set(world.names))
    if unknown:
        raise ScenarioError(f"report({field}=...): model(s) not in the world: {', '.join(unknown)}", field=field)
    return {str(name): float(when) for name, when in times.items()}
