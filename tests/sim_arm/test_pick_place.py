"""The default controller of an arm picks the target and places it, in PyBullet; a user's controller and the
robot_world front end drive the same episode."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pytest_ddenv import World
from pytest_ddenv.errors import ScenarioError
from pytest_ddenv.oracle.arm_predicates import KnockedOver
from pytest_ddenv.oracle.arm_state import GRIPPER_CLOSE, GRIPPER_OPEN, ArmState
from pytest_ddenv.scenario.robot_world import RobotWorld
from pytest_ddenv.sim import Simulator
from pytest_ddenv.sim.arm.control import ArmObservation, EndEffectorTarget, GripperCommand
from pytest_ddenv.sim.arm.pick_place import PHASES, PickAndPlace

pytestmark = pytest.mark.pybullet


def test_the_default_controller_places_the_cube(sim: Simulator, smoke: World) -> None:
    run = sim.run(smoke, seed=0)
    assert run.robot_kind == "arm" and run.robot == "panda"
    assert run.reached_goal and run.failure is None
    assert run.touched == {"cube"}  # neither the table under the base nor a distractor
    assert run.target_path is not None and run.target_path.shape == (len(run.times), 3)
    start, end = run.target_path[0], run.target_path[-1]
    assert math.dist(start[:2], (0.5, 0.0)) < 0.01
    assert math.dist(end[:2], (0.45, 0.3)) <= 0.08
    assert run.target_path[:, 2].max() > start[2] + 0.1  # carried, not pushed
    assert run.wheel_contacts.shape == (len(run.times), 2)
    assert (run.wheel_contacts.max(axis=0) > 0).all()  # both fingers held it
    assert run.goal_time == pytest.approx(run.sim_time)  # stops as soon as it is placed


def test_the_end_effector_is_recorded_as_the_pose(sim: Simulator, smoke: World) -> None:
    run = sim.run(smoke, seed=0)
    assert run.poses.shape == (len(run.times), 6)
    assert np.allclose(run.poses[0, :3], (0.307, 0.0, 0.885), atol=0.01)  # the Panda's home, base at z 0.4
    assert abs(abs(run.poses[0, 3]) - math.pi) < 0.01  # pointing down
    lowest = run.poses[:, 2].min()
    assert lowest == pytest.approx(0.425, abs=0.02)  # down to the cube's centre


def test_phases_follow_in_order(sim: Simulator, smoke: World) -> None:
    controller = PickAndPlace()
    seen: list[str] = []

    def watching(observation: ArmObservation) -> object:
        command = controller(observation)
        if not seen or seen[-1] != controller.phase:
            seen.append(controller.phase)
        return command

    watching.reset = controller.reset  # type: ignore[attr-defined]
    assert sim.run(smoke, controller=watching).reached_goal  # type: ignore[arg-type]
    assert seen == list(PHASES[:len(seen)])
    assert seen[-1] == "release"


def test_a_user_controller_that_never_closes_does_not_place(sim: Simulator, smoke: World) -> None:
    def hover(observation: ArmObservation) -> EndEffectorTarget:
        target = observation.target_pose
        assert target is not None
        return EndEffectorTarget((target[0], target[1], target[2] + 0.15), gripper=GRIPPER_OPEN)

    run = sim.run(smoke, controller=hover, timeout=2.0)
    assert not run.reached_goal and run.sim_time == pytest.approx(2.0, abs=0.06)
    assert run.touched == frozenset()


def test_a_gripper_command_alone_holds_the_arm(sim: Simulator, smoke: World) -> None:
    run = sim.run(smoke, controller=lambda o: GripperCommand(GRIPPER_CLOSE), timeout=1.0)
    assert np.allclose(run.poses[-1, :3], run.poses[0, :3], atol=0.01)


def test_robot_world_runs_an_arm_world(smoke: World) -> None:
    run = RobotWorld(smoke, seed=1).run()
    assert run.reached_goal


def test_a_mobile_robot_predicate_is_refused_on_an_arm(smoke: World) -> None:
    refused = "predicate 'stuck' is for mobile robots; the world's robot 'panda' is an arm"
    with pytest.raises(ScenarioError, match=refused) as caught:
        RobotWorld(smoke, predicates=["stuck"]).run()
    assert caught.value.field == "predicates"


def test_an_arm_run_is_written_and_read_back(sim: Simulator, smoke: World) -> None:
    import json

    from pytest_ddenv.sim import Run

    run = sim.run(smoke, seed=0)
    again = Run.from_dict(json.loads(json.dumps(run.to_dict())))
    assert again.robot_kind == "arm" and again.same_trajectory(run)
    assert again.target_path is not None and np.array_equal(again.target_path, run.target_path)  # type: ignore[arg-type]
    old = run.to_dict()
    del old["robot_kind"], old["target_path"]  # a log written before arms
    assert Run.from_dict(old).robot_kind == "mobile" and Run.from_dict(old).target_path is None


@pytest.mark.parametrize("removed", ["cube", "table"])
def test_a_world_without_its_target_or_table_is_refused(sim: Simulator, smoke: World, removed: str) -> None:
    field = "scenario.target" if removed == "cube" else "scenario.table"
    with pytest.raises(ScenarioError, match=f"'{removed}' is not a model of the world") as caught:
        sim.run(smoke.without([removed]))
    assert caught.value.field == field


class _SeenObjects:
    """A predicate of the test's own: records which objects' poses the arm's state holds."""

    name = "seen_objects"
    robots = "arm"

    def __init__(self) -> None:
        self.seen: set[str] = set()

    def reset(self) -> None:
        self.seen = set()

    def check(self, state: ArmState) -> None:
        self.seen |= set(state.objects)


@pytest.mark.parametrize("named", [True, False])
def test_knocked_over_sees_the_models_it_names_even_unwatched(sim: Simulator, smoke: World, named: bool) -> None:
    """`knocked_over(models=["block"])` on a model the scenario does not watch: the state holds its pose (a
    named model it could not see would never fire)."""
    spy = _SeenObjects()
    predicates = [KnockedOver(models=("block",)), spy] if named else [spy]
    sim.run(smoke, seed=0, predicates=predicates, timeout=0.5)
    assert ("block" in spy.seen) is named
    assert {"cube", "table", "mug"} <= spy.seen
