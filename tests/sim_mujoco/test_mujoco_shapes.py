"""Every shape of the world model in MuJoCo: it builds, rests on the ground or blocks the Husky where the world
model says it is, static models stay put, and friction follows the smaller mu of a pair."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("mujoco", reason="needs mujoco: pip install \"pytest-ddenv[mujoco]\"")

from mujoco_worlds import MUJOCO, flat_world
from PIL import Image

from pytest_ddenv.oracle import make_predicate
from pytest_ddenv.sim import Husky, Simulator
from pytest_ddenv.sim.mujoco.physics import MujocoPhysics
from pytest_ddenv.world import Ground, Model, Pose, Shape, World, geometry
from pytest_ddenv.world.meshes import load_heightmap, polyline_mesh

U_OUTLINE = ((0.0, 0.0), (2.6, 0.0), (2.6, 2.4), (2.2, 2.4), (2.2, 0.4), (0.4, 0.4), (0.4, 2.4), (0.0, 2.4))
"""A U opening towards +y: arms 0.4 m thick, the notch 1.8 m wide and 2 m deep (the Husky is 0.67 m wide)."""


def write_obj(path: Path, boxes: list[tuple[tuple[float, float, float], tuple[float, float, float]]]) -> Path:
    """An OBJ file of axis-aligned boxes (low corner, high corner), one object each."""
    lines: list[str] = []
    for index, (low, high) in enumerate(boxes):
        lines.append(f"o part{index}")
        base = index * 8
        for x in (low[0], high[0]):
            for y in (low[1], high[1]):
                for z in (low[2], high[2]):
                    lines.append(f"v {x} {y} {z}")
        for a, b, c, d in ((0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)):
            lines.append(f"f {base + a + 1} {base + b + 1} {base + c + 1} {base + d + 1}")
    path.write_text("\n".join(lines) + "\n")
    return path


def settled(world: World, seconds: float = 2.0) -> tuple[MujocoPhysics, dict[str, tuple[float, ...]]]:
    """`world` loaded in MuJoCo with the Husky parked far away, stepped `seconds`; each model's position."""
    physics = MujocoPhysics()
    robot = Husky()
    physics.load(world, robot, "min")
    physics.spawn(robot, (-30.0, -30.0, 0.2), 0.0)
    physics.step(round(seconds / world.physics.timestep))
    data = physics._loaded()[1]  # each model's origin (body_pose gives its centre of mass, as pybullet's does)
    positions = {name: tuple(float(v) for v in data.xpos[body]) for body, name in physics.bodies.items()}
    return physics, positions


def stuck() -> list:
    return [make_predicate("stuck", window=3.0, min_progress=0.2)]


DYNAMIC_SHAPES = {  # shape, resting height of the model's origin above the ground
    "box": (Shape("box", size=(0.4, 0.4, 0.4)), 0.2),
    "cylinder": (Shape("cylinder", radius=0.2, length=0.4), 0.2),
    "sphere": (Shape("sphere", radius=0.2), 0.2),
    "capsule": (Shape("capsule", radius=0.1, length=0.4, pose=Pose(0, 0, 0, math.pi / 2, 0, 0)), 0.1),
    "cone": (Shape("cone", radius=0.3, length=0.4), 0.2),
    "polyline": (Shape("polyline", points=((-0.2, -0.2), (0.2, -0.2), (0.2, 0.2), (-0.2, 0.2)), height=0.4), 0.0),
}


@pytest.mark.parametrize("kind", [*DYNAMIC_SHAPES, "mesh"])
def test_a_dynamic_shape_falls_and_rests_on_the_ground(kind: str, tmp_path: Path) -> None:
    if kind == "mesh":
        shape, rest = Shape("mesh", mesh=str(write_obj(tmp_path / "cube.obj", [((-0.2,) * 3, (0.2,) * 3)]))), 0.2
    else:
        shape, rest = DYNAMIC_SHAPES[kind]
    model = Model("thing", (shape,), pose=Pose(1.0, 2.0, rest + 0.3), static=False, mass=2.0)
    _, positions = settled(World(models=(model,), physics=MUJOCO))
    assert positions["thing"][2] == pytest.approx(rest, abs=0.01)
    assert positions["thing"][:2] == pytest.approx((1.0, 2.0), abs=0.02)


def test_a_static_model_stays_in_the_air_and_a_dynamic_one_falls() -> None:
    shelf = Model("shelf", (Shape("box", size=(0.4, 0.4, 0.4)),), pose=Pose(0.0, 0.0, 1.0))
    crate = Model("crate", (Shape("box", size=(0.4, 0.4, 0.4)),), pose=Pose(2.0, 0.0, 1.0), static=False)
    _, positions = settled(World(models=(shelf, crate), physics=MUJOCO))
    assert positions["shelf"] == (0.0, 0.0, 1.0)
    assert positions["crate"][2] == pytest.approx(0.2, abs=0.01)


def test_a_compound_of_primitives_rests_on_its_lowest_shape() -> None:
    table = Model("table", (Shape("box", size=(1.0, 1.0, 0.1), pose=Pose(0, 0, 0.5)),
                            Shape("cylinder", radius=0.05, length=0.5, pose=Pose(0, 0, 0.25))),
                  pose=Pose(3.0, 0.0, 0.3), static=False, mass=5.0)
    _, positions = settled(World(models=(table,), physics=MUJOCO))
    assert positions["table"][2] == pytest.approx(0.0, abs=0.01)


@pytest.mark.parametrize(("mu", "slides"), [(0.2, True), (0.5, False)])
def test_a_crate_on_a_20_degree_slope_slides_by_the_smaller_mu(mu: float, slides: bool) -> None:
    # tan(20 deg) = 0.36: a crate of mu 0.2 on a slope of mu 1 slides (the pair's friction is the smaller mu),
    # one of mu 0.5 sticks
    slope_angle = math.radians(20.0)
    slope = Model("slope", (Shape("box", size=(6.0, 2.0, 0.2)),), pose=Pose(0.0, 0.0, 1.0, 0, slope_angle, 0))
    normal = np.array([math.sin(slope_angle), 0.0, math.cos(slope_angle)])
    start = np.array([0.0, 0.0, 1.0]) + normal * (0.1 + 0.1 + 0.002)
    crate = Model("crate", (Shape("box", size=(0.2, 0.2, 0.2)),), pose=Pose(*start, 0, slope_angle, 0),
                  static=False, mass=1.0, mu=mu)
    _, positions = settled(World(models=(slope, crate), physics=MUJOCO, ground=None), seconds=1.0)
    moved = math.dist(positions["crate"], start)
    assert (moved > 0.3) if slides else (moved < 0.01)


def test_a_capsule_wall_blocks_the_husky(sim: Simulator) -> None:
    wall = Model("pipe", (Shape("capsule", radius=0.35, length=6.0),), pose=Pose(4.0, 0.0, 0.35, math.pi / 2, 0, 0))
    run = sim.run(flat_world(wall, goal=(8.0, 0.0), timeout=20.0), seed=0, predicates=stuck())
    assert run.engine == "mujoco"
    assert run.failure is not None and run.failure.predicate == "stuck" and "pipe" in run.failure.touched
    assert run.positions[:, 0].max() < 4.0 - 0.35


@pytest.mark.parametrize("kind", ["box", "cylinder"])
def test_a_wall_of_a_primitive_blocks_the_husky(sim: Simulator, kind: str) -> None:
    shape = (Shape("box", size=(0.3, 6.0, 1.0)) if kind == "box"
             else Shape("cylinder", radius=0.4, length=6.0, pose=Pose(0, 0, 0, math.pi / 2, 0, 0)))
    wall = Model("wall", (shape,), pose=Pose(4.0, 0.0, 0.5))
    run = sim.run(flat_world(wall, goal=(8.0, 0.0), timeout=20.0), seed=0, predicates=stuck())
    assert run.failure is not None and "wall" in run.failure.touched
    assert run.positions[:, 0].max() < 4.0 - 0.15


def test_a_row_of_spheres_and_cones_blocks_the_husky(sim: Simulator) -> None:
    shapes = tuple(Shape("sphere", radius=0.4, pose=Pose(0, y, 0.4)) for y in (-2.4, -0.8, 0.8, 2.4)) + tuple(
        Shape("cone", radius=0.45, length=1.0, pose=Pose(0, y, 0.5)) for y in (-3.2, -1.6, 0.0, 1.6, 3.2))
    row = Model("row", shapes, pose=Pose(4.0, 0.0, 0.0))
    run = sim.run(flat_world(row, goal=(8.0, 0.0), timeout=20.0), seed=0, predicates=stuck())
    assert run.failure is not None and "row" in run.failure.touched
    assert run.positions[:, 0].max() < 4.0


@pytest.mark.parametrize("kind", ["polyline", "mesh"])
def test_a_concave_static_shape_traps_the_husky_in_its_notch(sim: Simulator, kind: str, tmp_path: Path) -> None:
    # turned by 90 degrees, the U spans x 4.0..6.4 and y -1.3..1.3, its notch (x 4.0..6.0, y -0.9..0.9) opening
    # towards the robot: a convex hull would stop the robot at x = 4, the exact shape lets it in to x = 6
    if kind == "polyline":
        shape = Shape("polyline", points=U_OUTLINE, height=0.8)
    else:
        u_mesh: Any = polyline_mesh(U_OUTLINE, 0.8)  # one connected concave body: a slab per triangle
        u_mesh.export(tmp_path / "u.obj")
        shape = Shape("mesh", mesh=str(tmp_path / "u.obj"))
    trap = Model("trap", (shape,), pose=Pose(6.4, -1.3, 0.0, 0, 0, math.pi / 2))
    run = sim.run(flat_world(trap, goal=(8.0, 0.0), timeout=25.0), seed=0, predicates=stuck())
    assert run.failure is not None and run.failure.predicate == "stuck" and "trap" in run.first_touch
    front = run.failure.pose[0] + 0.99 / 2
    assert 5.5 < front <= 6.0 + 0.05


def test_the_hfield_is_the_world_models_heightmap_surface(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    Image.fromarray(rng.integers(0, 256, (5, 6)).astype(np.uint8)).save(tmp_path / "random.png")
    pose = Pose(1.0, 2.0, 0.3, 0, 0, 0.7)
    size = (5.0, 4.0, 1.0)
    hill = Model("hill", (Shape("heightmap", mesh=str(tmp_path / "random.png"), size=size),), pose=pose)
    physics = MujocoPhysics()
    physics.load(World(models=(hill,), physics=MUJOCO, ground=None), Husky(), "min")
    # the grid's inner vertices, where any split of a cell into triangles gives the same height
    xs, ys = np.meshgrid(np.linspace(-2.5, 2.5, 6)[1:-1], np.linspace(-2.0, 2.0, 5)[1:-1])
    local = np.column_stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)])
    placed = pose.position + local @ pose.rotation.T
    up = np.array([0.0, 0.0, 5.0])
    heights = physics.support_heights((placed + up).tolist(), (placed - up).tolist())
    expected = geometry.heightmap_height(load_heightmap(tmp_path / "random.png"), size, local[:, :2])
    assert np.asarray(heights) - pose.z == pytest.approx(expected, abs=1e-3)


def test_the_husky_starts_on_top_of_a_heightmap_and_drives_off_it(sim: Simulator, tmp_path: Path) -> None:
    Image.fromarray(np.full((16, 16), 255, dtype=np.uint8)).save(tmp_path / "plateau.png")
    plateau = Model("plateau", (Shape("heightmap", mesh=str(tmp_path / "plateau.png"), size=(4.0, 4.0, 0.1)),))
    run = sim.run(flat_world(plateau, goal=(4.0, 0.0), timeout=15.0, ground=Ground()), seed=0)
    assert run.reached_goal
    assert run.positions[0, 2] == pytest.approx(run.positions[-1, 2] + 0.1, abs=0.02)
    assert "plateau" in run.first_touch
