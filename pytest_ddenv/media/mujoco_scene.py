"""The animations' scene drawn by MuJoCo's renderer (`mujoco.Renderer`, OpenGL through EGL or OSMesa headless).

The same replay as the pybullet scene (media/animate.py): the world and the robot compiled once into one
MuJoCo model by the MuJoCo engine's own spec builder (sim/mujoco/world_spec.py, robot_spec.py; an arm's:
sim/mujoco/arm_spec.py), never stepped; every frame sets the robot's free joint from the recorded base pose (the
chassis's centre of mass, as both engines record it), its wheel joints and the moving models' free joints
from `Run.detail`, and runs MuJoCo's kinematics. An arm's base is fixed at the scenario's start and its arm
and finger joints set from a MuJoCo run's recorded joints. The colours are media/palette.py's, the camera
the one media/animate.py chose.

OpenGL is chosen by `MUJOCO_GL` when mujoco is first imported, so this module is used in a helper process
whose `MUJOCO_GL` was set before (media/gl_helper.py); a renderer that cannot start raises `GLUnavailable`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pytest_ddenv.media.palette import GROUND_RGBA, ROBOT_RGBA, WHEEL_RGBA, model_rgba
from pytest_ddenv.media.table_camera import PLACE_RGBA, PLACE_THICKNESS, place_disc
from pytest_ddenv.scenario.reported import REPORTED
from pytest_ddenv.sim.builder import GROUND_BODY_NAME
from pytest_ddenv.sim.run import Run
from pytest_ddenv.world.geometry import rotation_matrix
from pytest_ddenv.world.model import ArmDescription, World

FOV_DEGREES = 60.0
NEAR, FAR = 0.1, 80.0
"""The pybullet scene's projection: vertical field of view, near and far planes (m)."""
LIGHT_DIRECTION = (0.4, -0.5, 1.0)
"""Towards the light, as pybullet's `lightDirection`."""
AMBIENT, HEADLIGHT, SUNLIGHT = 0.65, 0.3, 0.35
"""Light intensities (ambient and diffuse of the camera's headlight, diffuse of the directional light) that
give the palette's colours about the brightness of pybullet's TinyRenderer."""
BOX_HALF_HEIGHT = 0.15
"""A robot that cannot be compiled here (a run reported by the user's simulator, a `Robot` of the user's) is
its footprint box, this high above and below its base, as in the pybullet scene."""


class GLUnavailable(RuntimeError):
    """MuJoCo's renderer could not start (no OpenGL backend here); the message says why."""


class MujocoScene:
    """The world and the robot as one MuJoCo model, posed frame by frame and drawn by `mujoco.Renderer`."""

    def __init__(self, world: World, run: Run, width: int, height: int) -> None:
        try:
            import mujoco
        except Exception as error:  # noqa: BLE001 - mujoco imports its MUJOCO_GL backend: a bad one fails here
            raise GLUnavailable(f"import mujoco: {type(error).__name__}: {error}") from None

        from pytest_ddenv.sim.mujoco.robot_spec import PREFIX, ROOT_JOINT
        from pytest_ddenv.sim.mujoco.world_spec import world_spec

        self.mujoco = mujoco
        robot, wheels, arm = _robot_spec(world, run)
        spec = world_spec(world, robot, PREFIX, "min")
        light = spec.worldbody.add_light(pos=[0.0, 0.0, 10.0], dir=[-v for v in LIGHT_DIRECTION])
        light.type = mujoco.mjtLightType.mjLIGHT_DIRECTIONAL
        light.castshadow = False
        light.diffuse = [SUNLIGHT] * 3
        disc = place_disc(world) if arm is not None else None
        if disc is not None:  # an arm's place region: a thin green disc on the table, drawn only
            centre, radius = disc
            spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[radius, PLACE_THICKNESS / 2.0, 0.0],
                                    pos=list(centre), rgba=list(PLACE_RGBA), contype=0, conaffinity=0)
        model = spec.compile()
        self.model, self.data = model, mujoco.MjData(model)
        _paint(model, world, PREFIX, wheels)
        extent = float(model.stat.extent)
        model.vis.global_.fovy = FOV_DEGREES
        model.vis.headlight.ambient, model.vis.headlight.diffuse = [AMBIENT] * 3, [HEADLIGHT] * 3
        model.vis.map.znear, model.vis.map.zfar = NEAR / extent, FAR / extent
        model.vis.global_.offwidth, model.vis.global_.offheight = max(width, 1), max(height, 1)
        self.arm = arm is not None
        """An arm: its base fixed at the scenario's start, its joints set from the recorded ones (arm joints
        then finger joints, as the MuJoCo engine records them), never from `Run.poses` (the end effector's)."""
        if arm is not None and world.scenario is not None:
            names = (*arm.arm_joints, *arm.finger_joints)
            self.root = _arm_root(model, model.joint(PREFIX + arm.arm_joints[0]).id)
            start = world.scenario.start
            model.body_pos[self.root] = [start.x, start.y, start.z]
            model.body_quat[self.root] = [math.cos(start.yaw / 2.0), 0.0, 0.0, math.sin(start.yaw / 2.0)]
            self.hinges = [int(model.jnt_qposadr[model.joint(PREFIX + name).id]) for name in names]
            in_robot = [int(model.body_rootid[b]) == self.root for b in range(model.nbody)]
        else:
            root_joint = model.joint(PREFIX + ROOT_JOINT).id
            self.root = int(model.jnt_bodyid[root_joint])
            self.root_address = int(model.jnt_qposadr[root_joint])
            in_robot = [int(model.body_rootid[b]) == self.root for b in range(model.nbody)]
            self.hinges = [int(model.jnt_qposadr[j]) for j in range(model.njnt)
                           if in_robot[int(model.jnt_bodyid[j])] and model.jnt_type[j] != mujoco.mjtJoint.mjJNT_FREE]
            self.centre = self._chassis_centre()
        self.moving = {model.body(b).name: (int(model.jnt_qposadr[model.body_jntadr[b]]), b)
                       for b in range(1, model.nbody) if not in_robot[b] and model.body_jntnum[b] > 0}
        """A moving model's name -> (its free joint's qpos address, its body)."""
        self.camera = mujoco.MjvCamera()
        self.camera.type = mujoco.mjtCamera.mjCAMERA_FREE
        self.option = mujoco.MjvOption()
        self.option.geomgroup[:] = 1  # the robot's geoms are in group 3, hidden by default
        try:
            self.renderer = mujoco.Renderer(model, height, width)
        except Exception as error:  # noqa: BLE001 - any failure to start OpenGL: say which and why
            raise GLUnavailable(f"{type(error).__name__}: {error}") from None
        self.renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False
        self.renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SKYBOX] = False

    def _chassis_centre(self) -> NDArray[np.float64]:
        """The chassis's centre of mass in the root body's frame (the recorded base pose is that point)."""
        mujoco, model, data = self.mujoco, self.model, self.data
        data.qpos[self.root_address:self.root_address + 7] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]
        mujoco.mj_kinematics(model, data)
        chassis = [b for b in range(model.nbody) if _welded_to(model, b, self.root)]
        masses = model.body_mass[chassis]
        total = float(masses.sum())
        if total <= 0:
            return np.zeros(3)
        return np.asarray((masses @ data.xipos[chassis]) / total, dtype=np.float64)

    def place(self, run: Run, index: int) -> None:
        data = self.data
        if not self.arm:
            x, y, z, roll, pitch, yaw = (float(v) for v in run.poses[index])
            rotation = np.ascontiguousarray(rotation_matrix(roll, pitch, yaw), dtype=np.float64)
            quaternion = np.zeros(4)
            self.mujoco.mju_mat2Quat(quaternion, rotation.reshape(9))
            origin = np.array([x, y, z]) - rotation @ self.centre
            data.qpos[self.root_address:self.root_address + 7] = [*origin, *quaternion]
        detail = run.detail
        if detail is not None:
            if run.engine == "mujoco" and detail.joints.shape[1] == len(self.hinges):
                data.qpos[self.hinges] = detail.joints[index]
            for name, poses in detail.bodies.items():
                moving = self.moving.get(name)
                if moving is not None and index < len(poses):
                    address, body = moving
                    px, py, pz, qx, qy, qz, qw = (float(v) for v in poses[index])
                    turn = np.zeros(9)  # the pose recorded is the centre of mass's (both engines): the body's origin
                    self.mujoco.mju_quat2Mat(turn, np.array([qw, qx, qy, qz]))
                    origin = np.array([px, py, pz]) - turn.reshape(3, 3) @ self.model.body_ipos[body]
                    data.qpos[address:address + 7] = [*origin, qw, qx, qy, qz]
        self.mujoco.mj_kinematics(self.model, data)

    def image(self, eye: Sequence[float], target: Sequence[float], width: int, height: int) -> NDArray[np.uint8]:
        offset = np.asarray(target, dtype=float) - np.asarray(eye, dtype=float)
        distance = float(np.linalg.norm(offset))
        camera = self.camera
        camera.lookat[:] = target
        camera.distance = distance
        camera.azimuth = math.degrees(math.atan2(offset[1], offset[0]))
        camera.elevation = math.degrees(math.asin(offset[2] / distance)) if distance > 0 else -90.0
        self.renderer.update_scene(self.data, camera=camera, scene_option=self.option)
        return np.asarray(self.renderer.render(), dtype=np.uint8).copy()

    def close(self) -> None:
        self.renderer.close()


def _robot_spec(world: World, run: Run) -> tuple[Any, frozenset[str], ArmDescription | None]:
    """The robot's spec (its URDF as the MuJoCo engine compiles it, else its footprint box), the names of
    its wheel bodies (an arm's: its finger bodies, drawn as dark) and an arm's description (None: not an
    arm, or drawn as its box)."""
    import mujoco

    from pytest_ddenv.sim.arm.robot import ArmRobot
    from pytest_ddenv.sim.mujoco.arm_spec import arm_spec
    from pytest_ddenv.sim.mujoco.robot_spec import ROOT_JOINT, robot_spec
    from pytest_ddenv.sim.robot import WheeledRobot, make_robot

    robot = None
    if world.scenario is not None and run.robot != REPORTED:
        try:
            robot = make_robot(world.scenario.robot, world.source)
            spec = robot_spec(robot) if isinstance(robot, WheeledRobot) else None
            if isinstance(robot, ArmRobot) and run.robot_kind == "arm":
                spec = arm_spec(robot.description, world.source, float(world.physics.timestep))
        except Exception:  # noqa: BLE001 - a robot that cannot be made here is drawn as its box, as in pybullet
            spec = None
        if isinstance(robot, WheeledRobot) and spec is not None:
            return spec, frozenset(spec.joint(name).parent.name for name in robot.wheel_names), None
        if isinstance(robot, ArmRobot) and spec is not None:
            fingers = frozenset(spec.joint(name).parent.name for name in robot.description.finger_joints)
            return spec, fingers, robot.description
    spec = mujoco.MjSpec()
    length, width = run.footprint
    body = spec.worldbody.add_body(name="base")
    body.add_freejoint(name=ROOT_JOINT)
    body.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[length / 2, width / 2, BOX_HALF_HEIGHT], mass=1.0)
    return spec, frozenset(), None


def _arm_root(model: Any, joint: int) -> int:
    """The body an arm's joint hangs from, up to the one fixed in the world (the arm's base)."""
    body = int(model.jnt_bodyid[joint])
    while int(model.body_parentid[body]) != 0:
        body = int(model.body_parentid[body])
    return body


def _paint(model: Any, world: World, prefix: str, wheels: frozenset[str]) -> None:
    """Every geom in the palette's colour: the ground, each model's, the robot's (its wheels darker)."""
    colors = {model_.name: model_rgba(model_) for model_ in world.models}
    for geom in range(model.ngeom):
        body = model.body(int(model.geom_bodyid[geom])).name
        if body in colors:
            model.geom_rgba[geom] = colors[body]
        elif model.geom(geom).name == GROUND_BODY_NAME:
            model.geom_rgba[geom] = GROUND_RGBA
        elif body.startswith(prefix):
            model.geom_rgba[geom] = WHEEL_RGBA if body.removeprefix(prefix) in wheels else ROBOT_RGBA


def _welded_to(model: Any, body: int, root: int) -> bool:
    """Whether `body` moves with `root` (no joint on the way up to it)."""
    while body != root:
        if body == 0 or model.body_jntnum[body] > 0:
            return False
        body = int(model.body_parentid[body])
    return True
