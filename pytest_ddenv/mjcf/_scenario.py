"""A scenario written in an MJCF scene: `<custom><text name="ddenv:scenario" data="..."/></custom>`.

`data` is `key=value` pairs separated by spaces (MuJoCo ignores custom text):
`robot=husky start=0,0,0 goal=8,0 timeout=30 tolerance=0.5`. `start` is X,Y[,YAW] (m, m, rad) and `goal`
X,Y[,Z] (m), both required; `robot` (a registered robot's name, default husky), `timeout` (simulated s) and
`tolerance` (the goal's, m) are optional. Each key at most once; anything else is a ScenarioError naming the
file, the line and the key.
"""

from __future__ import annotations

import math
from pathlib import Path

from pytest_ddenv.errors import ScenarioError, shown
from pytest_ddenv.world.limits import name_problem
from pytest_ddenv.world.model import Pose, Scenario

SCENARIO_TEXT = "ddenv:scenario"
KEYS = ("robot", "start", "goal", "timeout", "tolerance")
SYNTAX = "robot=NAME start=X,Y[,YAW] goal=X,Y[,Z] timeout=S tolerance=M"


def parse_scenario(data: str, source: Path, line: int | None) -> Scenario:
    """The scenario that `data` (the custom text's value) says; ScenarioError naming the key otherwise."""

    def fail(message: str, key: str | None = None) -> ScenarioError:
        field = f"custom/text[{SCENARIO_TEXT}]" + (f" {key}" if key else "")
        return ScenarioError(message, source=source, line=line, field=field)

    values: dict[str, str] = {}
    for pair in data.split():
        key, equals, value = pair.partition("=")
        if not equals or not value:
            raise fail(f"expected key=value pairs ({SYNTAX}), got {shown(pair)}")
        if key not in KEYS:
            raise fail(f"unknown key {shown(key)}; the keys are {', '.join(KEYS)}", key)
        if key in values:
            raise fail("given twice", key)
        values[key] = value
    for key in ("start", "goal"):
        if key not in values:
            raise fail(f"missing; a scenario needs start and goal ({SYNTAX})", key)

    def numbers(key: str, counts: tuple[int, ...]) -> list[float]:
        parts = values[key].split(",")
        try:
            result = [float(part) for part in parts]
        except ValueError:
            result = []
        if len(result) not in counts or not all(math.isfinite(value) for value in result):
            spelt = {"start": "X,Y or X,Y,YAW", "goal": "X,Y or X,Y,Z"}.get(key, "a positive number")
            raise fail(f"expected {spelt}, got {shown(values[key])}", key)
        return result

    def positive(key: str, default: float) -> float:
        if key not in values:
            return default
        (value,) = numbers(key, (1,))
        if value <= 0:
            raise fail(f"expected a positive number, got {shown(values[key])}", key)
        return value

    robot = values.get("robot", "husky")
    problem = name_problem(robot)
    if problem is not None:
        raise fail(f"{problem}; got {shown(robot)}", "robot")
    start, goal = numbers("start", (2, 3)), numbers("goal", (2, 3))
    default = Scenario()
    return Scenario(robot=robot, start=Pose(x=start[0], y=start[1], yaw=start[2] if len(start) == 3 else 0.0),
                    goal=(goal[0], goal[1], goal[2] if len(goal) == 3 else None),
                    goal_tolerance=positive("tolerance", default.goal_tolerance),
                    timeout=positive("timeout", default.timeout))
