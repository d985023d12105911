"""Capsules, polylines and heightmaps in pybullet: the Husky meets them as the world model describes them (MuJoCo's:
tests/sim_mujoco/test_mujoco_shapes.py)."""

from __future__ import annotations

import math
from pathlib import Path

from typing import Any

import numpy as np
import pytest
from helpers import box, digest, flat_world
from PIL import Image

from pytest_ddenv.world import geometry
from pytest_ddenv.oracle import make_predicate
from pytest_ddenv.sim import Simulator
from pytest_ddenv.sim.builder import build_world
from pytest_ddenv.world import Ground, Model, Pose, Shape, World
from pytest_ddenv.world.meshes import load_heightmap

U_OUTLINE = ((0.0, 0.0), (2.6, 0.0), (2.6, 2.4), (2.2, 2.4), (2.2, 0.4), (0.4, 0.4), (0.4, 2.4), (0.0, 2.4))
"""A U opening towards +y: arms 0.4 m thick, the notch 1.8 m wide and 2 m deep (the Husky is 0.67 m wide)."""
HULL_OUTLINE = ((0.0, 0.0), (2.6, 0.0), (2.6, 2.4), (0.0, 2.4))

pytestmark = pytest.mark.pybullet


def stuck() -> list:
    return [make_predicate("stuck", window=3.0, min_progress=0.2)]


def test_a_capsule_wall_blocks_the_husky(sim: Simulator) -> None:
    wall = Model("pipe", (Shape("capsule", radius=0.35, length=6.0),), pose=Pose(4.0, 0.0, 0.35, math.pi / 2, 0, 0))
    run = sim.run(flat_world(wall, goal=(8.0, 0.0), timeout=20.0), seed=0, predicates=stuck())
    assert run.failure is not None and run.failure.predicate == "stuck" and "pipe" in run.failure.touched
    assert run.positions[:, 0].max() < 4.0 - 0.35  # never got over it


def test_a_polyline_wall_blocks_the_husky(sim: Simulator) -> None:
    zigzag = ((0.0, -3.0), (0.4, -1.0), (0.0, 1.0), (0.4, 3.0), (0.7, 3.0), (0.3, 1.0), (0.7, -1.0), (0.3, -3.0))
    wall = Model("fence", (Shape("polyline", points=zigzag, height=0.9),), pose=Pose(4.0, 0.0, 0.0))
    run = sim.run(flat_world(wall, goal=(8.0, 0.0), timeout=20.0), seed=0, predicates=stuck())
    assert run.failure is not None and run.failure.predicate == "stuck" and "fence" in run.failure.touched
    assert run.positions[:, 0].max() < 4.5


@pytest.mark.parametrize(("outline", "trapped"), [(U_OUTLINE, True), (HULL_OUTLINE, False)], ids=["u", "hull"])
def test_a_concave_polyline_traps_the_husky_where_its_hull_would_not(
    sim: Simulator, outline: tuple[tuple[float, float], ...], trapped: bool
) -> None:
    # turned by 90 degrees, the U spans x 4.0..6.4 and y -1.3..1.3, its notch (x 4.0..6.0, y -0.9..0.9) opening
    # towards the robot, which drives along y = 0 to a goal behind it
    trap = Model("trap", (Shape("polyline", points=outline, height=0.8),), pose=Pose(6.4, -1.3, 0.0, 0, 0, math.pi / 2))
    world = flat_world(trap, goal=(8.0, 0.0), timeout=25.0)
    assert world.distances(np.array([[5.0, 0.0, 0.3]]))[0, 0] == (pytest.approx(0.9) if trapped else 0.0)
    run = sim.run(world, seed=0, predicates=stuck())
    assert run.failure is not None and run.failure.predicate == "stuck" and "trap" in run.failure.touched
    front = run.failure.pose[0] + 0.99 / 2  # the Husky's front at the failure
    if trapped:
        assert 5.5 < front <= 6.0 + 0.05  # inside the notch, against the U's bottom at x = 6.0
    else:
        assert front < 4.1  # against the hull's face at x = 4


def heightmap_image(path: Path) -> Path:
    """A gentle hill along x: 0 at both ends, the top (white) in the middle 20 % (slopes of ~0.3 / 4 m)."""
    x = np.linspace(0.0, 1.0, 65)
    profile = np.clip(np.minimum(x, 1.0 - x) / 0.4, 0.0, 1.0)
    Image.fromarray(np.tile(np.round(profile * 255), (33, 1)).astype(np.uint8)).save(path)
    return path


def test_the_husky_drives_over_a_gentle_heightmap_hill(sim: Simulator, tmp_path: Path) -> None:
    image = heightmap_image(tmp_path / "hill.png")
    hill = Model("hill", (Shape("heightmap", mesh=str(image), size=(10.0, 6.0, 0.3)),), pose=Pose(4.0, 0.0, 0.0))
    run = sim.run(flat_world(hill, start=Pose(-2.0, 0.0), goal=(10.0, 0.0), timeout=40.0), seed=0,
                  predicates=stuck())
    assert run.reached_goal and run.failure is None
    assert "hill" in run.first_touch
    on_top = np.abs(run.positions[:, 0] - 4.0) < 0.5
    ground_height = np.median(run.positions[run.positions[:, 0] < -1.0, 2])
    assert run.positions[on_top, 2] == pytest.approx(ground_height + 0.3, abs=0.03)  # it rode over the top


def test_the_husky_starts_on_top_of_a_heightmap(sim: Simulator, tmp_path: Path) -> None:
    image = heightmap_image(tmp_path / "hill.png")
    hill = Model("hill", (Shape("heightmap", mesh=str(image), size=(10.0, 6.0, 0.3)),), pose=Pose(0.0, 0.0, 0.5))
    run = sim.run(flat_world(hill, start=Pose(0.0, 0.0), goal=(1.0, 0.0), timeout=10.0), seed=0)
    assert run.reached_goal
    assert run.positions[0, 2] > 0.5 + 0.3  # placed on the hill's top, not on the ground under it


def test_pybullet_heightfield_is_the_world_models_surface(tmp_path: Path) -> None:
    """Image orientation, centring, heights and the split of each grid cell agree, for a turned heightmap."""
    rng = np.random.default_rng(1)
    Image.fromarray(rng.integers(0, 256, (5, 6)).astype(np.uint8)).save(tmp_path / "random.png")
    pose = Pose(1.0, 2.0, 0.3, 0, 0, 0.7)
    hill = Model("hill", (Shape("heightmap", mesh=str(tmp_path / "random.png"), size=(5.0, 4.0, 1.0)),), pose=pose)
    world = World(models=(hill,), ground=None)
    local = np.column_stack([rng.uniform(-2.45, 2.45, 500), rng.uniform(-1.95, 1.95, 500), np.zeros(500)])
    placed = pose.position + local @ pose.rotation.T
    p, client, _ = settle(world, 0.0)
    try:
        hits = p.rayTestBatch((placed + [0, 0, 5]).tolist(), (placed - [0, 0, 5]).tolist(), physicsClientId=client)
    finally:
        p.disconnect(client)
    assert all(hit[0] >= 0 for hit in hits)
    surface = np.array([hit[3][2] for hit in hits])
    expected = geometry.heightmap_height(load_heightmap(tmp_path / "random.png"), (5.0, 4.0, 1.0), local[:, :2])
    assert surface - pose.z == pytest.approx(expected, abs=1e-4)  # pybullet works in float32
    on_surface = np.column_stack([placed[:, :2], surface])
    above = world.distances(on_surface + [0, 0, 2e-3])[:, 0]
    assert np.all((above > 0) & (above <= 2e-3 + 1e-4))
    assert np.all(world.distances(on_surface - [0, 0, 2e-3]) == 0.0)  # under the surface: inside


def settle(world: World, seconds: float) -> tuple[Any, int, dict[int, str]]:
    import pybullet

    client = pybullet.connect(pybullet.DIRECT)
    pybullet.setGravity(0, 0, -9.81, physicsClientId=client)
    pybullet.setPhysicsEngineParameter(deterministicOverlappingPairs=1, physicsClientId=client)
    bodies = build_world(pybullet, client, world)
    for _ in range(round(seconds * 240)):
        pybullet.stepSimulation(physicsClientId=client)
    return pybullet, client, bodies


def test_dynamic_capsule_and_polyline_fall_and_rest() -> None:
    world = World(models=(
        Model("log", (Shape("capsule", radius=0.2, length=1.0),), pose=Pose(0, 0, 2.0, 0.3, math.pi / 2, 0),
              mass=3.0, static=False),
        Model("slab", (Shape("polyline", points=((0, 0), (1, 0), (1, 0.5), (0, 0.5)), height=0.2),),
              pose=Pose(5, 0, 1.0), mass=2.0, static=False),
    ), ground=Ground())
    p, client, bodies = settle(world, 4.0)
    try:
        ids = {name: body for body, name in bodies.items()}
        (x, y, z), orientation = p.getBasePositionAndOrientation(ids["log"], physicsClientId=client)
        axis = np.array(p.getMatrixFromQuaternion(orientation)).reshape(3, 3)[:, 2]
        assert z == pytest.approx(0.2, abs=0.01) and abs(axis[2]) < 0.02  # lying on the ground
        linear, angular = p.getBaseVelocity(ids["log"], physicsClientId=client)
        assert np.linalg.norm(linear) < 0.01 and np.linalg.norm(angular) < 0.05
        low, high = p.getAABB(ids["slab"], physicsClientId=client)
        assert low[2] == pytest.approx(0.0, abs=0.01) and high[2] == pytest.approx(0.2, abs=0.01)
        (x, y, z), _ = p.getBasePositionAndOrientation(ids["slab"], physicsClientId=client)
        assert (x, y, z) == pytest.approx((5.5, 0.25, 0.1), abs=0.01)  # its base frame is its centre of mass
    finally:
        p.disconnect(client)


def test_a_dynamic_polyline_collides_as_its_convex_hull() -> None:
    outline = U_OUTLINE
    world = World(models=(
        Model("static_u", (Shape("polyline", points=outline, height=1.0),), pose=Pose(0, 0, 0, 0, 0, 0.4)),
        Model("dynamic_u", (Shape("polyline", points=outline, height=1.0),), pose=Pose(0, 10, 0, 0, 0, 0.4),
              mass=5.0, static=False),
    ), ground=None)
    p, client, bodies = settle(World(models=world.models, ground=None, physics=world.physics), 0.0)
    try:
        notch = Pose(0, 0, 0, 0, 0, 0.4).compose(Pose(1.3, 1.5, 0.5)).position  # in the notch of the U
        for offset, expected in ((0.0, -1), (10.0, 1)):
            start, end = notch + [0, offset, 2.0], notch + [0, offset, -2.0]
            hit = p.rayTest(start.tolist(), end.tolist(), physicsClientId=client)[0]
            assert (bodies.get(hit[0], -1) != -1) == (expected == 1)
            if expected == 1:
                assert hit[3][2] == pytest.approx(1.0, abs=0.01)  # the hull's top
    finally:
        p.disconnect(client)


def test_far_new_shapes_do_not_change_the_run(sim: Simulator, tmp_path: Path) -> None:
    image = heightmap_image(tmp_path / "hill.png")
    wall = box("wall", (0.3, 4.0, 1.0), (4.0, 0.0, 0.5))
    far = (
        Model("far_pipe", (Shape("capsule", radius=0.3, length=2.0),), pose=Pose(40, 40, 1.0), mass=2.0, static=False),
        Model("far_u", (Shape("polyline", points=U_OUTLINE, height=0.8),), pose=Pose(-40, 30, 0)),
        Model("far_hill", (Shape("heightmap", mesh=str(image), size=(10.0, 6.0, 0.3)),), pose=Pose(60, -50, 0)),
    )
    alone = sim.run(flat_world(wall, timeout=6.0), seed=2)
    with_far = sim.run(flat_world(wall, *far, timeout=6.0), seed=2)
    assert digest(alone) == digest(with_far)
