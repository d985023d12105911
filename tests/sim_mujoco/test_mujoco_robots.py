"""Wheeled URDF robots in MuJoCo: the Husky (also from the URDF copy shipped for when pybullet is absent) and a
world file's robot mapping, with velocity actuators at the robot's torque limit and ellipsoid wheels."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import pytest

mujoco = pytest.importorskip("mujoco", reason="needs mujoco: pip install \"pytest-ddenv[mujoco]\"")

from mujoco_worlds import flat_world  # noqa: E402

from pytest_ddenv.sim import (  # noqa: E402
    Command,
    Husky,
    NoiseSettings,
    Run,
    RunSettings,
    Simulator,
    WheelCommand,
    WheeledRobot,
)
from pytest_ddenv.sim.mujoco.physics import MujocoPhysics  # noqa: E402
from pytest_ddenv.sim.robot import husky_urdf  # noqa: E402
from pytest_ddenv.world import Physics, RobotDescription, World  # noqa: E402

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "robots"
DIFFBOT = RobotDescription(urdf=str(EXAMPLE / "diffbot.urdf"), left_wheels=("left_wheel_joint",),
                           right_wheels=("right_wheel_joint",))


def with_robot(world: World, robot: RobotDescription) -> World:
    assert world.scenario is not None
    return dataclasses.replace(world, scenario=dataclasses.replace(world.scenario, robot=robot))


@pytest.mark.parametrize("robot", [Husky(), WheeledRobot.from_description(DIFFBOT)], ids=["husky", "diffbot"])
def test_each_wheel_has_a_velocity_actuator_at_the_robots_torque_limit_and_an_ellipsoid(robot: WheeledRobot) -> None:
    physics = MujocoPhysics()
    physics.load(World(physics=flat_world().physics), robot, "min")
    model = physics.model
    assert model is not None and model.nu == len(robot.wheel_names)
    for name in robot.wheel_names:
        actuator = model.actuator("robot/" + name)
        assert tuple(actuator.forcerange) == (-robot.max_force, robot.max_force)
        assert model.actuator_trnid[actuator.id, 0] == model.joint("robot/" + name).id
        wheel_body = model.jnt_bodyid[model.joint("robot/" + name).id]
        shapes = {int(model.geom_type[g]) for g in range(model.ngeom) if model.geom_bodyid[g] == wheel_body}
        assert shapes == {int(mujoco.mjtGeom.mjGEOM_ELLIPSOID)}


@pytest.mark.pybullet  # compares with pybullet
def test_the_husky_drives_straight_as_commanded(sim: Simulator) -> None:
    run = sim.run(flat_world(goal=(20.0, 0.0), timeout=5.0), seed=0, controller=lambda _: Command(1.0, 0.0))
    x, y = run.positions[-1, :2]
    assert 4.6 < x < 5.1 and abs(y) < 0.3  # 1 m/s for 5 s, less the start-up (pybullet: 4.94 m)
    assert run.poses[:, 2] == pytest.approx(0.157, abs=0.01)  # the chassis's centre of mass, as in pybullet
    assert run.wheel_contacts.shape == (len(run.times), 4)
    # the wheels carry the robot's 50 kg on average (one diagonal pair at a time: MuJoCo's skid-steer rocks)
    assert run.wheel_contacts.sum(axis=1).mean() == pytest.approx(50.0 * 9.81, rel=0.1)
    assert run.engine == "mujoco" and run.engine_version == mujoco.__version__ and run.pybullet_version == ""
    back = Run.from_dict(run.to_dict())
    assert (back.engine, back.engine_version) == ("mujoco", mujoco.__version__)

    world, quiet = flat_world(goal=(20.0, 0.0), timeout=5.0), RunSettings(noise=NoiseSettings.none())
    both = [sim.run(dataclasses.replace(world, physics=physics), settings=quiet, controller=lambda _: Command(1.0, 0.0))
            for physics in (Physics(), Physics(engine="mujoco"))]
    assert [r.engine for r in both] == ["pybullet", "mujoco"] and both[0].engine_version == both[0].pybullet_version
    assert both[0].positions[-1, 0] == pytest.approx(both[1].positions[-1, 0], abs=0.02)  # the same in both engines


def test_a_world_files_urdf_robot_drives_to_its_goal(sim: Simulator) -> None:
    run = sim.run(with_robot(flat_world(goal=(4.0, 1.0), timeout=15.0), DIFFBOT), seed=0)
    assert run.reached_goal and run.failure is None and run.robot == "diffbot"
    assert run.wheel_contacts.shape[1] == 2


def test_a_wheel_command_drives_the_urdf_robot_forward(sim: Simulator) -> None:
    world = with_robot(flat_world(goal=(10.0, 0.0), timeout=2.0), DIFFBOT)
    run = sim.run(world, controller=lambda observation: WheelCommand(5.0, 5.0))
    x, y = run.positions[-1, :2]
    assert 0.5 < x < 0.85 and abs(y) < 0.05 and abs(run.poses[-1, 5]) < 0.05  # 0.4 m/s (pybullet: same bounds)


@pytest.mark.pybullet  # compares with pybullet_data's file
def test_without_pybullet_the_husky_urdf_is_the_copy_in_the_package(monkeypatch: pytest.MonkeyPatch) -> None:
    installed = Path(husky_urdf())
    for module in ("pybullet", "pybullet_data"):  # what `import` sees where pybullet is not installed
        monkeypatch.setitem(sys.modules, module, None)
    shipped = Path(husky_urdf())
    assert shipped != installed and shipped.parent.name == "husky" and shipped.parent.parent.name == "sim"
    assert shipped.read_bytes() == installed.read_bytes()
    assert "Software License Agreement (BSD)" in shipped.read_text() and "Clearpath Robotics" in shipped.read_text()
    assert Husky().urdf == str(shipped)
    with Simulator() as sim:  # no pybullet client: the world runs in MuJoCo alone
        assert sim.client == -1
        run = sim.run(flat_world(goal=(2.0, 0.0), timeout=10.0), seed=0)
    assert run.reached_goal and run.engine == "mujoco"
