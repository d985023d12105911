"""Faster heavy scenes (issue 33, point 3): every single-body model is a maximal-coordinate pybullet rigid body
(dynamic ones too), and a world's `solver_iterations` reaches Bullet (rubble.yaml asks for 15). The rubble's
failure and minimal world with these settings: tests/test_paper_regression.py."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
from helpers import box, flat_world

from pytest_ddenv.oracle import make_predicate
from pytest_ddenv.sim import Simulator
from pytest_ddenv.world import Model, Pose, Shape, World

ROOT = Path(__file__).resolve().parents[2]
RIGID_BODY, MULTIBODY = 1, 2
"""`getDynamicsInfo(...)[10]`, pybullet's body type."""

pytestmark = pytest.mark.pybullet


def body_types(sim: Simulator, episode_bodies: dict[int, str]) -> dict[str, int]:
    import pybullet as p

    return {name: p.getDynamicsInfo(body, -1, physicsClientId=sim.client)[10] for body, name in episode_bodies.items()}


def test_single_body_models_static_or_dynamic_are_rigid_bodies_and_meshes_with_links_are_not() -> None:
    compound = Model("block", (Shape("box", size=(0.4, 0.1, 0.2), pose=Pose(0.0, 0.1, 0.1)),
                               Shape("box", size=(0.4, 0.1, 0.2), pose=Pose(0.0, -0.1, 0.1))),
                     pose=Pose(3.0, 2.0, 0.0), static=False, mass=5.0)
    linked = Model("linked", (Shape("box", size=(0.2, 0.2, 0.2)),
                              Shape("cone", radius=0.1, length=0.2, pose=Pose(0.0, 0.0, 0.2))),
                   pose=Pose(3.0, -2.0, 0.1), static=False, mass=1.0)
    world = flat_world(box("wall", (0.2, 0.2, 0.2), (5.0, 3.0, 0.1)),
                       box("board", (1.2, 0.04, 0.09), (2.0, 2.0, 0.045), static=False, mass=1.4), compound, linked)
    with Simulator() as sim:
        episode = sim.start(world, seed=0)
        types = body_types(sim, dict(episode.bodies))
        robot = body_types(sim, {episode.body: "robot"})["robot"]
    assert types == {"<ground>": MULTIBODY, "wall": RIGID_BODY, "board": RIGID_BODY, "block": RIGID_BODY,
                     "linked": MULTIBODY}
    assert robot == MULTIBODY


def test_a_dynamic_rigid_body_falls_rests_and_is_pushed_by_the_robot() -> None:
    """A dynamic box dropped from 0.3 m lands on the ground; one in the robot's path is pushed along +x."""
    dropped = box("dropped", (0.3, 0.3, 0.3), (2.0, 2.0, 0.3), static=False, mass=1.0)
    pushed = box("pushed", (0.3, 0.6, 0.3), (2.0, 0.0, 0.15), static=False, mass=2.0)
    world = flat_world(dropped, pushed, goal=(6.0, 0.0), timeout=8.0)
    with Simulator() as sim:
        episode = sim.start(world, seed=0)
        bodies = {name: body for body, name in episode.bodies.items()}
        run = sim.run(world, seed=0)
        import pybullet as p

        rest = p.getBasePositionAndOrientation(bodies["dropped"], physicsClientId=sim.client)[0]
        moved = p.getBasePositionAndOrientation(bodies["pushed"], physicsClientId=sim.client)[0]
    assert rest[2] == pytest.approx(0.15, abs=0.01)
    assert moved[0] > 3.0, f"the robot drove {run.poses[-1][:2]} and left the box at {moved}"
    assert "pushed" in run.first_touch


def test_a_worlds_solver_iterations_reach_bullet() -> None:
    import pybullet as p

    rubble = World.load(ROOT / "worlds" / "rubble.yaml")
    assert rubble.physics.solver_iterations == 15
    with Simulator() as sim:
        sim.start(rubble, seed=0, predicates=[make_predicate("high_centered")])
        assert p.getPhysicsEngineParameters(physicsClientId=sim.client)["numSolverIterations"] == 15
        sim.start(flat_world(), seed=0)
        assert p.getPhysicsEngineParameters(physicsClientId=sim.client)["numSolverIterations"] == 50


def test_bench_rubble_measures_a_probe_and_a_deviation() -> None:
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        import bench_rubble
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
    one = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]
    other = [[0.0, 0.0, 0.0], [1.0, 0.3, 0.4], [9.0, 9.0, 9.0]]  # a longer run: the common samples only
    assert bench_rubble.deviation(one, other) == pytest.approx(0.5)
    (row,) = bench_rubble.probe_rows([0], 1)
    assert row["seed"] == 0 and row["failure"].startswith("high_centered at t = ")
    assert row["cpu"] > 0 and row["sim_time"] > 0 and len(row["positions"][0]) == 3
