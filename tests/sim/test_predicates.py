"""Each predicate fires in a small world built for it, and none fires in a clean run."""

from __future__ import annotations

import pytest
from engines import in_engine
from helpers import box, ditch_world, flat_world

from pytest_ddenv.oracle import PREDICATES, make_predicate
from pytest_ddenv.sim import Simulator
from pytest_ddenv.world import Pose

ALL = ("stuck", "flipped", "high_centered", "fell", "collided", "timeout")


def _all_predicates():
    return [make_predicate(name) for name in ALL]


def test_clean_run_fires_nothing(sim: Simulator) -> None:
    run = sim.run(flat_world(goal=(10.0, 0.0), timeout=30.0), seed=0, predicates=_all_predicates())
    assert run.reached_goal and run.failure is None


def test_stuck_and_collided_at_a_wall(sim: Simulator) -> None:
    world = flat_world(box("wall", (0.3, 6.0, 1.0), (3.0, 0.0, 0.5)), timeout=20.0)
    stuck = sim.run(world, seed=0, predicates=[make_predicate("stuck")])
    assert stuck.failure is not None and stuck.failure.predicate == "stuck" and stuck.failure.touched == ("wall",)
    assert stuck.failure.time >= 5.0
    collided = sim.run(world, seed=0, predicates=[make_predicate("collided")])
    assert collided.failure is not None and collided.failure.predicate == "collided"
    assert collided.failure.time < stuck.failure.time
    named = sim.run(world, seed=0, predicates=[make_predicate("collided", models=["other"])])
    assert named.failure is None


def test_flipped_and_fell_off_a_high_ledge(sim: Simulator, physics_engine: str) -> None:
    world = in_engine(flat_world(box("ledge", (6.0, 8.0, 2.0), (-1.0, 0.0, 1.0)), start=Pose(-2.0, 0.0),
                                 goal=(6.0, 0.0), timeout=15.0), physics_engine)
    fell = sim.run(world, seed=0, predicates=[make_predicate("fell")])
    assert fell.failure is not None and fell.failure.predicate == "fell"
    flipped = sim.run(world, seed=0, predicates=[make_predicate("flipped")])
    assert flipped.failure is not None and flipped.failure.predicate == "flipped"


def test_high_centered_on_a_ridge(sim: Simulator) -> None:
    ridge = box("ridge", (3.0, 0.2, 0.35), (0.0, 0.0, 0.175))
    world = flat_world(ridge, start=Pose(0.0, 0.0, 0.35 - 0.13), start_z_given=True, goal=(8.0, 0.0),
                       timeout=10.0)
    run = sim.run(world, seed=0, predicates=[make_predicate("high_centered")])
    assert run.failure is not None and run.failure.predicate == "high_centered"
    assert run.failure.touched == ("ridge",)


def test_timeout(sim: Simulator, physics_engine: str) -> None:
    world = in_engine(flat_world(goal=(10.0, 0.0), timeout=3.0), physics_engine)
    run = sim.run(world, seed=0, predicates=[make_predicate("timeout")])
    assert run.failure is not None and run.failure.predicate == "timeout"
    assert abs(run.failure.time - 3.0) < 0.06
    assert not sim.run(world, seed=0).failed  # no predicate: no failure


def test_ditch_traps_the_robot(sim: Simulator) -> None:
    run = sim.run(ditch_world(), seed=0, predicates=[make_predicate("stuck")])
    assert run.failure is not None and run.failure.predicate == "stuck"
    assert {"near", "far"} & set(run.failure.touched)


@pytest.mark.parametrize(
    ("name", "params", "message"),
    [
        ("stuk", {}, "valid predicates"),
        ("stuck", {"windw": 3}, "valid parameters: window, min_progress"),
        ("stuck", {"window": 0}, "> 0"),
        ("stuck", {"window": "5"}, "finite number"),
        ("high_centered", {"max_wheel_load": 2}, "fraction"),
        ("collided", {"models": "wall"}, "list of model names"),
    ],
)
def test_make_predicate_validates(name, params, message) -> None:
    from pytest_ddenv.errors import ScenarioError

    with pytest.raises(ScenarioError, match=message):
        make_predicate(name, **params)


def test_every_builtin_is_listed() -> None:
    from pytest_ddenv.oracle import ARM_PREDICATES  # the arm's: tests/test_arm_predicates.py

    assert set(PREDICATES) == set(ALL) | set(ARM_PREDICATES)
    for name in ALL:
        assert make_predicate(name).name == name
