"""Bad scenarios are rejected with a ScenarioError naming the field, before any simulation."""

from __future__ import annotations

import dataclasses

import pytest
from helpers import box, flat_world

from pytest_ddenv.errors import ScenarioError
from pytest_ddenv.sim import ROBOTS, Husky, RunSettings, Simulator, register_robot
from pytest_ddenv.sim.settings import NoiseSettings
from pytest_ddenv.world import Pose


def test_missing_scenario(sim: Simulator) -> None:
    world = dataclasses.replace(flat_world(), scenario=None)
    with pytest.raises(ScenarioError, match="no scenario") as info:
        sim.run(world)
    assert info.value.field == "scenario"


def test_unknown_robot_lists_the_registered_ones(sim: Simulator) -> None:
    with pytest.raises(ScenarioError, match="registered robots: .*husky") as info:
        sim.run(flat_world(robot="spot"))
    assert info.value.field == "scenario.robot"


@pytest.mark.parametrize("timeout", [0.0, -1.0, float("nan")])
def test_bad_timeout(sim: Simulator, timeout: float) -> None:
    with pytest.raises(ScenarioError, match=f"field 'timeout': expected a finite time limit in seconds > 0, got "
                                            f"{timeout!r}") as info:
        sim.run(flat_world(), timeout=timeout)
    assert info.value.field == "timeout"
    world = flat_world()
    world = dataclasses.replace(world, scenario=dataclasses.replace(world.scenario, timeout=timeout))
    with pytest.raises(ScenarioError) as info:
        sim.run(world)
    assert info.value.field == "scenario.timeout"


def test_start_inside_a_model(sim: Simulator) -> None:
    world = flat_world(box("crate", (2.0, 2.0, 0.3), (0.0, 0.0, 0.15)), start=Pose(0.0, 0.0, 0.0),
                       start_z_given=True)
    with pytest.raises(ScenarioError, match="inside crate") as info:
        sim.run(world)
    assert info.value.field == "scenario.start"


def test_start_z_omitted_puts_the_robot_on_top(sim: Simulator) -> None:
    world = flat_world(box("crate", (3.0, 3.0, 0.3), (0.0, 0.0, 0.15)), goal=(0.5, 0.0), timeout=2.0)
    run = sim.run(world)
    assert run.poses[0][2] > 0.3


def test_no_support_without_ground(sim: Simulator) -> None:
    with pytest.raises(ScenarioError, match="nothing supports") as info:
        sim.run(flat_world(ground=None))
    assert info.value.field == "scenario.start"
    supported = flat_world(box("deck", (30.0, 4.0, 0.2), (5.0, 0.0, 0.1)), ground=None, goal=(4.0, 0.0))
    assert sim.run(supported).reached_goal


def test_bad_settings() -> None:
    with pytest.raises(ScenarioError, match=r"field 'noise.actuation': expected a finite standard deviation >= 0, "
                                            r"got -0\.1"):
        NoiseSettings(actuation=-0.1)
    with pytest.raises(ScenarioError, match="field 'settings.control_rate': expected a finite number > 0, got 0"):
        RunSettings(control_rate=0)
    with pytest.raises(ScenarioError, match="field 'settings.friction': expected 'min' or 'product', got 'max'"):
        RunSettings(friction="max")


def test_bad_predicate_object(sim: Simulator) -> None:
    with pytest.raises(ScenarioError, match="not a failure predicate"):
        sim.run(flat_world(), predicates=["stuck"])  # type: ignore[list-item]


def test_register_a_robot(sim: Simulator) -> None:
    class SlowHusky(Husky):
        name = "slow_husky"

        def drive(self, linear, angular, scale_left=1.0, scale_right=1.0):
            super().drive(min(linear, 0.3), angular, scale_left, scale_right)

    register_robot("slow_husky", SlowHusky)
    try:
        with pytest.raises(ValueError, match="already registered"):
            register_robot("slow_husky", SlowHusky)
        run = sim.run(flat_world(goal=(3.0, 0.0), robot="slow_husky", timeout=30.0))
        assert run.reached_goal and run.goal_time > 7.0 and run.robot == "slow_husky"
    finally:
        ROBOTS.pop("slow_husky", None)
