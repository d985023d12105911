"""An arm's world in YAML and SDF: read, written back unchanged, and each bad field one clear error."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from pytest_ddenv import ArmDescription, World
from pytest_ddenv.errors import ScenarioError, WorldError
from pytest_ddenv.sim.arm.robot import PANDA, ArmRobot
from pytest_ddenv.sim.robot import check_robot

PANDA_URDF = Path(PANDA.urdf)
ARM_MAPPING = f"""\
    robot:
      urdf: {PANDA_URDF}
      arm_joints: [panda_joint1, panda_joint2, panda_joint3, panda_joint4, panda_joint5, panda_joint6, panda_joint7]
      finger_joints: [panda_finger_joint1, panda_finger_joint2]
      end_effector: panda_grasptarget
      home: [0, -0.785, 0, -2.356, 0, 1.571, 0.785]
      name: my_panda"""


def arm_world(robot: str = "robot: panda", extra: str = "target: cube\n  table: table\n  watch: [mug]") -> str:
    return textwrap.dedent("""\
        format: 1
        scenario:
          {robot}
          start: {{x: 0, y: 0, z: 0.4}}
          goal: {{x: 0.45, y: 0.3}}
          timeout: 10
          {extra}
        models:
          - {{name: table, pose: [0.3, 0, 0.2], box: [1, 1, 0.4]}}
          - {{name: cube, pose: [0.5, 0, 0.425], box: [0.05, 0.05, 0.05], mass: 0.1}}
          - {{name: mug, pose: [0.5, -0.3, 0.45], cylinder: {{radius: 0.04, length: 0.1}}, mass: 0.3}}
        """).format(robot=robot, extra=extra)


def mapped_world() -> World:
    robot = textwrap.indent(textwrap.dedent(ARM_MAPPING), "  ").strip()
    return World.from_yaml(arm_world(robot))


def test_an_arm_mapping_is_read_as_an_arm_description() -> None:
    scenario = mapped_world().scenario
    assert scenario is not None and isinstance(scenario.robot, ArmDescription)
    assert scenario.robot.arm_joints == PANDA.arm_joints and scenario.robot.end_effector == "panda_grasptarget"
    assert scenario.robot.home == pytest.approx(PANDA.home) and scenario.robot.label == "my_panda"
    assert (scenario.target, scenario.table, scenario.watch) == ("cube", "table", ("mug",))


@pytest.mark.parametrize("world", [mapped_world, lambda: World.from_yaml(arm_world())], ids=["mapping", "panda"])
def test_yaml_round_trip(world, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    original = world()
    again = World.from_yaml(original.to_yaml())
    assert again.scenario == original.scenario and again.names == original.names


@pytest.mark.parametrize("world", [mapped_world, lambda: World.from_yaml(arm_world())], ids=["mapping", "panda"])
def test_sdf_round_trip(world, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    original = world()
    path = tmp_path / "arm.sdf"
    path.write_text(original.to_sdf(), encoding="utf-8")
    again = World.load(path).scenario
    assert again == original.scenario


def test_a_reduced_world_writes_only_the_watch_models_it_has(tmp_path: Path) -> None:
    world = World.from_yaml(arm_world()).select(["table", "cube"])
    assert World.from_yaml(world.to_yaml()).scenario.watch == ()  # type: ignore[union-attr]
    path = tmp_path / "reduced.sdf"
    path.write_text(world.to_sdf(), encoding="utf-8")
    assert World.load(path).scenario.watch == ()  # type: ignore[union-attr]


@pytest.mark.parametrize(("extra", "field", "message"), [
    ("target: teapot", "scenario.target", "'teapot' is not a model"),
    ("table: [table]", "scenario.table", "a non-empty string"),
    ("watch: [mug, kettle]", "scenario.watch[1]", "'kettle' is not a model"),
    ("watch: mug", "scenario.watch", "a list of model names"),
])
def test_a_scenario_naming_a_missing_model_says_which_field(extra: str, field: str, message: str) -> None:
    with pytest.raises(ScenarioError, match=message) as caught:
        World.from_yaml(arm_world(extra=extra))
    assert caught.value.field == field


@pytest.mark.parametrize(("change", "field", "message"), [
    (("home: [0, -0.785, 0, -2.356, 0, 1.571, 0.785]", "home: [0, 0]"), "scenario.robot.home", "7 joint positions"),
    (("  end_effector: panda_grasptarget\n", ""), "scenario.robot.end_effector", "missing"),
    ((f"urdf: {PANDA_URDF}", "urdf: nowhere.urdf"), "scenario.robot.urdf", "URDF file not found"),
    (("name: my_panda", "gripper: yes"), "scenario.robot.gripper", "unknown key"),
])
def test_a_bad_arm_mapping_says_which_field(change: tuple[str, str], field: str, message: str) -> None:
    robot = textwrap.indent(textwrap.dedent(ARM_MAPPING).replace(*change), "  ").strip()
    with pytest.raises(WorldError, match=message) as caught:
        World.from_yaml(arm_world(robot))
    assert caught.value.field == field


@pytest.mark.parametrize(("change", "field", "message"), [
    ({"arm_joints": (*PANDA.arm_joints[:6], "elbow")}, "scenario.robot.arm_joints", "no joint named 'elbow'"),
    ({"finger_joints": ("panda_hand_joint",)}, "scenario.robot.finger_joints", "is fixed, it cannot move"),
    ({"finger_joints": ("panda_joint7",)}, "scenario.robot.finger_joints", "both an arm and a finger joint"),
    ({"end_effector": "tool0"}, "scenario.robot.end_effector", "no link named 'tool0'"),
    ({"home": (0.0, 0.0, 0.0, -3.5, 0.0, 0.0, 0.0)}, "scenario.robot.home", "outside joint 'panda_joint4'"),
    ({"arm_joints": ()}, "scenario.robot.arm_joints", "at least one joint"),
])
def test_an_arm_that_does_not_fit_its_urdf_says_which_field(change: dict[str, object], field: str,
                                                             message: str) -> None:
    description = ArmDescription(**{**PANDA.__dict__, **change})  # type: ignore[arg-type]
    with pytest.raises(ScenarioError, match=message) as caught:
        check_robot(description, "world.yaml")
    assert caught.value.field == field and caught.value.source == "world.yaml"


def test_the_panda_is_an_arm_robot_without_a_simulation() -> None:
    robot = ArmRobot(PANDA)
    assert robot.name == "panda" and robot.home == PANDA.home and robot.wheel_links == ()
    assert [j.name for j in robot.fingers] == ["panda_finger_joint1", "panda_finger_joint2"]


def sdf_world(scenario: str) -> str:
    return textwrap.dedent(f"""\
        <sdf version="1.6" xmlns:ddenv="https://github.com/pytest-ddenv/pytest-ddenv/sdf">
          <world name="w">
            {scenario}
            <model name="table"><static>true</static><link name="l"><collision name="c"><geometry>
              <box><size>1 1 0.4</size></box></geometry></collision></link></model>
          </world>
        </sdf>
        """)


WAY = '<ddenv:start x="0" y="0"/><ddenv:goal x="1" y="0"/>'
ARM = f'<ddenv:arm_description urdf="{PANDA_URDF}" arm_joints="a b" finger_joints="f" end_effector="e"'


@pytest.mark.parametrize(("scenario", "field", "message"), [
    (f'<ddenv:scenario robot="panda" target="cube">{WAY}</ddenv:scenario>', "ddenv:scenario/@target",
     "'cube' is not a model"),
    (f'<ddenv:scenario>{WAY}{ARM} home="1"/></ddenv:scenario>', "ddenv:arm_description/@home",
     "expected 2 numbers"),
    (f'<ddenv:scenario>{WAY}{ARM.replace(str(PANDA_URDF), "x.urdf")}/></ddenv:scenario>',
     "ddenv:arm_description/@urdf", "URDF file not found"),
    (f'<ddenv:scenario>{WAY}{ARM}/><ddenv:robot_description urdf="{PANDA_URDF}"/></ddenv:scenario>',
     "ddenv:arm_description", "one robot"),
])
def test_a_bad_sdf_arm_scenario_says_which_attribute(scenario: str, field: str, message: str, tmp_path: Path) -> None:
    path = tmp_path / "w.sdf"
    path.write_text(sdf_world(scenario), encoding="utf-8")
    with pytest.raises(ScenarioError, match=message) as caught:
        World.load(path)
    assert caught.value.field == field


@pytest.mark.pybullet
def test_a_urdf_pybullet_cannot_load_says_so(tmp_path: Path) -> None:
    import dataclasses

    from pytest_ddenv.sim import Simulator

    (tmp_path / "panda.urdf").write_bytes(PANDA_URDF.read_bytes())  # without its meshes
    world = World.from_yaml(arm_world(), source=tmp_path / "world.yaml")
    world = dataclasses.replace(world, scenario=dataclasses.replace(  # type: ignore[arg-type]
        world.scenario, robot=dataclasses.replace(PANDA, urdf="panda.urdf")))
    with Simulator() as sim, pytest.raises(ScenarioError, match="pybullet cannot load the arm's URDF") as caught:
        sim.run(world)
    assert caught.value.field == "scenario.robot.urdf"


def test_the_reduction_keeps_an_arms_table_and_target() -> None:
    from pytest_ddenv.scenario.probe import keeps_start_support

    keeps = keeps_start_support(World.from_yaml(arm_world()))
    assert keeps(frozenset({"table", "cube"})) is None
    assert keeps(frozenset({"table", "mug"})) == "removes 'cube', the arm's target"
    assert keeps(frozenset({"cube", "mug"})) == "removes 'table', the model under the robot's start"


@pytest.mark.parametrize(("robot", "kind"), [("panda", "arm"), ("husky", "mobile"), (PANDA, "arm"),
                                             ("not_registered", "mobile")])
def test_the_kind_of_a_scenarios_robot(robot: object, kind: str) -> None:
    from pytest_ddenv.sim.arm.robot import robot_kind

    assert robot_kind(robot) == kind  # type: ignore[arg-type]
