"""The shipped scenario worlds hold the geometry of the paper's Gazebo worlds (paper-artifact.md, §1, App. A-C)."""

from __future__ import annotations

import dataclasses
import functools
import importlib.util
import math
from collections import Counter
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from pytest_ddenv.world import Model, World

ROOT = Path(__file__).resolve().parent.parent
WORLDS = ROOT / "worlds"
MAIN = {"ditch": 43, "rubble": 36, "friction": 25}
VARIANTS = {
    "ditch_bridged": 43,
    "ditch_ground_only": 0,
    "rubble_no_blocks": 34,
    "rubble_ground_only": 0,
    "friction_no_barrels": 17,
    "friction_ground_only": 0,
}
ALL_WORLDS = sorted({**MAIN, **VARIANTS})


@functools.cache
def load(name: str) -> World:
    """Each shipped world parsed once per session (worlds are immutable)."""
    return World.load(WORLDS / f"{name}.yaml")


@pytest.fixture
def ditch() -> World:
    return load("ditch")


@pytest.fixture
def rubble() -> World:
    return load("rubble")


@pytest.fixture
def friction() -> World:
    return load("friction")


def top(world: World, name: str) -> float:
    return float(world.bounds(name)[1, 2])


def support_under(world: World, x: float, y: float) -> str:
    """The name of the model with the highest top whose x/y extent contains (x, y)."""
    best, best_top = "", -math.inf
    for name in world.names:
        low, high = world.bounds(name)
        if low[0] <= x <= high[0] and low[1] <= y <= high[1] and high[2] > best_top:
            best, best_top = name, float(high[2])
    return best


def _dims(model: Model) -> tuple[float, float, float]:
    low, high = World(models=(dataclasses.replace(model, pose=dataclasses.replace(model.pose, x=0.0)),)).bounds(
        model.name
    )
    return tuple(float(v) for v in high - low)  # type: ignore[return-value]


# -- every world -------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ALL_WORLDS)
def test_world_loads_with_its_model_count(name: str) -> None:
    world = load(name)
    expected = {**MAIN, **VARIANTS}[name]
    assert len(world) == expected
    assert len(world.reducible_names) == expected
    assert world.ground is not None and (world.ground.mu, world.ground.mu2) == (100.0, 50.0)
    assert world.scenario is not None and world.scenario.timeout <= 60.0


@pytest.mark.parametrize("name", ALL_WORLDS)
def test_yaml_round_trip_is_exact(name: str) -> None:
    path = WORLDS / f"{name}.yaml"
    world = load(name)
    assert World.from_yaml(world.to_yaml(), source=path) == world
    body = "".join(line for line in path.read_text(encoding="utf-8").splitlines(keepends=True) if not line.startswith("#"))
    # the files name no engine, which is pybullet where it is installed and mujoco elsewhere (written then)
    assert world.with_engine("pybullet").to_yaml() == body


def _generator() -> ModuleType:
    spec = importlib.util.spec_from_file_location("make_scenario_worlds", ROOT / "tools" / "make_scenario_worlds.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_generator_reproduces_the_committed_files() -> None:
    assert _generator().main(["--check"]) == 0


@pytest.mark.parametrize("name", ["ditch", "rubble", "friction"])
def test_start_and_goal_are_over_a_support(name: str) -> None:
    world = load(name)
    assert world.scenario is not None
    start = world.scenario.start
    expected_start = {"ditch": "asphalt_plane", "rubble": "asphalt_plane", "friction": "grey_wall"}[name]
    assert support_under(world, start.x, start.y) == expected_start
    goal_x, goal_y, _ = world.scenario.goal
    assert support_under(world, goal_x, goal_y) != ""


# -- ditch -----------------------------------------------------------------------------------------------------
def test_ditch_gap_between_the_plateaus(ditch: World) -> None:
    near, far = ditch.bounds("asphalt_plane"), ditch.bounds("asphalt_plane_clone")
    assert near[1, 0] == pytest.approx(1.4617, abs=1e-4)
    assert far[0, 0] == pytest.approx(1.9689, abs=1e-4)
    assert far[0, 0] - near[1, 0] == pytest.approx(0.507, abs=1e-3)
    assert near[1, 2] == pytest.approx(0.8802, abs=1e-4)
    assert far[1, 2] == pytest.approx(0.8726, abs=1e-4)
    assert near[0, 2] < 0.0 and far[0, 2] < 0.0  # solid down to (and through) the ground: the ditch floor is z = 0
    for name in ("asphalt_plane", "asphalt_plane_clone"):
        assert ditch.model(name).static and (ditch.model(name).mu, ditch.model(name).mu2) == (100.0, 50.0)


def test_ditch_pads(ditch: World) -> None:
    pads = [model for model in ditch if model.name.startswith("frc2016_roughterrain")]
    assert len(pads) == 40
    for pad in pads:
        assert pad.static and len(pad.shapes) == 32
        assert pad.pose.yaw == 0.0 and 0.769 <= pad.pose.z <= 0.777
        platform, blocks = pad.shapes[0], pad.shapes[1:]
        assert platform.size == (1.27, 0.5969, 0.003175) and platform.pose.z == 0.08269
        assert Counter(block.size[2] for block in blocks if block.size) == {0.0254: 10, 0.0508: 11, 0.0762: 10}
        assert Counter(block.pose.y for block in blocks) == {0.1143: 10, 0.0: 11, -0.1143: 10}
        platform_top = pad.pose.z + 0.08269 + 0.003175 / 2
        assert 0.852 <= platform_top <= 0.862  # below the asphalt surface
    near = [pad for pad in pads if pad.pose.x < 1.4617]
    far = [pad for pad in pads if pad.pose.x > 1.9689]
    assert (len(near), len(far)) == (16, 24)
    assert min(p.pose.x for p in near) == pytest.approx(-1.14) and max(p.pose.x for p in near) == pytest.approx(0.865)
    assert min(p.pose.x for p in far) == pytest.approx(2.634) and max(p.pose.x for p in far) == pytest.approx(5.03)


def test_ditch_cinder_block_rests_on_the_far_plateau(ditch: World) -> None:
    block = ditch.model("cinder_block")
    assert block.dynamic and block.mass == 5.0 and len(block.shapes) == 5 and (block.mu, block.mu2) == (1.0, 1.0)
    low, high = ditch.bounds("cinder_block")
    assert low[2] == pytest.approx(top(ditch, "asphalt_plane_clone"), abs=2e-3)
    assert high[2] - low[2] == pytest.approx(0.2032, abs=1e-3)
    assert (block.pose.x, block.pose.y, block.pose.yaw) == (4.448, -1.102, -0.032)


def test_ditch_bridged_has_no_gap(ditch: World) -> None:
    bridged = load("ditch_bridged")
    assert bridged.names == ditch.names
    assert bridged.bounds("asphalt_plane")[1, 0] == pytest.approx(bridged.bounds("asphalt_plane_clone")[0, 0])
    assert bridged.bounds("asphalt_plane")[0, 0] == pytest.approx(ditch.bounds("asphalt_plane")[0, 0])
    assert bridged.without(["asphalt_plane"]).models == ditch.without(["asphalt_plane"]).models


# -- rubble ------------------------------------------------------------------------------------------------------
def test_rubble_boards(rubble: World) -> None:
    boards = [model for model in rubble if model.name.startswith("lumber_2x4x48")]
    assert len(boards) == 33
    for board in boards:
        assert board.dynamic and board.mass == 1.4111 and (board.mu, board.mu2) == (5.0, 5.0)
        assert board.shapes[0].size == (1.2192, 0.038, 0.0888)
    flat = [b for b in boards if abs(abs(b.pose.roll) - math.pi / 2) < 0.3]
    on_edge = [b for b in boards if abs(b.pose.roll) < 0.3]
    assert (len(flat), len(on_edge)) == (25, 8)
    xs = [b.pose.x for b in boards]
    ys = [b.pose.y for b in boards]
    zs = [b.pose.z for b in boards]
    assert (min(xs), max(xs), min(ys), max(ys)) == (-2.293, 2.072, -2.348, 0.915)
    assert (min(zs), max(zs)) == (0.067, 0.203)
    assert rubble.model("lumber_2x4x48").pose.y == 0.248  # effective pose, not the stale body y = 10.80


def test_rubble_asphalt_and_blocks(rubble: World) -> None:
    assert top(rubble, "asphalt_plane") == pytest.approx(0.05)
    for name in ("cinder_block", "cinder_block_0"):
        block = rubble.model(name)
        assert block.dynamic and block.mass == 5.0 and len(block.shapes) == 5
        assert rubble.bounds(name)[0, 2] == pytest.approx(0.05, abs=2e-3)
    # both blocks lie near the straight line from the spawn to the goal (paper-artifact.md §1b)
    start, goal = np.array([-3.0, -0.5]), np.array([3.75, -1.08])
    direction = (goal - start) / np.linalg.norm(goal - start)
    for name in ("cinder_block", "cinder_block_0"):
        offset = rubble.model(name).pose.position[:2] - start
        assert abs(offset[0] * direction[1] - offset[1] * direction[0]) < 0.07


def test_rubble_no_blocks_is_rubble_without_its_blocks(rubble: World) -> None:
    variant = load("rubble_no_blocks")
    assert variant.models == rubble.without(["cinder_block", "cinder_block_0"]).models


# -- friction ------------------------------------------------------------------------------------------------------
def test_friction_tiles(friction: World) -> None:
    tiles = [model for model in friction if model.name.startswith("grey_wall")]
    assert len(tiles) == 16
    frictions = Counter((tile.mu, tile.mu2) for tile in tiles)
    assert frictions == {(1000.0, 500.0): 8, (1.0, 5.0): 8}
    for tile in tiles:
        assert tile.static
        dims = _dims(tile)
        assert dims[0] == pytest.approx(2.0) and dims[1] == pytest.approx(2.0, abs=0.02)
        assert dims[2] == pytest.approx(0.2, abs=0.02)
        flat_top = tile.pose.z + 0.1
        assert 0.240 <= flat_top <= 0.251 and flat_top > top(friction, "asphalt_plane_0")
        red = tile.mu == 1000.0
        assert tile.color[:3] == ((1.0, 0.1, 0.1) if red else (0.1, 1.0, 0.1))
    assert friction.model("grey_wall").mu == 1000.0  # the start tile is a high-friction (red) one


def test_friction_slab_and_barrels(friction: World) -> None:
    slab = friction.model("asphalt_plane_0")
    assert slab.static and (slab.mu, slab.mu2) == (1.0, 1.0)
    assert top(friction, "asphalt_plane_0") == pytest.approx(0.2344, abs=1e-4)
    barrels = [model for model in friction if model.name.startswith("Construction Barrel")]
    assert len(barrels) == 8
    for barrel in barrels:
        assert barrel.static and [s.kind for s in barrel.shapes] == ["cylinder", "cylinder"]
        ring, body = barrel.shapes
        assert ring.radius == pytest.approx(0.51, abs=0.01) and body.radius == pytest.approx(0.30, abs=0.01)
        assert top(friction, barrel.name) - barrel.pose.z == pytest.approx(1.20, abs=0.01)
    assert friction.model("Construction Barrel_2").pose.z == 0.045


def test_friction_no_barrels_is_friction_without_its_barrels(friction: World) -> None:
    variant = load("friction_no_barrels")
    barrels = [name for name in friction.names if name.startswith("Construction Barrel")]
    assert variant.models == friction.without(barrels).models


def test_friction_goal_is_on_the_green_tile(friction: World) -> None:
    assert friction.scenario is not None
    goal_x, goal_y, _ = friction.scenario.goal
    assert support_under(friction, goal_x, goal_y) == "grey_wall_0_clone_clone_1"
