"""`GoToGoal` with drifting odometry (issue 27, point 8): the example diffbot (a URDF robot) driving 8 m north
in an empty world ends 0.12-0.32 m from where its dead-reckoning estimate says the goal is (its wheels slip
a little). Before, it stopped there and `stuck` fired at the goal on some seeds, a failure with nothing in
the way; now it searches around its estimate while the run goes on."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from helpers import flat_world

from pytest_ddenv.sim.controllers import GoToGoal
from pytest_ddenv.oracle import make_predicate
from pytest_ddenv.sim import Observation, Simulator
from pytest_ddenv.world import RobotDescription

DIFFBOT = RobotDescription(urdf=str(Path(__file__).resolve().parents[2] / "examples" / "robots" / "diffbot.urdf"),
                           left_wheels=("left_wheel_joint",), right_wheels=("right_wheel_joint",))
GOAL = (0.0, 8.0)
NORTH = flat_world(goal=GOAL, timeout=40.0, robot=DIFFBOT)  # type: ignore[arg-type]
SEEDS = range(16)


def stuck() -> list[object]:
    return [make_predicate("stuck", window=5.0, min_progress=0.2)]


def distance_to_goal(run: object) -> float:
    x, y = run.positions[-1, :2]  # type: ignore[attr-defined]
    return math.hypot(x - GOAL[0], y - GOAL[1])


@pytest.fixture(scope="module")
def drifted_seeds(sim: Simulator) -> list[int]:
    """The seeds where the robot, without the search (what the default did before: `search_radius=0`), stops
    where its estimate says the goal is, outside the goal tolerance, and `stuck` fires there with nothing
    touched (seeds 0 and 14 with pybullet 3.2.7, 0.30 and 0.32 m from the goal)."""
    assert NORTH.scenario is not None
    seeds = []
    for seed in SEEDS:
        run = sim.run(NORTH, seed=seed, predicates=stuck(), controller=GoToGoal(search_radius=0))  # type: ignore[arg-type]
        if run.failure is not None:
            assert run.failure.predicate == "stuck" and run.failure.touched == ()
            assert NORTH.scenario.goal_tolerance < distance_to_goal(run) < 0.5
            seeds.append(seed)
    assert seeds, f"no seed in {SEEDS} drifted past the goal tolerance: the premise of this module is gone"
    return seeds


def test_a_drifted_estimate_is_not_stuck_at_the_goal(sim: Simulator, drifted_seeds: list[int]) -> None:
    for seed in drifted_seeds:
        run = sim.run(NORTH, seed=seed, predicates=stuck())  # type: ignore[arg-type]
        assert run.failure is None and run.reached_goal, (seed, run.failure)


def test_runs_that_reach_the_goal_on_the_way_are_unchanged(sim: Simulator) -> None:
    """The search only starts where the estimate reaches the goal: a run whose true pose gets there first is
    the same, bit for bit, as without it."""
    searching = sim.run(NORTH, seed=1, predicates=stuck())  # type: ignore[arg-type]
    stopping = sim.run(NORTH, seed=1, predicates=stuck(), controller=GoToGoal(search_radius=0))  # type: ignore[arg-type]
    assert searching.reached_goal and searching.same_trajectory(stopping)


def test_a_goal_beyond_the_search_ends_stuck_back_at_the_estimate(sim: Simulator) -> None:
    """With a goal tolerance no search finds (2 cm), the robot searches out to `search_radius` around its
    estimate, drives back to it and stops: `stuck` fires there, later than without the search."""
    tight = flat_world(goal=GOAL, timeout=60.0, robot=DIFFBOT, goal_tolerance=0.02)  # type: ignore[arg-type]
    law = GoToGoal()
    searching = sim.run(tight, seed=0, predicates=stuck(), controller=law)  # type: ignore[arg-type]
    stopping = sim.run(tight, seed=0, predicates=stuck(), controller=GoToGoal(search_radius=0))  # type: ignore[arg-type]
    assert searching.failure is not None and stopping.failure is not None
    assert searching.failure.predicate == stopping.failure.predicate == "stuck"
    assert searching.failure.time > stopping.failure.time + 5.0
    end = stopping.positions[-1, :2]  # where the estimate reached the goal: it stood there for stuck's window
    after = searching.times >= stopping.failure.time - 5.0
    farthest = max(math.dist(position, end) for position in searching.positions[after, :2])
    assert law.search_radius - 0.2 < farthest < law.search_radius + 0.3
    assert math.dist(searching.positions[-1, :2], end) < 0.3


def test_one_go_to_goal_serves_run_after_run(sim: Simulator) -> None:
    """The search state is per run: `reset` (or time going back) starts the approach again."""
    law = GoToGoal()
    first = sim.run(NORTH, seed=0, predicates=stuck(), controller=law)  # type: ignore[arg-type]
    again = sim.run(NORTH, seed=0, predicates=stuck(), controller=law)  # type: ignore[arg-type]
    fresh = sim.run(NORTH, seed=0, predicates=stuck(), controller=GoToGoal())  # type: ignore[arg-type]
    assert first.same_trajectory(again) and first.same_trajectory(fresh)
    observation = Observation(time=0.0, goal=(0.0, 0.0, None), pose=(0.0, 0.0, 0.0), velocity=(0.0, 0.0),
                              wheel_speeds=(), imu=(0.0, 0.0, 0.0), scan=None, contacts=())
    assert law(observation).linear > 0  # at the goal at t = 0: a new run, and it searches from there


@pytest.mark.parametrize(("argument", "value", "words"), [
    ("search_radius", -1.0, "a finite number >= 0"),
    ("search_spacing", 0.0, "a finite number > 0"),
    ("search_speed", math.nan, "a finite number > 0"),
    ("max_speed", "fast", "a finite number > 0"),
])
def test_bad_arguments_are_refused_naming_the_argument(argument: str, value: object, words: str) -> None:
    with pytest.raises(ValueError, match=rf"^GoToGoal\({argument}=\.\.\.\): expected {words}"):
        GoToGoal(**{argument: value})  # type: ignore[arg-type]
