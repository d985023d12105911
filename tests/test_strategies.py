"""The Hypothesis strategies of `pytest_ddenv.strategies` draw valid, simulable worlds, as asked."""

from __future__ import annotations

import itertools
import math
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import find, given, seed, settings
from hypothesis import strategies as st
from hypothesis.errors import InvalidArgument

from pytest_ddenv import Ground, Model, Pose, Scenario, ScenarioError, Shape, World
from pytest_ddenv.scenario.robot_world import RobotWorld
from pytest_ddenv.strategies import (
    DEFAULT_REGION,
    DEFAULT_SCENARIO,
    HUSKY_FOOTPRINT,
    models,
    poses,
    scenarios,
    worlds,
)

ROOT = Path(__file__).resolve().parent.parent
TOLERANCE = 1e-9
REGION = ((0.0, -6.0), (12.0, 6.0))

Box = tuple[np.ndarray, np.ndarray]


# -- checks of a drawn world, with the world's own geometry --------------------------------------------------
def footprint(world: World, name: str) -> Box:
    low, high = world.bounds(name)
    return low[:2], high[:2]


def gap(a: Box, b: Box) -> float:
    """How far apart two axis-aligned rectangles are along the axis that separates them most (< 0: overlap)."""
    (a_low, a_high), (b_low, b_high) = a, b
    return float(max(np.max(b_low - a_high), np.max(a_low - b_high)))


def robot_start(scenario: Scenario) -> Box:
    """The bounds of the robot's footprint at its start pose."""
    length, width = HUSKY_FOOTPRINT
    c, s = math.cos(scenario.start.yaw), math.sin(scenario.start.yaw)
    corners = np.array([[scenario.start.x + c * a - s * b, scenario.start.y + s * a + c * b]
                        for a in (-length / 2, length / 2) for b in (-width / 2, width / 2)])
    return corners.min(axis=0), corners.max(axis=0)


def robot_on_goal(scenario: Scenario) -> Box:
    """The bounds of the robot standing on the goal at any heading."""
    reach = math.hypot(*HUSKY_FOOTPRINT) / 2
    goal = np.array(scenario.goal[:2])
    return goal - reach, goal + reach


def bottom(world: World, name: str) -> float:
    return float(world.bounds(name)[0][2])


def on_top(world: World, name: str) -> list[str]:
    """The models `name` rests on: their top at its bottom, its footprint inside theirs."""
    low, high = world.bounds(name)
    return [other for other in world.names if other != name
            and abs(world.bounds(other)[1][2] - low[2]) < TOLERANCE
            and np.all(world.bounds(other)[0][:2] <= low[:2] + TOLERANCE)
            and np.all(world.bounds(other)[1][:2] >= high[:2] - TOLERANCE)]


def check_valid(world: World, *, region: tuple = DEFAULT_REGION, clearance: float = 0.3) -> None:
    """Every property `worlds()` promises, checked with the world's bounds."""
    ground = world.ground.z if world.ground is not None else 0.0
    (xmin, ymin), (xmax, ymax) = region
    resting = [name for name in world.names if abs(bottom(world, name) - ground) < TOLERANCE]
    for name in world.names:
        assert re.fullmatch(r"(box|cylinder|sphere)_\d+", name), name
        low, high = footprint(world, name)
        assert xmin - TOLERANCE <= low[0] and high[0] <= xmax + TOLERANCE, (name, low, high)
        assert ymin - TOLERANCE <= low[1] and high[1] <= ymax + TOLERANCE, (name, low, high)
        if name not in resting:
            assert len(on_top(world, name)) == 1, f"{name} floats: {world.bounds(name)}"
        if world.scenario is not None:
            assert gap(footprint(world, name), robot_start(world.scenario)) >= clearance - TOLERANCE, name
            assert gap(footprint(world, name), robot_on_goal(world.scenario)) >= clearance - TOLERANCE, name
    for a, b in itertools.combinations(resting, 2):
        assert gap(footprint(world, a), footprint(world, b)) >= clearance - TOLERANCE, (a, b)
    for a, b in itertools.combinations(world.names, 2):  # stacked ones touch what they rest on, no more
        (a_low, a_high), (b_low, b_high) = world.bounds(a), world.bounds(b)
        overlap = np.minimum(a_high, b_high) - np.maximum(a_low, b_low)
        assert np.min(overlap) <= TOLERANCE, (a, b)


def settled_displacements(world: World, seconds: float = 1.0) -> dict[str, float]:
    """How far (m) each dynamic model moves in `seconds` of simulation without the robot."""
    import pybullet as p

    from pytest_ddenv.sim.builder import build_world

    client = p.connect(p.DIRECT)
    try:
        p.setGravity(*world.physics.gravity, physicsClientId=client)
        p.setTimeStep(world.physics.timestep, physicsClientId=client)
        bodies = build_world(p, client, world)
        dynamic = {body: name for body, name in bodies.items() if name in world and world.model(name).dynamic}
        before = {body: np.array(p.getBasePositionAndOrientation(body, physicsClientId=client)[0])
                  for body in dynamic}
        for _ in range(round(seconds / world.physics.timestep)):
            p.stepSimulation(physicsClientId=client)
        return {name: float(np.linalg.norm(
                    np.array(p.getBasePositionAndOrientation(body, physicsClientId=client)[0]) - before[body]))
                for body, name in dynamic.items()}
    finally:
        p.disconnect(physicsClientId=client)


# -- the property ---------------------------------------------------------------------------------------------
@pytest.mark.pybullet  # settled_displacements steps pybullet
@given(world=worlds(scenarios(start=REGION, goal=REGION), count=(5, 30), region=REGION, stacked=0.3))
@settings(max_examples=25, deadline=None)
def test_drawn_worlds_round_trip_do_not_overlap_and_simulate(world: World) -> None:
    assert World.from_yaml(world.to_yaml()) == world
    check_valid(world, region=REGION)
    run = RobotWorld(world).run(timeout=1.0)  # ScenarioError if the robot started inside a model
    assert run.footprint == HUSKY_FOOTPRINT
    assert min(run.first_touch.values(), default=math.inf) > 0.1, run.first_touch
    assert max(settled_displacements(world).values(), default=0.0) < 0.005


@given(world=worlds(count=30, region=REGION, stacked=0.5))
def test_thirty_models_with_default_settings_raise_no_health_check(world: World) -> None:
    assert len(world) == 30
    check_valid(world, region=REGION)


def test_the_husky_footprint_is_the_simulated_husky_s() -> None:
    from pytest_ddenv.sim import ROBOTS

    assert ROBOTS["husky"]().footprint == HUSKY_FOOTPRINT
    assert DEFAULT_SCENARIO.robot == "husky"


def test_a_model_on_the_robot_s_start_is_what_the_simulation_refuses() -> None:
    """The keep-out matters: the same check the strategies avoid fires for a model under the robot."""
    crate = Model("crate", (Shape("box", size=(0.4, 0.4, 0.4)),), pose=Pose(0.3, 0.0, 0.2))
    with pytest.raises(ScenarioError, match="the robot's start pose is inside crate"):
        RobotWorld(World(models=(crate,), scenario=DEFAULT_SCENARIO)).run(timeout=0.5)


# -- the parameters -------------------------------------------------------------------------------------------
@given(world=worlds(count=7, scenario=None, region=((20.0, 20.0), (30.0, 25.0)), clearance=1.0))
@settings(max_examples=20)
def test_count_region_and_clearance(world: World) -> None:
    assert len(world) == 7 and world.scenario is None and world.ground == Ground()
    check_valid(world, region=((20.0, 20.0), (30.0, 25.0)), clearance=1.0)


@given(world=worlds(count=(2, 4), kinds=("cylinder",), size=(0.3, 0.5), mass=(2.0, 3.0), friction=(0.1, 0.2),
                    static=False, ground=Ground(z=-1.0, mu=50.0)))
@settings(max_examples=20)
def test_kinds_sizes_physics_and_ground(world: World) -> None:
    assert 2 <= len(world) <= 4 and world.ground == Ground(z=-1.0, mu=50.0)
    for model in world:
        (shape,) = model.shapes
        assert shape.kind == "cylinder" and shape.radius is not None and shape.length is not None
        assert 0.3 <= 2 * shape.radius <= 0.5 and 0.3 <= shape.length <= 0.5
        assert model.dynamic and model.mass is not None and 2.0 <= model.mass <= 3.0
        assert 0.1 <= model.mu == model.mu2 <= 0.2
        assert bottom(world, model.name) == pytest.approx(-1.0)


def test_overlap_true_lets_models_overlap_and_holds_more_than_the_cells() -> None:
    found = find(worlds(count=(2, 10), scenario=None, overlap=True, region=((0.0, 0.0), (3.0, 3.0))),
                 lambda world: any(gap(footprint(world, a), footprint(world, b)) < 0
                                   for a, b in itertools.combinations(world.names, 2)))
    assert len(found) == 2
    with pytest.raises(InvalidArgument):
        worlds(count=10, scenario=None, region=((0.0, 0.0), (3.0, 3.0)))
    crowded = find(worlds(count=10, scenario=None, overlap=True, region=((0.0, 0.0), (3.0, 3.0))),
                   lambda world: True)
    assert len(crowded) == 10


@pytest.mark.pybullet  # settled_displacements steps pybullet
def test_stacked_puts_small_models_on_boxes_and_cylinders() -> None:
    world = find(worlds(count=(0, 10), stacked=1.0),
                 lambda world: any(bottom(world, name) > 0.0 for name in world.names))
    (upper,) = [name for name in world.names if bottom(world, name) > 0.0]
    (lower,) = on_top(world, upper)
    assert world.model(lower).shapes[0].kind in ("box", "cylinder")
    check_valid(world)
    assert max(settled_displacements(world).values(), default=0.0) < 0.005
    flat = find(worlds(count=10), lambda world: True)  # stacked=0: everything on the ground
    assert all(bottom(flat, name) == 0.0 for name in flat.names)


def test_templates_are_moved_to_the_ground_and_named_after_themselves() -> None:
    plan = World.load(ROOT / "worlds/cul_de_sac.yaml")
    templates = [plan.model("crate_1"), plan.model("barrel_1")]
    world = find(worlds(count=4, templates=templates, kinds=()),
                 lambda world: {name.rsplit("_", 1)[0] for name in world.names} == {"crate_1", "barrel_1"})
    for index, model in enumerate(world):
        template, number = model.name.rsplit("_", 1)
        assert number == str(index)
        assert model.shapes == plan.model(template).shapes and model.mass == plan.model(template).mass
        assert bottom(world, model.name) == pytest.approx(0.0, abs=TOLERANCE)
    assert World.from_yaml(world.to_yaml()) == world
    RobotWorld(world).run(timeout=0.5)


def test_templates_from_a_world_file_keep_finding_their_meshes(tmp_path: Path) -> None:
    import trimesh

    (tmp_path / "meshes").mkdir()
    trimesh.creation.box(extents=(0.4, 0.3, 0.2)).export(tmp_path / "meshes/brick.stl")
    (tmp_path / "bricks.yaml").write_text("format: 1\nmodels:\n"
                                          "- {name: brick, pose: [5, 5, 3], mesh: {file: meshes/brick.stl}}\n")
    world = find(worlds(count=2, templates=World.load(tmp_path / "bricks.yaml"), kinds=()), lambda world: True)
    assert Path(world.models[0].shapes[0].mesh or "").is_absolute()
    assert bottom(world, "brick_0") == pytest.approx(0.0, abs=1e-6)
    assert World.from_yaml(world.to_yaml()) == world
    RobotWorld(world).run(timeout=0.5)


@given(model=models(size=(0.1, 0.2), static=True, name="thing"))
@settings(max_examples=20)
def test_a_model_rests_on_the_ground_at_the_origin(model: Model) -> None:
    world = World(models=(model,))
    low, high = world.bounds("thing")
    assert low[2] == pytest.approx(0.0, abs=TOLERANCE) and model.static and model.mass is None
    assert np.allclose((low[:2] + high[:2]) / 2, 0.0, atol=TOLERANCE)
    assert np.all(high - low <= 0.2 * math.sqrt(2) + TOLERANCE)


@given(model=models(pose=poses(((1.0, 1.0), (2.0, 2.0)), z=0.5)),
       crate=models(template=Model("crate", (Shape("box", size=(1.0, 0.5, 0.2)),), pose=Pose(9, 9, 9, 0.3, 0, 0)),
                    pose=Pose(-3.0, 4.0, 0.0), yaw=False))
@settings(max_examples=20)
def test_a_model_goes_to_its_pose_and_a_template_keeps_its_shape(model: Model, crate: Model) -> None:
    world = World(models=(model, crate))
    assert World.from_yaml(world.to_yaml()) == world
    low, high = world.bounds(model.name)
    assert low[2] == pytest.approx(0.5) and np.all((low[:2] + high[:2]) / 2 >= 1.0 - TOLERANCE)
    low, high = world.bounds("crate")
    assert low[2] == pytest.approx(0.0, abs=TOLERANCE)
    assert np.allclose((low[:2] + high[:2]) / 2, (-3.0, 4.0)) and crate.pose.roll == pytest.approx(0.3)


@given(scenario=scenarios(start=((0.0, 0.0), (1.0, 1.0)), goal=((5.0, 5.0), (6.0, 6.0)), timeout=(10.0, 20.0),
                          goal_tolerance=0.5))
@settings(max_examples=20)
def test_scenarios_draw_start_goal_and_timeout(scenario: Scenario) -> None:
    assert 0.0 <= scenario.start.x <= 1.0 and 0.0 <= scenario.start.y <= 1.0 and scenario.start.z == 0.0
    assert 5.0 <= scenario.goal[0] <= 6.0 and 5.0 <= scenario.goal[1] <= 6.0 and scenario.goal[2] is None
    assert 10.0 <= scenario.timeout <= 20.0 and scenario.goal_tolerance == 0.5 and scenario.robot == "husky"


def test_examples_shrink_to_fewer_and_smaller_static_models() -> None:
    world = find(worlds(count=(0, 10), size=(0.25, 0.8)), lambda world: len(world) >= 2)
    assert len(world) == 2
    for model in world:
        assert model.static
        low, high = world.bounds(model.name)
        assert np.allclose(high - low, 0.25)


def test_the_same_seed_draws_the_same_worlds() -> None:
    def drawn() -> list[World]:
        seen: list[World] = []

        @seed(1234)
        @settings(max_examples=5, database=None)
        @given(worlds(count=(1, 5), stacked=0.5))
        def collect(world: World) -> None:
            seen.append(world)

        collect()
        return seen

    assert drawn() == drawn()


def test_a_strategy_shows_the_call_that_made_it() -> None:
    assert repr(worlds(count=(3, 12), stacked=0.2)) == "worlds(count=(3, 12), stacked=0.2)"
    assert repr(models(size=(0.1, 0.3))) == "models(size=(0.1, 0.3))"
    assert repr(scenarios()) == "scenarios()" and repr(poses()) == "poses()"


# -- impossible requests fail when the strategy is built --------------------------------------------------------
def test_too_many_models_for_the_region_is_refused_at_once_with_a_larger_region_to_use() -> None:
    with pytest.raises(InvalidArgument, match=r"worlds\(count=30\): 30 model\(s\) need 30 cell\(s\) of 1.432 x "
                                              r"1.432 m .* the region, 3 x 3 m, holds 2 x 2 cells.*Use a larger "
                                              r"region \(about 8.6 x 8.6 m\)"):
        worlds(count=(0, 30), region=((0.0, 0.0), (3.0, 3.0)), scenario=None)
    with pytest.raises(InvalidArgument, match="a drawn scenario's start and goal may keep"):
        worlds(scenarios(start=REGION), count=60, region=REGION)


@pytest.mark.parametrize(("arguments", "message"), [
    ({"count": (5, 2)}, r"worlds\(count=...\): expected 0 <= lowest <= highest"),
    ({"count": 2.5}, r"worlds\(count=...\): expected a whole number"),
    ({"size": (0.5, 0.1)}, r"worlds\(size=...\): the lowest value 0.5 is above the highest 0.1"),
    ({"size": (0.0, 0.1)}, r"worlds\(size=...\): expected finite numbers > 0"),
    ({"size": (0.1001, 0.1002)}, r"holds no multiple of 0.001"),
    ({"kinds": ("mesh",)}, r"worlds\(kinds=...\): unknown kind\(s\) \['mesh'\]"),
    ({"kinds": ()}, r"no kinds and no templates: nothing to draw"),
    ({"stacked": 1.5}, r"worlds\(stacked=...\): expected a probability from 0 to 1"),
    ({"region": ((1, 1), (0, 2))}, r"expected xmin < xmax and ymin < ymax"),
    ({"scenario": Scenario(robot="rover")}, r"robot is 'rover'.*pass robot_footprint=\(length, width\)"),
    ({"robot_footprint": (1.0, -1.0)}, r"worlds\(robot_footprint=...\): expected \(length, width\)"),
    ({"templates": ["crate"]}, r"worlds\(templates=...\): expected a World or a sequence of Models"),
])
def test_bad_arguments_are_refused_when_the_strategy_is_built(arguments: dict, message: str) -> None:
    with pytest.raises(InvalidArgument, match=message):
        worlds(**arguments)


def test_a_robot_of_your_own_needs_its_footprint_and_gets_it_kept_clear() -> None:
    rover = Scenario(robot="rover", start=Pose(5.0, 0.0), goal=(9.0, 0.0, None))
    strategy = worlds(rover, robot_footprint=(3.0, 2.0), count=(5, 10))

    @given(strategy)
    @settings(max_examples=10)
    def check(world: World) -> None:
        for name in world.names:
            assert gap(footprint(world, name), (np.array([3.5, -1.0]), np.array([6.5, 1.0]))) >= 0.3 - TOLERANCE

    check()


def test_draws_in_a_plain_given_with_other_values() -> None:
    @given(world=worlds(count=(1, 3)), speed=st.floats(0.1, 1.0))
    @settings(max_examples=5)
    def check(world: World, speed: float) -> None:
        assert 1 <= len(world) <= 3 and 0.1 <= speed <= 1.0

    check()
