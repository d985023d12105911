"""Ready-made controllers. `GoToGoal` is the default one (the paper's robot: it drives blind to the goal on
its own position estimate); `AvoidObstacles` adds a reactive laser behaviour to any controller.

A controller of your own is any callable `controller(observation) -> Command` (see `pytest_ddenv.Observation`
and docs/writing-tests.md); pass it to `robot_world.run(controller=...)`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from pytest_ddenv.sim.control import (
    AnyCommand,
    Command,
    ControllerLike,
    Observation,
    check_controller,
    wrap_angle,
)
from pytest_ddenv.sim.settings import RunSettings
from pytest_ddenv.validation import expected, is_finite_number

__all__ = ["AvoidObstacles", "GoToGoal", "default_controller"]


@dataclass
class _Progress:
    """Where a `GoToGoal` is in its run: "approach", "search" (around the estimated goal) or "done"."""

    phase: str = "approach"
    time: float = -math.inf


@dataclass(frozen=True)
class GoToGoal:
    """Turn toward the goal and drive to it, on the robot's own pose estimate; where the estimate says the
    goal is, search around it if the run goes on (the goal is not reached in truth: the odometry drifted).

    `angular = clip(turn_gain * heading error, +-max_turn_rate)`,
    `linear = min(max_speed, 0.8 * distance) * max(0, cos heading error)**2`, until its estimate is within
    `stop_distance` m of the goal. Then, while the run goes on (it ends when the true pose is within the
    scenario's goal tolerance), it drives on at `search_speed` m/s: straight ahead for `search_spacing / 2` m
    (the estimate of a wheeled robot mostly drifts ahead of the truth: wheels slip), then outward on a spiral
    around the estimated goal whose turns are `search_spacing` m apart, out to `search_radius` m; then it
    drives back to the estimated goal and stops there. `search_radius=0`: it stops where its estimate says
    the goal is, with no search.
    """

    max_speed: float = 1.0
    turn_gain: float = 2.0
    max_turn_rate: float = 0.8
    stop_distance: float = 0.05
    search_radius: float = 0.6
    search_spacing: float = 0.3
    search_speed: float = 0.3
    _progress: _Progress = field(default_factory=_Progress, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        for name in ("max_speed", "turn_gain", "max_turn_rate", "search_spacing", "search_speed"):
            value = getattr(self, name)
            if not is_finite_number(value) or value <= 0:
                raise ValueError(expected("a finite number > 0", value, f"GoToGoal({name}=...)"))
        for name in ("stop_distance", "search_radius"):
            value = getattr(self, name)
            if not is_finite_number(value) or value < 0:
                raise ValueError(expected("a finite number >= 0", value, f"GoToGoal({name}=...)"))

    def reset(self, observation: Observation) -> None:
        """Start a run: approach the goal."""
        self._progress.phase, self._progress.time = "approach", observation.time

    def __call__(self, observation: Observation) -> Command:
        progress = self._progress
        if observation.time < progress.time:  # a new run without reset()
            progress.phase = "approach"
        progress.time = observation.time
        x, y, yaw = observation.pose
        goal = observation.goal
        dx, dy = goal[0] - x, goal[1] - y
        distance = math.hypot(dx, dy)
        if progress.phase == "approach" and distance < self.stop_distance:
            progress.phase = "search" if self.search_radius > 0 else "done"
        if progress.phase == "search":
            if distance <= self.search_radius:
                return self._search(-dx, -dy, yaw)
            progress.phase = "done"
        if distance < self.stop_distance:
            return Command(0.0, 0.0)
        error = wrap_angle(math.atan2(dy, dx) - yaw)
        angular = max(-self.max_turn_rate, min(self.max_turn_rate, self.turn_gain * error))
        linear = min(self.max_speed, 0.8 * distance) * max(0.0, math.cos(error)) ** 2
        return Command(linear, angular)

    def _search(self, from_goal_x: float, from_goal_y: float, yaw: float) -> Command:
        """Straight ahead near the estimated goal, then counterclockwise on the spiral out of it."""
        radius = math.hypot(from_goal_x, from_goal_y)
        if radius < self.search_spacing / 2.0:
            heading = yaw
        else:  # the spiral's tangent, turned outward so that each turn is search_spacing further out
            outward = math.atan2(self.search_spacing / (2.0 * math.pi), radius)
            heading = math.atan2(from_goal_y, from_goal_x) + math.pi / 2.0 - outward
        error = wrap_angle(heading - yaw)
        angular = max(-self.max_turn_rate, min(self.max_turn_rate, self.turn_gain * error))
        linear = min(self.max_speed, self.search_speed) * max(0.0, math.cos(error)) ** 2
        return Command(linear, angular)


@dataclass(frozen=True)
class AvoidObstacles:
    """Wrap a controller: stop and turn away (at `turn_rate`) while a laser hit lies in the corridor ahead
    (`corridor_width` wide, `corridor_depth` deep from the robot's centre); otherwise do what `inner` says.
    Without a laser it is `inner` unchanged."""

    inner: ControllerLike
    turn_rate: float = 0.8
    corridor_width: float = 0.8
    corridor_depth: float = 1.4

    def __post_init__(self) -> None:
        check_controller(self.inner, "AvoidObstacles(inner=...)")

    def reset(self, observation: Observation) -> None:
        reset = getattr(self.inner, "reset", None)
        if reset is not None:
            reset(observation)

    def __call__(self, observation: Observation) -> AnyCommand:
        command = self.inner(observation)
        scan = observation.scan
        if scan is None:
            return command
        finite = np.isfinite(scan.ranges)
        ranges = np.where(finite, scan.ranges, 0.0)
        ahead = scan.origin[0] + ranges * np.cos(scan.angles)  # the hits in the robot's frame
        side = scan.origin[1] + ranges * np.sin(scan.angles)
        half_width = self.corridor_width / 2.0
        blocking = finite & (ahead > 0.0) & (ahead < self.corridor_depth) & (np.abs(side) < half_width)
        if not blocking.any():
            return command
        away = -1.0 if float(np.sum(side[blocking])) > 0 else 1.0  # turn away from the obstacle's side
        return Command(0.0, away * self.turn_rate)


def default_controller(settings: RunSettings) -> ControllerLike:
    """The controller a run uses when none is given: `GoToGoal` with the settings' gains, wrapped in
    `AvoidObstacles` when `settings.avoid_obstacles`."""
    law = GoToGoal(settings.max_speed, settings.turn_gain, settings.max_turn_rate)
    if settings.avoid_obstacles:
        return AvoidObstacles(law, turn_rate=settings.max_turn_rate)
    return law
