"""Stage `time`: shorten the scenario. The latest start pose along the failing trajectory that still gives
the same failure (binary search over points of the path, at most `MAX_POINTS`; not for an arm, whose base is
fixed and whose path is the end effector's), then the shortest time limit
(the failure's time from the new start plus a margin), each decided by the deflake rule. A start is rounded
to the finest rung of the attributes stage's ladder (0.1 m, 5 degrees). The path is that of a failing run of
the world the stage starts from: the one it is given, else one run here (logged, counted) when the log does
not hold the path yet."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from pytest_ddenv.reduce import events
from pytest_ddenv.sim.arm.robot import robot_kind
from pytest_ddenv.stages import runs_kept
from pytest_ddenv.stages.attributes import ANGLES, LENGTHS
from pytest_ddenv.stages.context import StageContext
from pytest_ddenv.stages.result import StageResult
from pytest_ddenv.world.model import Pose, World

if TYPE_CHECKING:
    from pytest_ddenv.sim import Run

STAGE = "time"
MAX_POINTS = 16
"""Start points tried along the path at most (binary search: about 4 decisions)."""
MIN_SPACING = 0.25
"""Metres between two start points at least."""
TIME_MARGIN = 1.0
"""Simulated seconds left after the failure's time in the shortened time limit."""
PATH_RUNS = 3
"""Runs (attempts 0, 1, ...) at most to get a failing run of the world when none was given."""


def start_points(run: Run, failure_time: float) -> list[tuple[float, int]]:
    """(path distance before the failure point, sample index) of the candidate starts, from the original
    start (first) to the failure point (last), evenly spaced along the path."""
    times = np.asarray(run.times, dtype=float)
    last = int(np.searchsorted(times, failure_time, side="right")) - 1
    last = max(0, min(last, len(times) - 1))
    positions = np.asarray(run.poses[: last + 1, :2], dtype=float)
    steps = np.linalg.norm(np.diff(positions, axis=0), axis=1) if len(positions) > 1 else np.zeros(0)
    along = np.concatenate([[0.0], np.cumsum(steps)])
    total = float(along[-1])
    spacing = max(MIN_SPACING, total / MAX_POINTS)
    points: list[tuple[float, int]] = [(total, 0)]
    mark = spacing
    for index in range(1, last + 1):
        if along[index] >= mark:
            points.append((total - float(along[index]), index))
            mark = float(along[index]) + spacing
    if points[-1][1] != last and last > 0:
        points.append((0.0, last))
    return points


def moved(world: World, point: Point) -> World:
    """`world` with the robot starting (at rest, on what is under it) at `point` of the path, rounded to the
    finest rung of the ladder (0.1 m, 5 degrees)."""
    assert world.scenario is not None
    start = Pose(_round(point.x, LENGTHS[-1]), _round(point.y, LENGTHS[-1]), 0.0, 0.0, 0.0,
                 _round(point.yaw, ANGLES[-1]))
    return dataclasses.replace(world, scenario=dataclasses.replace(world.scenario, start=start, start_z_given=False))


def _round(value: float, step: float) -> float:
    return round(round(value / step) * step, 9) + 0.0  # + 0.0: never -0.0


@dataclass(frozen=True)
class Point:
    """A start point of the path: its distance (m) before the failure point, the time (s) the robot was
    there in the failing run, and its pose in the plane."""

    distance: float
    time: float
    x: float
    y: float
    yaw: float


def path_points(context: StageContext, trajectory: Run | None) -> tuple[list[Point], float] | None:
    """The start points and the failure time: from the stage's log when it has them (a resumed reduction
    uses the same path whatever run it has now), else from `trajectory` (then logged)."""
    view = context.log.view(STAGE)
    for event in view.own_events():
        if isinstance(event, events.FailurePath):
            return [Point(*point) for point in event.points], event.failure_time
    if trajectory is None or len(trajectory.times) < 2:
        return None
    failure_time = float(trajectory.failure.time) if trajectory.failure is not None else float(trajectory.times[-1])
    clearance = float(trajectory.footprint[0])  # a start closer than a robot length is where it got stuck
    points = [Point(distance, float(trajectory.times[index]), *(float(trajectory.poses[index][k]) for k in (0, 1, 5)))
              for distance, index in start_points(trajectory, failure_time) if distance >= clearance or index == 0]
    view.write(events.FailurePath(failure_time=failure_time,
                                  points=tuple((p.distance, p.time, p.x, p.y, p.yaw) for p in points)))
    return points, failure_time


def run(context: StageContext) -> StageResult:
    """`context.run`: a failing run of `context.base` (None: one is run here if the log lacks the path)."""
    world = context.base
    begin = context.budget.started()
    path = None
    if world.scenario is not None:
        path = path_points(context, context.run or (None if _logged_path(context) else _failing_run(context, begin)))
    if world.scenario is None or path is None:
        why = "the world has no scenario" if world.scenario is None else (
            f"no failing run of the world it starts from to take the path from (none of the at most {PATH_RUNS} "
            "runs made failed the same way, or the budget ran out)")
        return StageResult(STAGE, world, simulations=context.budget.started() - begin,
                           findings=[f"not shortened: {why}"])
    points, failure_time = path
    arm = robot_kind(world.scenario.robot, world.source) == "arm"  # its path is the end effector's, not the base's
    search = _Search() if arm else _latest_start(context, world, points, begin)
    good = search.good
    distance, start_time = points[good].distance, points[good].time
    shortened = world if good == 0 else moved(world, points[good])
    findings: list[str] = []
    if good:
        findings.append(f"starting {distance:.2f} m before the failure point (t = {start_time:.1f} s of the "
                        f"original run, {points[0].distance - distance:.2f} m along its path) still gives the same "
                        "failure")
    elif arm:
        findings.append("an arm's base does not move along its path: no later start is tried")
    else:
        findings.append("the robot needs its original start: no later start along the path gave the same failure")
    findings += search.errors
    details: dict[str, Any] = {"points": len(points),
                               "start": shortened.scenario.start.as_list() if shortened.scenario else None,
                               "start_time": start_time, "distance_before_failure": distance}
    original_timeout = world.scenario.timeout
    new_failure = search.failure_times.get(good, max(0.0, failure_time - start_time))
    incomplete = search.incomplete
    if incomplete is None:
        shortened, incomplete = _shorter_limit(context, shortened, new_failure, distance, begin, findings)
    assert shortened.scenario is not None
    saved_failing = max(0.0, failure_time - new_failure)
    saved_passing = original_timeout - shortened.scenario.timeout
    findings.append(f"simulated time saved per probe: {saved_failing:.1f} s on a failing run, {saved_passing:.1f} s "
                    "on a passing one")
    details.update({"timeout": shortened.scenario.timeout, "original_timeout": original_timeout,
                    "saved_sim_seconds_failing": round(saved_failing, 3),
                    "saved_sim_seconds_passing": round(saved_passing, 3)})
    return StageResult(STAGE, shortened, probes=0, simulations=context.budget.started() - begin, findings=findings,
                       details=details, incomplete=incomplete)


def _logged_path(context: StageContext) -> bool:
    return any(isinstance(event, events.FailurePath) for event in context.log.view(STAGE).own_events())


def _failing_run(context: StageContext, begin: int) -> Run | None:
    """A run of `context.base` that fails the same way: attempts 0, 1, ... (at most `PATH_RUNS`), logged in
    the stage's view as runs of "path run" and counted by the budget."""
    for attempt in range(PATH_RUNS):
        _, runs, errors, failing = runs_kept.measure(context, STAGE, "path run", context.base, 1,
                                                     first_attempt=attempt, stage_begin=begin)
        if failing is not None or (runs == 0 and not errors):  # found, or no budget left
            return failing
    return None


@dataclass
class _Search:
    """The binary search for the latest start: `good` indexes the latest point known to give the failure."""

    good: int = 0
    incomplete: str | None = None
    failure_times: dict[int, float] = field(default_factory=dict)
    errors: list[str] = field(default_factory=list)


def _latest_start(context: StageContext, world: World, points: Sequence[Point], begin: int) -> _Search:
    """The latest start along the path that still gives the same failure (point 0: the original start)."""
    search = _Search()
    bad = len(points)
    while bad - search.good > 1:
        middle = (search.good + bad) // 2
        distance = points[middle].distance
        decided = context.decide(STAGE, f"start {distance:.2f} m before the failure point",
                                 moved(world, points[middle]), stage_begin=begin)
        if decided.verdict is None and not decided.error:
            search.incomplete = "budget: no probes left"
            break
        if decided.error:  # the start is not valid (e.g. inside a model): start earlier
            search.errors.append(f"a start {distance:.2f} m before the failure point errored: {decided.error}")
            bad = middle
        elif decided.verdict:
            search.good = middle
            search.failure_times[middle] = _failure_time(decided.signatures)
        else:
            bad = middle
    return search


def _shorter_limit(context: StageContext, world: World, failure_time: float, distance: float, begin: int,
                   findings: list[str]) -> tuple[World, str | None]:
    """`world` with the shortest time limit that still gives the failure (its time plus a margin), if that
    is shorter than its own; a finding is added to `findings`. Returns the world and why it stopped early."""
    assert world.scenario is not None
    original_timeout = world.scenario.timeout
    timeout = float(math.ceil(failure_time + TIME_MARGIN))
    if timeout >= original_timeout:
        return world, None
    limited = dataclasses.replace(world, scenario=dataclasses.replace(world.scenario, timeout=timeout))
    decided = context.decide(STAGE, f"time limit {timeout:g} s, start {distance:.2f} m before", limited,
                             stage_begin=begin)
    if decided.verdict:
        findings.append(f"time limit {original_timeout:g} s -> {timeout:g} s")
        return limited, None
    if decided.verdict is None and not decided.error:
        return world, "budget: no probes left"
    findings.append(f"the failure needs the time limit of {original_timeout:g} s (not {timeout:g} s)")
    return world, None


def _failure_time(signatures: list[dict[str, object] | None]) -> float:
    """The latest failure time among the runs' signatures (0 when none has one)."""
    times = [value for s in signatures if isinstance(s, dict) and isinstance(value := s.get("time"), (int, float))]
    return float(max(times, default=0.0))
