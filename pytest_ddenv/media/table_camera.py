"""The animations' camera for an arm on a table: fixed for the whole run, above the arm's side of the table,
looking obliquely at the middle of the target's start and the place region (a chase camera behind a fixed
base would only show the arm's back); and the place region, drawn as a thin disc on the table
(`place_disc`)."""

from __future__ import annotations

import math

import numpy as np

from pytest_ddenv.sim.run import Run
from pytest_ddenv.world.model import World

ELEVATION_DEGREES = 40.0
"""How far the camera looks down (degrees below the horizon)."""
SIDE_DEGREES = 50.0
"""How far the camera is turned about the look-at point from straight behind the arm's base, so that the arm
does not hide the target."""
FRAMING = 1.8
"""Camera distance per metre of the scene shown (the target, the place region and the arm's base), for the
60 degree field of view of both renderers."""
CLOSEST = 1.4
"""The camera is never closer than this (m) to the point it looks at."""
LIFT = 0.1
"""The point looked at is this far (m) above the middle of the target and the place region, so that the arm
above them stays in the picture."""


def table_camera(world: World, run: Run) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """(eye, look-at point) of the camera over an arm's table: it looks at `LIFT` above the middle of the
    target's first recorded position (else the end effector's) and the place region, from above the arm's
    base."""
    scenario = world.scenario
    base = np.array([scenario.start.x, scenario.start.y, scenario.start.z] if scenario else [0.0, 0.0, 0.0])
    first = run.target_path[0] if run.target_path is not None and len(run.target_path) else run.poses[0, :3]
    target = np.asarray(first, dtype=float)
    place = target.copy()
    if scenario is not None:
        place[:2] = scenario.goal[:2]
        if scenario.goal[2] is not None:
            place[2] = float(scenario.goal[2])
    look = (target + place) / 2.0 + np.array([0.0, 0.0, LIFT])
    away = base[:2] - look[:2]
    if float(np.linalg.norm(away)) < 1e-6:  # the base under the look-at point: look along the arm's yaw
        yaw = scenario.start.yaw if scenario else 0.0
        away = -np.array([math.cos(yaw), math.sin(yaw)])
    heading = math.atan2(float(away[1]), float(away[0])) + math.radians(SIDE_DEGREES)
    span = max(float(np.linalg.norm(target - place)), float(np.linalg.norm(base[:2] - look[:2]))) + 0.3
    distance = max(CLOSEST, FRAMING * span)
    elevation = math.radians(ELEVATION_DEGREES)
    flat = distance * math.cos(elevation)
    eye = (float(look[0]) + flat * math.cos(heading), float(look[1]) + flat * math.sin(heading),
           float(look[2]) + distance * math.sin(elevation))
    return eye, (float(look[0]), float(look[1]), float(look[2]))


PLACE_RGBA = (0.2, 0.7, 0.3, 1.0)
"""The place region's disc in the animations (green, as the recording's goal; the arm is yellow)."""
PLACE_THICKNESS = 0.002
"""The disc's thickness (m); it is drawn only, never simulated."""


def place_disc(world: World) -> tuple[tuple[float, float, float], float] | None:
    """(centre, radius) of the disc that shows an arm's place region: the scenario's goal and tolerance, on
    the table's top (else at the goal's z, else on the ground); None without a scenario."""
    scenario = world.scenario
    if scenario is None:
        return None
    x, y, z = scenario.goal
    if z is None and scenario.table is not None and scenario.table in world.names:
        z = float(world.bounds(scenario.table)[1, 2])
    if z is None:
        z = world.ground.z if world.ground is not None else 0.0
    return (float(x), float(y), float(z) + PLACE_THICKNESS / 2.0), float(scenario.goal_tolerance)
