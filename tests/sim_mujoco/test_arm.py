"""The Franka Panda in MuJoCo (sim/mujoco/arm_spec.py, arm.py, arm_camera.py): compiled from its URDF (or an
MJCF), its servos, inverse kinematics, the gripper closing on a cube, lifting it and holding it, its contacts
and camera; an arm world run by the engine (w31core's smoke and blocked worlds, the default controller), runs
that repeat bit for bit, and the same arm as pybullet's."""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco", reason="needs mujoco: pip install \"pytest-ddenv[mujoco]\"")

from mujoco_worlds import digest, in_mujoco  # noqa: E402

from pytest_ddenv.errors import ScenarioError  # noqa: E402
from pytest_ddenv.scenario.robot_world import RobotFailure, RobotWorld  # noqa: E402
from pytest_ddenv.sim import Simulator  # noqa: E402
from pytest_ddenv.sim.arm.control import ArmObservation, GripperCommand  # noqa: E402
from pytest_ddenv.sim.mujoco.arm import MujocoArm, arm_world  # noqa: E402
from pytest_ddenv.sim.urdf_mujoco import mujoco_readable_urdf  # noqa: E402
from pytest_ddenv.world import Ground, Model, Physics, Pose, Scenario, Shape, World  # noqa: E402
from pytest_ddenv.world.model import ArmDescription, Camera  # noqa: E402

pytestmark = pytest.mark.mujoco

PANDA_URDF = Path(__file__).resolve().parents[2] / "pytest_ddenv" / "sim" / "arm" / "panda" / "panda.urdf"
PANDA = ArmDescription(urdf=str(PANDA_URDF), arm_joints=tuple(f"panda_joint{i}" for i in range(1, 8)),
                       finger_joints=("panda_finger_joint1", "panda_finger_joint2"), end_effector="panda_grasptarget",
                       home=(0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785), name="panda")
VELOCITIES = (2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61, 0.2, 0.2)
"""The URDF's velocity limits: the seven arm joints, then the two fingers."""
EFFORTS = (87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0, 40.0)
"""The actuators' force limits: the URDF's efforts, the gripper's both fingers' together."""
BASE = (0.0, 0.0, 0.4)
DOWN = (1.0, 0.0, 0.0, 0.0)
"""The gripper pointing down (x, y, z, w)."""
CUBE_AT = (0.5, 0.0, 0.425)


def tabletop(*extra: Model, arm: ArmDescription = PANDA) -> World:
    """A 0.4 m table in front of the arm's base, a 5 cm cube of 0.1 kg and friction 1 on it."""
    table = Model("table", (Shape("box", size=(0.7, 1.0, 0.4)),), pose=Pose(0.5, 0.0, 0.2), static=True, mu=1.0)
    cube = Model("cube", (Shape("box", size=(0.05, 0.05, 0.05)),), pose=Pose(*CUBE_AT), static=False, mass=0.1,
                 mu=1.0)
    return World(models=(table, cube, *extra), physics=Physics(engine="mujoco"), ground=Ground(), name="tabletop",
                 scenario=Scenario(robot=arm, start=Pose(*BASE), start_z_given=True, target="cube", table="table"))


def placed(world: World, arm: ArmDescription = PANDA) -> MujocoArm:
    assert arm.home is not None
    driven = arm_world(world, arm, "min", velocities=VELOCITIES, home=arm.home)
    driven.place(BASE, 0.0)
    return driven


def simulate(arm: MujocoArm, seconds: float) -> None:
    for _ in range(round(seconds * 240)):
        arm.advance()
        mujoco.mj_step(arm.model, arm.data)


def body_position(arm: MujocoArm, name: str) -> np.ndarray:
    return np.array(arm.data.xpos[arm.model.body(name).id])


def move_to(arm: MujocoArm, position: tuple[float, float, float], seconds: float = 1.5) -> None:
    arm.set_joint_targets(arm.inverse_kinematics(position, DOWN))
    simulate(arm, seconds)


def pick_and_lift(arm: MujocoArm) -> None:
    x, y, z = CUBE_AT
    move_to(arm, (x, y, z + 0.15))
    move_to(arm, (x, y, z))
    arm.set_gripper("close")
    simulate(arm, 1.0)
    move_to(arm, (x, y, z + 0.25), seconds=2.0)


def test_the_panda_compiles_with_its_urdf_limits() -> None:
    arm = placed(tabletop())
    model = arm.model
    assert arm.link_names[-1] == "panda_link0" and arm.link_names[11] == "panda_grasptarget"
    assert {arm.link_names[k] for k in arm.finger_links} == {"panda_leftfinger", "panda_rightfinger"}
    assert arm.lower[3] == pytest.approx(-3.1416) and arm.upper[5] == pytest.approx(3.8223)
    assert arm.max_opening == pytest.approx(0.08)
    assert [float(model.actuator_forcerange[a, 1]) for a in range(model.nu)] == pytest.approx(EFFORTS)
    assert int(model.body_jntnum[arm.root]) == 0  # the base is fixed
    assert arm.joint_state()[0] == pytest.approx(PANDA.home) and arm.gripper_opening() == pytest.approx(0.08)
    position, _ = arm.end_effector()
    assert position[2] > BASE[2] + 0.3 and arm.self_contacts() == []


def test_the_base_stands_where_it_is_placed() -> None:
    arm = placed(tabletop())
    home, _ = arm.end_effector()
    arm.place((1.0, 2.0, 0.4), math.pi / 2)
    moved, _ = arm.end_effector()
    assert moved == pytest.approx((1.0 - home[1], 2.0 + home[0], home[2]), abs=1e-9)
    position, orientation, _, _ = arm.base_state()
    assert position == pytest.approx((1.0, 2.0, 0.4)) and orientation[2] == pytest.approx(math.pi / 2)


def test_inverse_kinematics_reaches_a_reachable_pose_within_1_cm_and_leaves_the_state_alone() -> None:
    arm = placed(tabletop())
    before = arm.data.qpos.copy()
    goal = (0.45, 0.2, 0.55)
    solution = arm.inverse_kinematics(goal, DOWN)
    assert np.array_equal(arm.data.qpos, before)
    assert all(lo <= q <= hi for lo, q, hi in zip(arm.lower, solution, arm.upper, strict=True))
    arm.set_joint_targets(solution)
    simulate(arm, 2.0)
    position, orientation = arm.end_effector()
    assert math.dist(position, goal) < 0.01
    assert abs(orientation[0]) > 0.999  # still pointing down


def test_joints_track_targets_within_their_speed_limits() -> None:
    arm = placed(tabletop())
    targets = [0.5, -0.3, 0.2, -2.0, 0.3, 1.9, 0.2]
    arm.set_joint_targets(targets)
    fastest = np.zeros(7)
    for _ in range(3 * 240):
        setpoints = arm.data.ctrl[:7].copy()
        simulate(arm, 1 / 240)
        assert (np.abs(arm.data.ctrl[:7] - setpoints) <= np.array(VELOCITIES[:7]) / 240 + 1e-12).all()
        fastest = np.maximum(fastest, np.abs(arm.joint_state()[1]))
    positions, velocities = arm.joint_state()
    assert positions == pytest.approx(targets, abs=0.005)
    assert np.abs(velocities).max() < 0.01
    # the setpoints keep to the speed limits; the four strong joints follow them, while the wrist's 12 N m
    # do not always hold it back when the shoulder swings it (3.5 rad/s here)
    assert (fastest[:4] <= np.array(VELOCITIES[:4]) * 1.1).all()
    assert fastest[0] > 1.0  # it moved at speed, not creeping


def test_targets_are_clipped_to_the_limits() -> None:
    arm = placed(tabletop())
    arm.set_joint_targets([4.0, 0.0, 0.0, 1.0, 0.0, 1.571, 0.785])
    simulate(arm, 2.0)
    positions, _ = arm.joint_state()
    assert positions[0] == pytest.approx(arm.upper[0], abs=0.01)
    assert positions[3] == pytest.approx(arm.upper[3], abs=0.01)


def test_the_gripper_closes_on_a_cube_and_lifts_it() -> None:
    arm = placed(tabletop())
    pick_and_lift(arm)
    cube = body_position(arm, "cube")
    position, _ = arm.end_effector()
    assert cube[2] > CUBE_AT[2] + 0.2
    assert math.dist(cube, position) < 0.02
    assert 0.04 < arm.gripper_opening() < 0.05  # the 5 cm cube between the fingers
    cube_id = arm.model.body("cube").id
    touching = {arm.touching(int(c.geom1), int(c.geom2)) for c in arm.data.contact[:arm.data.ncon]}
    assert {(finger, cube_id) for finger in arm.finger_links} <= touching
    for goal in ((0.4, 0.3, 0.6), (0.3, -0.3, 0.5), (0.5, 0.0, 0.6)):  # swung about at full speed
        move_to(arm, goal, seconds=2.0)
        position, _ = arm.end_effector()
        assert math.dist(body_position(arm, "cube"), position) < 0.04
    assert 0.04 < arm.gripper_opening() < 0.05
    held = body_position(arm, "cube") - np.array(arm.end_effector()[0])
    simulate(arm, 5.0)  # with MuJoCo's default impratio it crept 15 cm in 10 s and fell out, 7.7 mm with 10
    assert np.linalg.norm(body_position(arm, "cube") - np.array(arm.end_effector()[0]) - held) < 0.002


def test_the_gripper_closes_on_nothing_and_opens_again() -> None:
    arm = placed(tabletop())
    arm.set_gripper("close")
    simulate(arm, 0.6)
    left, right = (arm.data.qpos[arm.model.joint(f"robot/{name}").id] for name in PANDA.finger_joints)
    assert arm.gripper_opening() < 0.002 and left == pytest.approx(right, abs=1e-4)
    assert arm.self_contacts() == []
    arm.set_gripper("open")
    simulate(arm, 0.6)
    assert arm.gripper_opening() == pytest.approx(0.08, abs=0.002)


def test_self_contacts_name_non_adjacent_links() -> None:
    arm = placed(tabletop())
    assert arm.self_contacts() == []
    arm.data.qpos[:7] = [0.0, 0.0, 0.0, -3.07, 0.0, 0.0, 0.0]  # the elbow folded: the hand in the shoulder
    mujoco.mj_forward(arm.model, arm.data)
    pairs = arm.self_contacts()
    assert (4, 6) in pairs  # panda_link5 and panda_link7
    for a, b in pairs:  # never a link and its parent, nor the hand and the link it is fixed to
        assert a < b and b - a > 1 and not {a, b} <= {6, 7, 8, 11}


def test_a_run_repeats_bit_for_bit() -> None:
    def run() -> str:
        arm = placed(tabletop())
        digest = hashlib.sha1()
        for position in ((0.5, 0.0, 0.575), (0.5, 0.0, 0.425)):
            move_to(arm, position)
            digest.update(arm.data.qpos.tobytes())
        arm.set_gripper("close")
        simulate(arm, 1.0)
        digest.update(arm.data.qpos.tobytes() + arm.data.qvel.tobytes())
        return digest.hexdigest()

    assert run() == run()


def test_an_mjcf_arm_picks_as_its_urdf_does(tmp_path: Path) -> None:
    urdf_arm = placed(tabletop())
    mjcf = tmp_path / "panda.xml"
    mujoco.mj_saveLastXML(str(mjcf), mujoco.MjModel.from_xml_string(mujoco_readable_urdf(str(PANDA_URDF))))
    described = dataclasses.replace(PANDA, mjcf=str(mjcf))
    arm = placed(tabletop(arm=described), described)
    assert arm.link_names == urdf_arm.link_names and arm.model.nu == 8
    pick_and_lift(arm)
    assert body_position(arm, "cube")[2] > CUBE_AT[2] + 0.2


@pytest.mark.parametrize(("change", "field"), [
    ({"arm_joints": ("panda_joint1", "elbow")}, "scenario.robot.arm_joints"),
    ({"finger_joints": ("panda_finger_joint1", "thumb")}, "scenario.robot.finger_joints"),
    ({"end_effector": "tool0"}, "scenario.robot.end_effector"),
    ({"mjcf": "missing.xml"}, "scenario.robot.mjcf"),
    ({"urdf": str(PANDA_URDF.parent / "meshes" / "finger.obj")}, "scenario.robot.urdf"),
])
def test_a_wrong_arm_is_one_error_naming_the_field(change: dict[str, object], field: str) -> None:
    described = dataclasses.replace(PANDA, **change)  # type: ignore[arg-type]
    with pytest.raises(ScenarioError) as raised:
        arm_world(tabletop(arm=described), described, "min", velocities=VELOCITIES, home=PANDA.home or ())
    assert raised.value.field == field


# -- an arm world run by the engine (MujocoPhysics) -------------------------------------------------------------
ARM_DATA = Path(__file__).resolve().parents[1] / "data"
"""w31core's arm worlds: arm_smoke.yaml (the default controller places the cube), arm_blocked.yaml (a tall box
beside the cube, which the hand hits)."""


def arm_file_in_mujoco(name: str) -> World:
    return in_mujoco(World.load(ARM_DATA / f"{name}.yaml"))


def test_robot_world_picks_and_places_the_smoke_worlds_cube_in_mujoco() -> None:
    run = RobotWorld(arm_file_in_mujoco("arm_smoke"), seed=0).run()
    assert run.engine == "mujoco" and run.robot_kind == "arm"
    assert run.reached_goal and run.failure is None
    assert run.touched == {"cube"}  # neither the table under the base nor a distractor
    assert run.target_path is not None
    start, end = run.target_path[0], run.target_path[-1]
    assert math.dist(end[:2], (0.45, 0.3)) <= 0.08
    assert run.target_path[:, 2].max() > start[2] + 0.1  # carried, not pushed
    held = run.wheel_contacts[(run.wheel_contacts > 1.0).all(axis=1)]  # both fingers on the cube
    assert len(held) > 20 and np.median(held, axis=0) == pytest.approx((20.0, 20.0), abs=1.0)  # each its effort
    assert np.allclose(run.poses[0, :3], (0.307, 0.0, 0.885), atol=0.01)  # the Panda's home, as in pybullet


def test_the_hand_hits_the_tall_box_in_mujoco() -> None:
    with pytest.raises(RobotFailure) as failed:
        RobotWorld(arm_file_in_mujoco("arm_blocked"), seed=0).run()
    assert failed.value.signature.predicate == "arm_collision"
    assert failed.value.run.touched == {"tall_box"}


def test_removing_an_untouched_model_leaves_the_arm_run_bit_identical() -> None:
    world = arm_file_in_mujoco("arm_smoke")
    full = RobotWorld(world, seed=0).run()
    assert full.touched == {"cube"}
    for name in ("mug", "block", "post"):
        reduced = dataclasses.replace(world, models=tuple(m for m in world.models if m.name != name))
        assert digest(RobotWorld(reduced, seed=0).run()) == digest(full), name


def test_an_arm_run_repeats_bit_for_bit_in_mujoco() -> None:
    world = arm_file_in_mujoco("arm_smoke")
    first, second = (RobotWorld(world, seed=3).run() for _ in range(2))
    assert digest(first) == digest(second)
    assert first.target_path is not None and second.target_path is not None
    assert np.array_equal(first.target_path, second.target_path)
    code = textwrap.dedent(
        f"""
        import sys
        sys.path.insert(0, {json.dumps(str(Path(__file__).parent))})
        from mujoco_worlds import digest, in_mujoco
        from pytest_ddenv import World
        from pytest_ddenv.scenario.robot_world import RobotWorld
        print(digest(RobotWorld(in_mujoco(World.load({json.dumps(str(ARM_DATA / "arm_smoke.yaml"))})), seed=3).run()))
        """
    )
    fresh = [subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True
                            ).stdout.strip().splitlines()[-1] for _ in range(2)]
    # two fresh processes agree (the probes' workers are fresh processes); this long-lived test process once
    # did not, in a full xdist run (cause not found: see the issue 31 closing note), so it is not compared
    assert fresh[0] == fresh[1]


@pytest.mark.slow
def test_the_reduction_keeps_the_box_the_hand_hits_in_mujoco(pytester: pytest.Pytester) -> None:
    blocked = (ARM_DATA / "arm_blocked.yaml").read_text(encoding="utf-8") + "physics: {engine: mujoco}\n"
    pytester.makefile(".yaml", arm_blocked=blocked)
    pytester.makepyfile(test_arm="""
        import pytest

        @pytest.mark.ddenv(world="arm_blocked.yaml", deflake=1)
        def test_places_the_cube(robot_world):
            assert robot_world.run().reached_goal
    """)
    result = pytester.runpytest_subprocess("--ddenv-reduce")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*RobotFailure*arm_collision*tall_box*", "*reduced 6 -> 3 models*"])
    (summary_file,) = Path(pytester.path, "ddenv-artifacts").glob("*/summary.json")
    summary = json.loads(summary_file.read_text())
    assert sorted(summary["minimal_models"]) == ["cube", "table", "tall_box"]
    assert summary["one_minimal"] is True


@pytest.mark.pybullet
def test_the_panda_is_the_same_arm_in_both_engines() -> None:
    smoke = World.load(ARM_DATA / "arm_smoke.yaml")
    with Simulator() as sim:
        in_pybullet, in_mujoco_engine = (sim.start(world, seed=0).arm for world in (smoke, in_mujoco(smoke)))
        assert dict(in_mujoco_engine.link_names) == dict(in_pybullet.link_names)
        assert in_mujoco_engine.finger_links == in_pybullet.finger_links
        assert (in_mujoco_engine.lower, in_mujoco_engine.upper) == (in_pybullet.lower, in_pybullet.upper)
        assert in_mujoco_engine.max_opening == in_pybullet.max_opening
        (position, orientation), (expected, turned) = in_mujoco_engine.end_effector(), in_pybullet.end_effector()
        assert position == pytest.approx(expected, abs=1e-6) and orientation == pytest.approx(turned, abs=1e-6)


# -- the declared camera, ray cast (sim/mujoco/arm_camera.py) ---------------------------------------------------
OVERHEAD = Camera(position=(0.5, 0.0, 0.8), look_at=(0.5, 0.0, 0.4), width=48, height=32, kind="depth")


def pictures(world: World) -> list[np.ndarray]:
    seen: list[ArmObservation] = []

    def look(observation: ArmObservation) -> GripperCommand:
        seen.append(observation)
        return GripperCommand("open")

    with Simulator() as sim:
        sim.run(world, controller=look, timeout=0.1)
    return [o.image for o in seen]  # type: ignore[misc]


def with_camera(world: World, camera: Camera) -> World:
    assert world.scenario is not None
    return dataclasses.replace(world, scenario=dataclasses.replace(world.scenario, camera=camera))


def test_a_depth_camera_sees_the_cube_on_the_table_in_mujoco() -> None:
    (depth, *_) = pictures(with_camera(arm_file_in_mujoco("arm_smoke"), OVERHEAD))
    assert depth.shape == (32, 48) and depth.dtype == np.float32 and not depth.flags.writeable
    assert depth[15, 24] == pytest.approx(0.8 - 0.45, abs=0.005)  # the cube's top, under the camera
    assert depth[2, 2] == pytest.approx(0.8 - 0.4, abs=0.005)  # the table's top beside it


def test_an_rgb_camera_sees_the_red_cube_in_mujoco() -> None:
    (rgb, *_) = pictures(with_camera(arm_file_in_mujoco("arm_smoke"), dataclasses.replace(OVERHEAD, kind="rgb")))
    assert rgb.shape == (32, 48, 3) and rgb.dtype == np.uint8
    red, green, blue = (int(v) for v in rgb[15, 24])
    assert red > 2 * green and red > 2 * blue  # the cube, red in the world file
    assert len({int(v) for v in rgb[2, 2]}) == 1  # the table, grey


def test_the_camera_changes_nothing_else_in_mujoco() -> None:
    world = arm_file_in_mujoco("arm_smoke")
    assert digest(RobotWorld(world, seed=3).run()) == digest(RobotWorld(with_camera(world, OVERHEAD), seed=3).run())


@pytest.mark.pybullet
def test_the_depth_pictures_of_both_engines_agree() -> None:
    oblique = Camera(position=(1.0, -0.5, 0.9), look_at=(0.4, 0.0, 0.4), width=40, height=30, kind="depth")
    smoke = with_camera(World.load(ARM_DATA / "arm_smoke.yaml"), oblique)
    (in_pybullet, *_), (in_mujoco_engine, *_) = pictures(smoke), pictures(in_mujoco(smoke))
    close = np.abs(in_mujoco_engine - in_pybullet) < 0.01
    assert close.mean() > 0.99  # 99.9 % measured; the rest on the edges of the models (pybullet draws visual meshes)
