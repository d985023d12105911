"""Wheeled robots described by their URDF (the `scenario.robot` mapping): measured, driven, recorded,
written back, and refused with a clear error when the description does not fit the URDF."""

from __future__ import annotations

import dataclasses
import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from helpers import flat_world

from pytest_ddenv.errors import ScenarioError
from pytest_ddenv.sim import Run, Simulator, WheelCommand, WheeledRobot, urdf_geometry
from pytest_ddenv.sim.robot import husky_urdf, make_robot
from pytest_ddenv.world import LaserMount, RobotDescription, Scenario, World

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "robots"
DIFFBOT_URDF = EXAMPLE / "diffbot.urdf"
DIFFBOT = RobotDescription(urdf=str(DIFFBOT_URDF), left_wheels=("left_wheel_joint",),
                           right_wheels=("right_wheel_joint",))


def with_robot(world: World, robot: str | RobotDescription) -> World:
    assert world.scenario is not None
    return dataclasses.replace(world, scenario=dataclasses.replace(world.scenario, robot=robot))


def husky_description() -> RobotDescription:
    return RobotDescription(
        urdf=husky_urdf(),  # pybullet_data's, or without pybullet the package's copy
        left_wheels=("front_left_wheel", "rear_left_wheel"), right_wheels=("front_right_wheel", "rear_right_wheel"),
        drive="skid-steer", wheel_radius=0.17775, track=0.5708, max_wheel_torque=100.0,
        laser=LaserMount(height=0.35, min_range=0.62),
    )


# -- the example robot --------------------------------------------------------------------------------
def urdf_wheels(path: Path) -> dict[str, tuple[float, float]]:
    """Wheel joint name -> (collision cylinder radius, lateral joint position), read from the URDF's XML."""
    root = ET.parse(path).getroot()
    radius = {link.get("name"): float(cylinder.get("radius", "nan")) for link in root.iter("link")
              for cylinder in link.iterfind("collision/geometry/cylinder")}
    wheels = {}
    for joint in root.iter("joint"):
        child, origin = joint.find("child"), joint.find("origin")
        if joint.get("type") == "continuous" and child is not None and origin is not None:
            wheels[joint.get("name", "")] = (radius[child.get("link")], float(origin.get("xyz", "0 0 0").split()[1]))
    return wheels


def test_example_diffbot_loads_from_yaml_and_its_geometry_matches_the_urdf() -> None:
    world = World.load(EXAMPLE / "diffbot_world.yaml")
    assert world.scenario is not None and isinstance(world.scenario.robot, RobotDescription)
    description = world.scenario.robot
    assert (description.drive, description.left_wheels, description.right_wheels) == (
        "differential", ("left_wheel_joint",), ("right_wheel_joint",))
    robot = make_robot(description, world.source)
    assert isinstance(robot, WheeledRobot) and robot.name == "diffbot"
    wheels = urdf_wheels(DIFFBOT_URDF)
    assert robot.wheel_radius == pytest.approx(wheels["left_wheel_joint"][0], abs=1e-6)
    assert robot.track == pytest.approx(wheels["left_wheel_joint"][1] - wheels["right_wheel_joint"][1], abs=1e-6)
    assert robot.track_factor == 1.0
    assert robot.footprint == pytest.approx((0.45, 0.44), abs=0.01)  # chassis length; wheel to wheel
    assert robot.base_height == pytest.approx(0.08, abs=0.005)  # the base frame is at the wheel axles
    laser = robot.laser
    assert laser is not None and 0.09 < laser.height < 0.2 and 0.3 < laser.min_range < 0.45  # just above/outside


@pytest.mark.pybullet
@pytest.mark.mujoco
def test_without_pybullet_mujoco_measures_the_urdf_as_pybullet_does(monkeypatch: pytest.MonkeyPatch) -> None:
    """Where pybullet is not installed, MuJoCo compiles the URDF and measures it (sim/urdf_mujoco.py): the same
    wheels and track, the footprint and base height but for pybullet's 1 mm collision margin, the laser within
    3 cm, the same mass."""
    left, right = DIFFBOT.left_wheels, DIFFBOT.right_wheels
    by_pybullet = urdf_geometry.measure_urdf(str(DIFFBOT_URDF), make_robot(DIFFBOT)._flags(), left, right)
    monkeypatch.setattr(urdf_geometry, "_cache", {})
    monkeypatch.setattr(urdf_geometry, "pybullet_installed", lambda: False)
    by_mujoco = urdf_geometry.measure_urdf(str(DIFFBOT_URDF), 0, left, right)
    assert (by_mujoco.wheel_radius, by_mujoco.track, by_mujoco.mass) == pytest.approx(
        (by_pybullet.wheel_radius, by_pybullet.track, by_pybullet.mass), abs=1e-6)
    assert by_mujoco.footprint == pytest.approx(by_pybullet.footprint, abs=0.0025)
    assert by_mujoco.base_height == pytest.approx(by_pybullet.base_height, abs=0.0015)
    assert by_mujoco.laser.height == pytest.approx(by_pybullet.laser.height, abs=0.035)
    assert by_mujoco.laser.min_range == pytest.approx(by_pybullet.laser.min_range, abs=0.005)
    assert by_mujoco.footprint != by_pybullet.footprint  # measured by MuJoCo: no collision margin


def test_diffbot_drives_to_a_goal_on_flat_ground(sim: Simulator) -> None:
    run = sim.run(flat_world(goal=(4.0, 1.0), timeout=15.0, robot=DIFFBOT), seed=0)  # type: ignore[arg-type]
    assert run.reached_goal and run.failure is None
    assert run.goal_time is not None and run.goal_time < 10.0


def test_run_records_the_robot_name_and_footprint(sim: Simulator) -> None:
    named = dataclasses.replace(DIFFBOT, name="rover")
    run = sim.run(flat_world(goal=(1.0, 0.0), timeout=3.0, robot=named), seed=0)  # type: ignore[arg-type]
    assert run.robot == "rover" and run.footprint == pytest.approx((0.45, 0.44), abs=0.01)
    assert run.wheel_contacts.shape[1] == 2
    back = Run.from_dict(run.to_dict())
    assert back.robot == "rover" and back.footprint == run.footprint
    husky = sim.run(flat_world(goal=(1.0, 0.0), timeout=2.0), seed=0)
    assert husky.robot == "husky" and husky.footprint == (0.99, 0.67)


def test_wheel_command_drives_the_diffbot_forward() -> None:
    world = flat_world(goal=(10.0, 0.0), timeout=2.0, robot=DIFFBOT)  # type: ignore[arg-type]
    with Simulator() as simulator:
        run = simulator.run(world, controller=lambda observation: WheelCommand(5.0, 5.0))
    x, y = run.positions[-1, :2]
    # 5 rad/s x 0.08 m = 0.4 m/s for 2 s, less the start-up
    assert 0.5 < x < 0.85 and abs(y) < 0.05 and abs(run.poses[-1, 5]) < 0.05


def test_docs_example_is_the_example_world() -> None:
    import re

    page = (EXAMPLE.parent.parent / "docs" / "world-format.md").read_text()
    marker = "<!-- checked by tests/sim/test_urdf_robot.py::test_docs_example_is_the_example_world -->\n~~~yaml\n"
    block = re.search(re.escape(marker) + r"(.*?)~~~", page, flags=re.DOTALL)
    assert block is not None
    source = EXAMPLE / "diffbot_world.yaml"
    documented, example = World.from_yaml(block[1], source=source), World.load(source)
    assert documented.scenario == example.scenario and documented.name == example.name
    assert documented.models == example.select(["loading_dock"]).models


# -- kinematics from the description ------------------------------------------------------------------
def test_skid_steer_defaults_to_track_factor_one_and_a_half() -> None:
    skid = WheeledRobot.from_description(dataclasses.replace(DIFFBOT, drive="skid-steer"))
    assert skid.track_factor == 1.5
    assert WheeledRobot.from_description(DIFFBOT).track_factor == 1.0
    given = WheeledRobot.from_description(dataclasses.replace(DIFFBOT, drive="skid-steer", track_factor=1.2))
    assert given.track_factor == 1.2


def test_explicit_wheel_radius_and_track_override_the_urdf() -> None:
    robot = WheeledRobot.from_description(dataclasses.replace(DIFFBOT, wheel_radius=0.1, track=0.5))
    assert (robot.wheel_radius, robot.track) == (0.1, 0.5)
    assert robot.footprint == pytest.approx((0.45, 0.44), abs=0.01)  # still measured


def test_husky_as_a_description_reaches_the_goal(sim: Simulator) -> None:
    robot = make_robot(husky_description())
    assert isinstance(robot, WheeledRobot)
    assert (robot.name, robot.track_factor, robot.max_force) == ("husky", 1.5, 100.0)
    assert robot.footprint == pytest.approx((0.99, 0.67), abs=0.03)
    run = sim.run(flat_world(goal=(6.0, 0.0), timeout=20.0, robot=husky_description()), seed=0)  # type: ignore[arg-type]
    assert run.reached_goal and run.robot == "husky"


# -- writing the mapping back -------------------------------------------------------------------------
def test_mapping_round_trips_through_yaml_from_another_folder(tmp_path: Path,
                                                               monkeypatch: pytest.MonkeyPatch) -> None:
    world = World.load(EXAMPLE / "diffbot_world.yaml")
    assert World.from_yaml(world.to_yaml(), source=world.source) == world
    monkeypatch.chdir(tmp_path)
    (tmp_path / "out").mkdir()
    world.save(Path("out") / "x.yaml")
    text = (tmp_path / "out" / "x.yaml").read_text()
    assert "urdf: diffbot.urdf" not in text  # rebased onto out/
    back = World.load(tmp_path / "out" / "x.yaml")
    assert back.scenario is not None and isinstance(back.scenario.robot, RobotDescription)
    assert not Path(back.scenario.robot.urdf).is_absolute()
    assert (tmp_path / "out" / back.scenario.robot.urdf).resolve() == DIFFBOT_URDF
    assert back.models == world.models
    assert world.scenario is not None
    assert dataclasses.replace(back.scenario.robot, urdf="") == dataclasses.replace(world.scenario.robot, urdf="")
    assert make_robot(back.scenario.robot, back.source).name == "diffbot"


def test_mapping_round_trips_through_sdf(tmp_path: Path) -> None:
    description = dataclasses.replace(DIFFBOT, drive="skid-steer", wheel_radius=0.081, track_factor=1.3,
                                      laser=LaserMount(0.2, 0.5), name="rover")
    world = with_robot(World.load(EXAMPLE / "diffbot_world.yaml"), description)
    world.save(tmp_path / "x.sdf")
    back = World.load(tmp_path / "x.sdf")
    assert back.scenario == world.scenario and back.names == world.names
    no_laser = with_robot(world, dataclasses.replace(DIFFBOT, laser=False))
    no_laser.save(tmp_path / "y.sdf")
    assert World.load(tmp_path / "y.sdf").scenario == no_laser.scenario


def test_a_relative_urdf_in_an_sdf_file_is_relative_to_that_file(tmp_path: Path) -> None:
    (tmp_path / "robots").mkdir()
    (tmp_path / "robots" / "diffbot.urdf").write_text(DIFFBOT_URDF.read_text())
    (tmp_path / "worlds").mkdir()
    world = with_robot(World(scenario=Scenario(goal=(2.0, 0.0, None))), DIFFBOT)
    text = world.to_sdf().replace(f'urdf="{DIFFBOT_URDF}"', 'urdf="../robots/diffbot.urdf"')
    assert 'urdf="../robots/diffbot.urdf"' in text
    (tmp_path / "worlds" / "hand.sdf").write_text(text)
    loaded = World.load(tmp_path / "worlds" / "hand.sdf")
    assert loaded.scenario is not None and isinstance(loaded.scenario.robot, RobotDescription)
    assert make_robot(loaded.scenario.robot, loaded.source).name == "diffbot"


# -- bad input ----------------------------------------------------------------------------------------
def robot_urdf(*, left_y: float = 0.2, right_y: float = -0.2, left_collision: bool = True) -> str:
    """A small two-wheeled robot's URDF with the wheel positions and the left wheel's collision as asked."""

    def wheel(side: str, y: float, collision: bool) -> str:
        shape = '<geometry><cylinder radius="0.1" length="0.04"/></geometry>'
        return f"""
  <link name="{side}_wheel">
    <inertial><mass value="0.5"/><inertia ixx="0.001" ixy="0" ixz="0" iyy="0.002" iyz="0" izz="0.001"/></inertial>
    <visual><origin rpy="1.5708 0 0"/>{shape}</visual>
    {f'<collision><origin rpy="1.5708 0 0"/>{shape}</collision>' if collision else ''}
  </link>
  <joint name="{side}_joint" type="continuous">
    <parent link="base"/><child link="{side}_wheel"/><origin xyz="0 {y} 0"/><axis xyz="0 1 0"/>
  </joint>"""

    return f"""<?xml version="1.0"?>
<robot name="twowheel">
  <link name="base">
    <inertial><mass value="5"/><inertia ixx="0.05" ixy="0" ixz="0" iyy="0.05" iyz="0" izz="0.05"/></inertial>
    <collision><origin xyz="0 0 0.05"/><geometry><box size="0.4 0.3 0.1"/></geometry></collision>
  </link>{wheel("left", left_y, left_collision)}{wheel("right", right_y, True)}
</robot>
"""


WORLD_YAML = """\
format: 1
scenario:
  robot: {robot}
  start: {{x: 0, y: 0, yaw: 0}}
  goal: {{x: 2, y: 0}}
  timeout: 5
"""


def world_with(tmp_path: Path, robot: str, urdf: str | None = None) -> World:
    """A world file in `tmp_path` whose scenario.robot is `robot` (YAML flow mapping), `urdf` beside it."""
    if urdf is not None:
        (tmp_path / "robot.urdf").write_text(urdf)
    path = tmp_path / "bad.yaml"
    path.write_text(WORLD_YAML.format(robot=robot))
    return World.load(path)


GOOD = "{urdf: robot.urdf, left_wheels: [left_joint], right_wheels: [right_joint]"


@pytest.mark.parametrize(("robot", "field", "words"), [
    ("{urdf: nowhere.urdf, left_wheels: [a], right_wheels: [b]}", "scenario.robot.urdf", "nowhere.urdf"),
    (GOOD + ", drive: tank}", "scenario.robot.drive", "differential, skid-steer"),
    ("{urdf: robot.urdf, left_wheels: [], right_wheels: [right_joint]}", "scenario.robot.left_wheels", "non-empty"),
    ("{urdf: robot.urdf, left_wheels: [left_joint]}", "scenario.robot.right_wheels", "missing"),
    (GOOD + ", laser: {height: 0.3}}", "scenario.robot.laser.min_range", "missing"),
    (GOOD + ", laser: {height: 0.3, min_range: 0.5, fov: 3}}", "scenario.robot.laser.fov", "unknown key"),
    (GOOD + ", laser: yes please}", "scenario.robot.laser", "true, false or a mapping"),
    (GOOD + ", laser: {height: 0.3, min_range: -1}}", "scenario.robot.laser.min_range", ">= 0"),
    (GOOD + ", wheel_radius: 0}", "scenario.robot.wheel_radius", "positive"),
    (GOOD + ", colour: red}", "scenario.robot.colour", "unknown key"),
    ("{urdf: robot.urdf, left_wheels: [left_joint], right_wheels: [left_joint]}", "scenario.robot.right_wheels",
     "also in left_wheels"),
])
def test_bad_mapping_is_refused_when_the_world_is_read(tmp_path: Path, robot: str, field: str, words: str) -> None:
    with pytest.raises(ScenarioError) as caught:
        world_with(tmp_path, robot, robot_urdf())
    assert caught.value.field == field, str(caught.value)
    assert str(tmp_path / "bad.yaml") in str(caught.value) and words in str(caught.value)


@pytest.mark.parametrize(("robot", "urdf", "field", "words"), [
    (GOOD.replace("[left_joint]", "[left_joint, middle_joint]") + "}", robot_urdf(), "scenario.robot.left_wheels",
     "no joint named 'middle_joint'; its joints: left_joint, right_joint"),
    (GOOD.replace("[right_joint]", "[rigth_joint]") + "}", robot_urdf(), "scenario.robot.right_wheels",
     "no joint named 'rigth_joint'"),
    (GOOD + "}", robot_urdf(left_collision=False), "scenario.robot.left_wheels",
     "'left_wheel' of wheel joint 'left_joint' has no collision shape"),
    (GOOD + "}", robot_urdf(left_y=0.0, right_y=0.0), "scenario.robot.track",
     "the left and right wheels are at the same lateral position"),
    (GOOD + "}", robot_urdf(left_y=-0.2, right_y=0.2), "scenario.robot.left_wheels", "swap left_wheels and right"),
])
def test_mapping_that_does_not_fit_the_urdf_is_refused(sim: Simulator, tmp_path: Path, robot: str, urdf: str,
                                                       field: str, words: str) -> None:
    world = world_with(tmp_path, robot, urdf)
    with pytest.raises(ScenarioError) as caught:
        sim.run(world)
    assert caught.value.field == field, str(caught.value)
    message = str(caught.value)
    assert str(tmp_path / "bad.yaml") in message and str(tmp_path / "robot.urdf") in message and words in message


def test_an_explicit_track_needs_no_lateral_wheel_distance(tmp_path: Path) -> None:
    world = world_with(tmp_path, GOOD + ", track: 0.4}", robot_urdf(left_y=0.0, right_y=0.0))
    assert world.scenario is not None
    robot = make_robot(world.scenario.robot, world.source)
    assert isinstance(robot, WheeledRobot) and robot.track == 0.4


def test_unknown_drive_in_python_is_refused() -> None:
    with pytest.raises(ScenarioError, match="unknown drive 'tank'") as caught:
        WheeledRobot(DIFFBOT_URDF, left_wheels=["left_wheel_joint"], right_wheels=["right_wheel_joint"], drive="tank")
    assert caught.value.field == "scenario.robot.drive"


def test_a_registered_description_names_its_robot_in_errors(monkeypatch: pytest.MonkeyPatch) -> None:
    from pytest_ddenv.sim import ROBOTS, register_robot

    monkeypatch.setattr("pytest_ddenv.sim.robot.ROBOTS", dict(ROBOTS))
    with pytest.raises(ValueError, match=r"register_robot\('ghost', \.\.\.\) at test_urdf_robot\.py:\d+: URDF file "
                                         r"not found: ghost\.urdf \(a relative path is taken from the current folder"):
        register_robot("ghost", dataclasses.replace(DIFFBOT, urdf="ghost.urdf"))
    register_robot("wrong_wheels", dataclasses.replace(DIFFBOT, left_wheels=("left_whel_joint",)))
    with pytest.raises(ScenarioError, match=r"robot 'wrong_wheels' \(registered at test_urdf_robot\.py:\d+\): .*"
                                            r"has no joint named 'left_whel_joint'"):
        make_robot("wrong_wheels")


# -- the laser's mounting ---------------------------------------------------------------------------------
MOUNTED = LaserMount(0.2, 0.5, x=0.15, y=-0.05, yaw=0.3)


def test_a_laser_mounting_round_trips_through_yaml_and_sdf(tmp_path: Path) -> None:
    world = with_robot(World.load(EXAMPLE / "diffbot_world.yaml"), dataclasses.replace(DIFFBOT, laser=MOUNTED))
    assert "yaw: 0.3" in world.to_yaml()
    assert World.from_yaml(world.to_yaml(), source=world.source).scenario == world.scenario
    world.save(tmp_path / "x.sdf")
    assert World.load(tmp_path / "x.sdf").scenario == world.scenario
    assert 'laser="0.2 0.5 0.15 -0.05 0.3"' in (tmp_path / "x.sdf").read_text()


def test_a_bad_laser_mounting_in_sdf_names_the_field(tmp_path: Path) -> None:
    world = with_robot(World.load(EXAMPLE / "diffbot_world.yaml"), dataclasses.replace(DIFFBOT, laser=MOUNTED))
    world.save(tmp_path / "x.sdf")
    text = (tmp_path / "x.sdf").read_text().replace('laser="0.2 0.5 0.15 -0.05 0.3"', 'laser="0.2 0.5 0.15"')
    (tmp_path / "y.sdf").write_text(text)
    with pytest.raises(ScenarioError, match=r"laser.*expected true, false, 'HEIGHT MIN_RANGE' or 'HEIGHT MIN_RANGE "
                                            r"X Y YAW', got '0.2 0.5 0.15'"):
        World.load(tmp_path / "y.sdf")


def first_scan(sim: Simulator, mount: LaserMount) -> tuple[np.ndarray, np.ndarray]:
    """The first scan's hits in the robot's frame and its angles, of a Husky with its laser at `mount`
    standing 3 m before a wall."""
    from helpers import box

    from pytest_ddenv import Command, Observation

    seen: list[Observation] = []

    def still(observation: Observation) -> Command:
        seen.append(observation)
        return Command(0.0, 0.0)

    robot = dataclasses.replace(husky_description(), laser=mount)
    world = flat_world(box("wall", (0.3, 6.0, 1.0), (3.0, 0.0, 0.5)), robot="husky", timeout=0.2)
    sim.run(with_robot(world, robot), seed=0, controller=still)
    assert seen[0].scan is not None
    return seen[0].scan.points(), seen[0].scan.angles


def test_the_laser_sees_from_where_it_is_mounted(sim: Simulator) -> None:
    centre_points, centre_angles = first_scan(sim, LaserMount(0.35, 0.62))
    ahead_points, _ = first_scan(sim, LaserMount(0.35, 0.62, x=0.3))
    turned_points, turned_angles = first_scan(sim, LaserMount(0.35, 0.62, yaw=math.pi / 2))
    np.testing.assert_allclose(turned_angles, centre_angles + math.pi / 2)  # angles in the robot's frame
    for points in (centre_points, ahead_points, turned_points):  # the wall is where it is, however mounted
        facing = points[np.abs(points[:, 1]) < 0.5]
        assert len(facing) >= 3 and np.all(np.abs(facing[:, 0] - 2.85) < 0.1), facing
