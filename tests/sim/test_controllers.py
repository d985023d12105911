"""A controller in the loop: what it sees, what it may return, and what happens when it misbehaves."""

from __future__ import annotations

import math
import signal
import time
import traceback

import numpy as np
import pytest
from helpers import box, flat_world

from pytest_ddenv import Command, ControllerError, ControllerTimeout, Observation, WheelCommand
from pytest_ddenv.oracle import make_predicate
from pytest_ddenv.sim import RunSettings, Simulator
from pytest_ddenv.sim.controllers import AvoidObstacles, GoToGoal, default_controller

WALL = box("wall", (0.3, 4.0, 1.0), (3.0, 0.0, 0.5))


def same(a: object, b: object) -> bool:
    return a.same_trajectory(b) and a.failure == b.failure  # type: ignore[attr-defined]


def test_the_default_controller_is_go_to_goal(sim: Simulator) -> None:
    world = flat_world(WALL, goal=(6.0, 0.0), timeout=8.0)
    stuck = [make_predicate("stuck", window=2.0, min_progress=0.2)]
    default = sim.run(world, seed=2, predicates=stuck)
    explicit = sim.run(world, seed=2, predicates=stuck, controller=GoToGoal())
    law = GoToGoal()
    as_function = sim.run(world, seed=2, predicates=stuck, controller=lambda observation: law(observation))
    assert same(default, explicit) and same(default, as_function)
    assert default.failure is not None and default.failure.touched == ("wall",)


def test_avoid_obstacles_is_the_default_with_avoid_obstacles_set(sim: Simulator) -> None:
    world = flat_world(WALL, goal=(6.0, 0.0), timeout=6.0)
    settings = RunSettings(avoid_obstacles=True)
    assert isinstance(default_controller(settings), AvoidObstacles)
    wrapped = AvoidObstacles(GoToGoal(), turn_rate=settings.max_turn_rate)
    assert same(sim.run(world, seed=1, settings=settings), sim.run(world, seed=1, settings=settings, controller=wrapped))


class Recorder:
    """Drives straight ahead and keeps every observation."""

    def __init__(self) -> None:
        self.resets: list[Observation] = []
        self.seen: list[Observation] = []

    def reset(self, observation: Observation) -> None:
        self.resets.append(observation)

    def __call__(self, observation: Observation) -> Command:
        self.seen.append(observation)
        return Command(linear=0.6, angular=0.0)


def test_what_a_controller_sees(sim: Simulator) -> None:
    recorder = Recorder()
    run = sim.run(flat_world(WALL, goal=(6.0, 0.0), timeout=6.0), seed=0, controller=recorder)
    first, last = recorder.seen[0], recorder.seen[-1]
    assert recorder.resets == [first], "reset once, with the first observation"
    assert [o.time for o in recorder.seen[:3]] == pytest.approx([0.0, 0.05, 0.1])
    assert first.goal == (6.0, 0.0, None) and len(first.wheel_speeds) == 4
    assert math.dist(first.pose[:2], run.poses[0, :2]) < 0.2  # the estimate starts at the scenario's start
    assert first.scan is not None and first.scan.ranges.shape == first.scan.angles.shape == (90,)
    with pytest.raises(ValueError):
        first.scan.ranges[0] = 1.0  # read-only
    ahead = np.abs(first.scan.angles) < 0.2
    assert np.all(first.scan.ranges[ahead] > 2.0), "the wall is about 2.85 m ahead at the start..."
    assert any(np.all(o.scan.ranges[ahead] < 2.0) for o in recorder.seen), "...which the laser sees coming"
    assert any(contact.model == "wall" for contact in last.contacts), "it drove into the wall"
    assert last.velocity[0] > 0.3 > abs(run.velocities[-1, 0]), "the encoders say it moves: its wheels slip"
    assert len(last.imu) == 3


def test_a_robot_without_laser_gets_no_scan(sim: Simulator) -> None:
    recorder = Recorder()
    sim.run(flat_world(goal=(6.0, 0.0), timeout=0.5), seed=0, settings=RunSettings(laser_rays=0), controller=recorder)
    assert all(observation.scan is None for observation in recorder.seen)


def test_wheel_commands_drive_the_wheels(sim: Simulator) -> None:
    straight = sim.run(flat_world(goal=(20.0, 0.0), timeout=3.0), seed=0, controller=lambda o: WheelCommand(4.0, 4.0))
    spin = sim.run(flat_world(goal=(20.0, 0.0), timeout=3.0), seed=0, controller=lambda o: WheelCommand(-3.0, 3.0))
    assert straight.poses[-1, 0] > 1.0 and abs(straight.poses[-1, 1]) < 0.3
    assert math.hypot(*spin.poses[-1, :2]) < 0.3 and abs(spin.poses[-1, 5] - spin.poses[0, 5]) > 0.3


@pytest.mark.parametrize(
    ("returned", "fragment"),
    [
        ((0.5, 0.0), r"returned tuple \(0\.5, 0\.0\) at t = 0\.00 s; expected Command"),
        (None, "returned NoneType None"),
        (Command(float("nan"), 0.0), r"at t = 0\.00 s: expected finite speeds, got Command\(linear=nan, angular=0\.0\)"),
        (WheelCommand(1.0, float("inf")), r"at t = 0\.00 s: expected finite speeds, got WheelCommand\(left=1\.0, right=inf\)"),
    ],
)
def test_a_command_that_is_not_a_command_is_a_controller_error(sim: Simulator, returned: object,
                                                               fragment: str) -> None:
    def broken(observation: Observation) -> object:
        return returned

    with pytest.raises(ControllerError, match=fragment) as raised:
        sim.run(flat_world(timeout=1.0), controller=broken)  # type: ignore[arg-type]
    assert "broken" in str(raised.value)


def test_what_the_controller_raises_propagates_with_a_note(sim: Simulator) -> None:
    def divide(observation: Observation) -> Command:
        if observation.time > 0.2:
            raise ZeroDivisionError("no room to turn")
        return Command(0.5, 0.0)

    with pytest.raises(ZeroDivisionError, match="no room") as raised:
        sim.run(flat_world(timeout=2.0), controller=divide)
    assert any("raised by the controller" in note and "t = 0.25 s" in note for note in raised.value.__notes__)


def test_a_controller_that_is_too_slow_fails_the_run(sim: Simulator) -> None:
    def slow(observation: Observation) -> Command:
        time.sleep(0.05)
        return Command(0.5, 0.0)

    with pytest.raises(ControllerTimeout, match="wall-clock limit of 0.3 s.*slow"):
        sim.run(flat_world(timeout=5.0), controller=slow, max_wall_time=0.3)


def test_a_controller_that_never_returns_is_stopped_by_the_run_alarm(sim: Simulator) -> None:
    def stuck(observation: Observation) -> Command:
        if observation.time > 0.2:
            time.sleep(30)  # a controller waiting for a message that never comes
        return Command(0.5, 0.0)

    with pytest.raises(ControllerTimeout, match="wall-clock limit of 0.5 s.*stuck") as raised:
        sim.run(flat_world(timeout=5.0), controller=stuck, max_wall_time=0.5)
    # Raised inside the controller's call (by the alarm), not after it returned (by the per-tick check).
    assert [frame.name for frame in traceback.extract_tb(raised.value.__traceback__)][-2:] == ["stuck", "_fire"]
    assert signal.getsignal(signal.SIGALRM) == signal.SIG_DFL and signal.getitimer(signal.ITIMER_REAL)[0] == 0


@pytest.mark.parametrize("controller", ["go", 42])
def test_a_controller_must_be_callable(sim: Simulator, controller: object) -> None:
    with pytest.raises(TypeError, match=rf"controller: expected a callable controller\(observation\) -> Command, got "
                                        rf"{controller!r}"):
        sim.run(flat_world(timeout=1.0), controller=controller)  # type: ignore[arg-type]
