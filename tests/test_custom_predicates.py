"""Predicates of your own: objects following the Predicate protocol, functions of the state, registered names."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import pytest

from pytest_ddenv import RobotWorld, World, predicate, register_predicate
from pytest_ddenv.errors import ScenarioError
from pytest_ddenv.oracle import (
    PREDICATES,
    FailureSignature,
    FunctionPredicate,
    RobotState,
    make_predicate,
    predicate_spec,
    signature,
)
from pytest_ddenv.scenario.robot_world import RobotFailure

WALL_WORLD = """
format: 1
scenario: {start: {x: 0, y: 0, yaw: 0}, goal: {x: 4, y: 0}, timeout: 8}
models:
  - {name: wall, pose: [2.0, 0, 0.5], box: [0.3, 4.0, 1.0]}
"""


@dataclass
class TouchedTwice:
    """Fails the second time the robot starts touching a model."""

    name: str = field(default="touched_twice", init=False)
    touches: int = field(default=0, init=False)
    touching: bool = field(default=False, init=False)

    def reset(self) -> None:
        self.touches, self.touching = 0, False

    def check(self, state: RobotState) -> FailureSignature | None:
        now = bool(state.touched)
        if now and not self.touching:
            self.touches += 1
        self.touching = now
        return signature(self.name, state, "touched twice") if self.touches >= 1 and now else None


@pytest.fixture
def wall() -> World:
    return World.from_yaml(WALL_WORLD, source="wall.yaml")


def test_a_predicate_object_fails_the_run(wall: World) -> None:
    robot_world = RobotWorld(wall, predicates=(predicate_spec(TouchedTwice()),))
    with pytest.raises(RobotFailure, match="'touched_twice' predicate fired.*touching wall"):
        robot_world.run()


def test_a_function_of_the_state_fails_the_run(wall: World) -> None:
    def close_to_the_wall(state: RobotState) -> bool:
        return state.pose[0] > 1.0

    spec = predicate_spec(close_to_the_wall)
    assert spec.name == "close_to_the_wall" and isinstance(spec.instance, FunctionPredicate)
    with pytest.raises(RobotFailure, match="'close_to_the_wall' predicate fired") as raised:
        RobotWorld(wall, predicates=(spec,)).run()
    assert 1.0 < raised.value.signature.pose[0] < 1.2


def test_the_predicate_decorator_names_the_failure_and_keeps_the_message(wall: World) -> None:
    @predicate(name="too_far")
    def beyond(state: RobotState) -> str | None:
        return f"x = {state.pose[0]:.1f}" if state.pose[0] > 0.5 else None

    assert isinstance(beyond, FunctionPredicate)
    with pytest.raises(RobotFailure, match=r"'too_far' predicate fired.*x = 0\.5"):
        RobotWorld(wall, predicates=(predicate_spec(beyond),)).run()


def test_a_registered_predicate_works_by_name(wall: World) -> None:
    @dataclass
    class PastX:
        x: float = 1.0
        name: str = field(default="past_x", init=False)

        def reset(self) -> None:
            pass

        def check(self, state: RobotState) -> FailureSignature | None:
            return signature(self.name, state) if state.pose[0] > self.x else None

    register_predicate("past_x", PastX, replace=True)
    try:
        spec = predicate_spec("past_x", {"x": 0.8})
        assert spec.to_json() == {"name": "past_x", "params": {"x": 0.8}}
        with pytest.raises(RobotFailure, match="past_x"):
            RobotWorld(wall, predicates=(spec,)).run()
        with pytest.raises(ScenarioError, match="predicate 'past_x' has no parameter 'y'; valid parameters: x"):
            make_predicate("past_x", y=1)
    finally:
        PREDICATES.pop("past_x", None)


def test_register_predicate_refuses_clashes_and_non_factories() -> None:
    with pytest.raises(ValueError, match="'stuck' is already registered"):
        register_predicate("stuck", lambda: TouchedTwice(), replace=True)
    with pytest.raises(ValueError, match=r"register_predicate\(name=...\): expected an identifier, got 'not a name'"):
        register_predicate("not a name", lambda: TouchedTwice())
    with pytest.raises(TypeError, match=r"register_predicate\('nothing', ...\): expected a callable factory, got 3"):
        register_predicate("nothing", 3)  # type: ignore[arg-type]
    register_predicate("not_a_predicate", lambda: 3)
    try:
        with pytest.raises(ScenarioError, match="returned 3, which is not a failure predicate"):
            make_predicate("not_a_predicate")
    finally:
        PREDICATES.pop("not_a_predicate", None)


@pytest.mark.parametrize(
    ("value", "params", "fragment"),
    [
        (TouchedTwice, {}, "TouchedTwice is a class; pass an instance"),
        (42, {}, "42 is not a failure predicate: expected a registered name"),
        (TouchedTwice(), {"window": 3}, "parameters window are only for a predicate given by name"),
        (type("NoCheck", (), {"name": "x", "reset": lambda self: None, "check": 3})(), {}, "needs a method check"),
    ],
)
def test_what_is_not_a_predicate_is_said_clearly(value: Any, params: dict[str, Any], fragment: str) -> None:
    with pytest.raises(ScenarioError, match=fragment):
        predicate_spec(value, params)


@pytest.mark.parametrize("returned", [3, "fine", [1]])
def test_a_predicate_that_returns_something_else_is_an_error(wall: World, returned: Any) -> None:
    class Odd:
        name = "odd"

        def reset(self) -> None:
            pass

        def check(self, state: RobotState) -> Any:
            return returned

    with pytest.raises(ScenarioError, match="predicate 'odd' returned .* check\\(\\) must return a FailureSignature"):
        RobotWorld(wall, predicates=(predicate_spec(Odd()),)).run()


def test_a_function_predicate_that_returns_something_else_is_an_error(wall: World) -> None:
    half = FunctionPredicate(lambda state: 0.5, "half")
    with pytest.raises(ScenarioError, match="predicate function half returned float 0.5"):
        RobotWorld(wall, predicates=(predicate_spec(half),)).run()


def test_a_predicate_object_is_reset_before_every_run(wall: World) -> None:
    counter = TouchedTwice()
    robot_world = RobotWorld(wall, predicates=(predicate_spec(counter),))
    for _ in range(2):
        with pytest.raises(RobotFailure):
            robot_world.run()
        assert counter.touches == 1 and math.isfinite(robot_world.runs[-1].failure.time)


def test_robot_world_takes_predicates_by_registered_name(wall: World) -> None:
    """Names as strings are built as the robot_failure marker builds them (not an AttributeError on .build)."""
    robot_world = RobotWorld(wall, predicates=("stuck", TouchedTwice()))
    assert [p.name for p in robot_world.build_predicates()] == ["stuck", "touched_twice"]
    assert RobotWorld(wall, predicates="stuck").predicates == RobotWorld(wall, predicates=["stuck"]).predicates
    assert robot_world.rebound(wall).predicates == robot_world.predicates


@pytest.mark.parametrize(
    ("predicates", "message"),
    [
        (("wobbly",), r"RobotWorld\(predicates=...\)\[0\]: .*unknown failure predicate 'wobbly'; valid predicates: "),
        (("stuck", 3), r"RobotWorld\(predicates=...\)\[1\]: .*3 is not a failure predicate"),
        (5, r"RobotWorld\(predicates=...\): expected a list of predicates .*, got 5"),
    ],
)
def test_robot_world_rejects_what_is_not_a_predicate(wall: World, predicates: Any, message: str) -> None:
    with pytest.raises(ScenarioError, match=message):
        RobotWorld(wall, predicates=predicates)


def test_a_run_that_raises_is_recorded_as_such(wall: World) -> None:
    """What the reduction needs to say "the run raised" rather than "the test made no run"."""
    robot_world = RobotWorld(wall)

    def broken(observation: Any) -> Any:
        raise RuntimeError("controller bug")

    with pytest.raises(RuntimeError, match="controller bug"):
        robot_world.run(controller=broken)
    assert isinstance(robot_world.run_error, RuntimeError) and robot_world.runs == []
    robot_world.run(raise_on_failure=False)
    assert robot_world.run_error is None and len(robot_world.runs) == 1
