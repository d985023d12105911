"""The Husky drives, senses and records."""

from __future__ import annotations

import json

import numpy as np
import pytest
from engines import WHEELS_HOP_AT_A_WALL
from helpers import box, flat_world

from pytest_ddenv.oracle import make_predicate
from pytest_ddenv.sim import Run, RunSettings, Simulator, simulate


def test_reaches_a_goal_10_m_away(sim: Simulator) -> None:
    run = sim.run(flat_world(goal=(10.0, 0.0), timeout=30.0), seed=0)
    assert run.reached_goal and run.failure is None
    assert run.goal_time is not None and 8.0 < run.goal_time < 20.0
    assert run.sim_time == run.goal_time  # stopped early
    assert np.hypot(*(run.positions[-1, :2] - (10.0, 0.0))) <= 0.3
    assert run.steps == round(run.sim_time * 240)


def test_goal_behind_the_robot(sim: Simulator) -> None:
    # skid-steer turning on the spot misleads wheel odometry by ~0.3-0.4 m (see docs/simulation.md)
    run = sim.run(flat_world(goal=(-4.0, 3.0), timeout=30.0, goal_tolerance=0.6), seed=1)
    assert run.reached_goal


def test_run_to_the_end_when_asked(sim: Simulator) -> None:
    run = sim.run(flat_world(goal=(2.0, 0.0), timeout=6.0), seed=0, settings=RunSettings(stop_early=False))
    assert run.reached_goal and run.goal_time is not None and run.goal_time < 6.0
    assert abs(run.sim_time - 6.0) < 0.06 and abs(run.times[-1] - run.sim_time) < 1e-9


@pytest.mark.mujoco_gap(WHEELS_HOP_AT_A_WALL)
def test_run_record_arrays_touch_and_sense(sim: Simulator) -> None:
    wall = box("wall", (0.3, 4.0, 1.0), (5.0, 0.0, 0.5))
    run = sim.run(flat_world(wall, timeout=12.0), seed=0, predicates=[make_predicate("stuck", window=3.0)])
    T = len(run.times)
    assert run.poses.shape == (T, 6) and run.velocities.shape == (T, 6) and run.wheel_contacts.shape == (T, 4)
    assert np.all(np.diff(run.times) > 0)
    assert "wall" in run.first_sensed and "wall" in run.first_touch
    assert run.first_sensed["wall"] < run.first_touch["wall"] <= run.last_touch["wall"]
    assert run.failure is not None and run.failure.predicate == "stuck" and "wall" in run.failure.touched
    assert (run.wheel_contacts[5:] > 0).all()  # resting on the ground
    assert run.model_names == ("wall",) and run.engine_version


def test_run_json_round_trip(sim: Simulator) -> None:
    wall = box("wall", (0.3, 4.0, 1.0), (4.0, 0.0, 0.5))
    run = sim.run(flat_world(wall, timeout=8.0), seed=4, predicates=[make_predicate("collided")])
    data = json.loads(json.dumps(run.to_dict()))
    back = Run.from_dict(data)
    assert back.same_trajectory(run)
    assert np.array_equal(back.wheel_contacts, run.wheel_contacts)
    assert back.failure == run.failure and back.settings == run.settings
    assert back.to_dict() == run.to_dict()


def test_simulate_one_shot() -> None:
    run = simulate(flat_world(goal=(2.0, 0.0), timeout=10.0), seed=0)
    assert run.reached_goal


def test_obstacle_avoidance_option(sim: Simulator) -> None:
    pole = box("pole", (0.3, 0.3, 1.0), (4.0, 0.0, 0.5))
    world = flat_world(pole, goal=(8.0, 0.0), timeout=30.0)
    blind = sim.run(world, seed=0, predicates=[make_predicate("collided")])
    careful = sim.run(world, seed=0, predicates=[make_predicate("collided")],
                      settings=RunSettings(avoid_obstacles=True))
    assert blind.failure is not None
    assert careful.failure is None and careful.reached_goal
