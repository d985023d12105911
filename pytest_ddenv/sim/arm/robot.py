"""`ArmRobot`: a fixed-base arm with a parallel gripper from a URDF, and the built-in Franka Panda ("panda").

Built from an `ArmDescription` (a world file's `scenario.robot` mapping with `arm_joints`): the URDF is read
as XML when the robot is made (no engine needed), so an unknown joint or end-effector link is a
`ScenarioError` naming the field before any run. Spawned in pybullet with a fixed base, self-collision on
(links joined by a joint, or through fixed joints, never collide), it gives its `PybulletArm` as `arm`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from pytest_ddenv.errors import ControllerError, ScenarioError
from pytest_ddenv.sim.arm.driven import DrivenArm
from pytest_ddenv.sim.quiet import silenced
from pytest_ddenv.sim.robot import ROBOTS, Robot, make_robot, register_arm_factory
from pytest_ddenv.sim.tracebacks import hidden_in_tracebacks
from pytest_ddenv.world.files import regular_file_problem, resolve_relative
from pytest_ddenv.world.model import ArmDescription, RobotDescription

__tracebackhide__ = hidden_in_tracebacks
"""pytest leaves this module's frames out of a failing test's traceback (see sim/tracebacks.py)."""

FIELD = "scenario.robot"
MOVING = ("revolute", "prismatic", "continuous")
PANDA_HOME = (0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785)
"""The Panda's joints at the start: the gripper pointing down, 0.3 m in front of the base and 0.5 m above it."""
PANDA = ArmDescription(
    urdf=str(Path(__file__).parent / "panda" / "panda.urdf"),
    arm_joints=tuple(f"panda_joint{i}" for i in range(1, 8)),
    finger_joints=("panda_finger_joint1", "panda_finger_joint2"),
    end_effector="panda_grasptarget",
    home=PANDA_HOME,
    name="panda",
)
"""The built-in arm "panda": the Franka Panda of pybullet_data (shipped in sim/arm/panda/)."""


@dataclass(frozen=True)
class UrdfJoint:
    """A joint as the URDF declares it (limits of a continuous joint: +-pi)."""

    name: str
    kind: str
    lower: float
    upper: float
    effort: float
    velocity: float


def read_urdf(urdf: Path, source: str | None) -> tuple[dict[str, UrdfJoint], tuple[str, ...]]:
    """The joints (by name) and link names of a URDF, read as XML; ScenarioError naming `source` and the field
    when it cannot be read."""
    import defusedxml.ElementTree

    problem = regular_file_problem(urdf, "URDF file")
    if problem is not None:
        raise ScenarioError(problem, source=source, field=f"{FIELD}.urdf")
    try:
        root = defusedxml.ElementTree.fromstring(urdf.read_bytes())
    except Exception as error:  # noqa: BLE001 - any parse error is the file's
        raise ScenarioError(f"cannot read the URDF {urdf}: {error}", source=source, field=f"{FIELD}.urdf") from None
    joints: dict[str, UrdfJoint] = {}
    for joint in root.iter("joint"):
        name, kind = str(joint.get("name")), str(joint.get("type"))
        limit = joint.find("limit")
        limits = {} if limit is None else dict(limit.attrib)
        values = []
        bound = math.pi if kind == "continuous" else 0.0
        for key, default in (("lower", -bound), ("upper", bound), ("effort", 100.0), ("velocity", 1.0)):
            try:
                values.append(float(limits.get(key, default)))
            except ValueError:
                raise ScenarioError(f"{urdf}: joint {name!r} has an unreadable limit {key}={limits[key]!r}",
                                    source=source, field=f"{FIELD}.urdf") from None
        joints[name] = UrdfJoint(name, kind, *values)
    links = tuple(str(link.get("name")) for link in root.iter("link"))
    return joints, links


class ArmRobot(Robot):
    """A fixed-base arm from an `ArmDescription` (see the module docstring). One instance serves one run."""

    footprint = (0.2, 0.2)
    base_height = 0.0
    has_laser = False

    def __init__(self, description: ArmDescription, source: str | None = None) -> None:
        self.description = description
        self.source = source
        self.urdf = str(resolve_relative(description.urdf, source))
        self.name = description.label
        joints, links = read_urdf(Path(self.urdf), source)
        self.joints, self.fingers = self._joints(joints)
        if description.end_effector not in links:
            raise ScenarioError(f"the arm's URDF {self.urdf} has no link named {description.end_effector!r}",
                                source=source, field=f"{FIELD}.end_effector")
        self.home = self._home()
        self.arm: DrivenArm | None = None
        """The arm as the engine that spawned it drives it (set by `spawn`; MuJoCo's engine sets its own)."""
        self._links: dict[int, str] = {}
        self._mass = 0.0

    def _joints(self, joints: Mapping[str, UrdfJoint]) -> tuple[list[UrdfJoint], list[UrdfJoint]]:
        """The description's arm and finger joints, checked against the URDF's `joints`."""
        description, source = self.description, self.source
        for key, names in (("arm_joints", description.arm_joints), ("finger_joints", description.finger_joints)):
            if not names:
                raise ScenarioError("an arm needs at least one joint here", source=source, field=f"{FIELD}.{key}")
            for name in names:
                if name not in joints:
                    moving = sorted(n for n, j in joints.items() if j.kind in MOVING)
                    raise ScenarioError(f"the arm's URDF {self.urdf} has no joint named {name!r}; its moving joints: "
                                        f"{', '.join(moving) or '(none)'}", source=source, field=f"{FIELD}.{key}")
                if joints[name].kind not in MOVING:
                    raise ScenarioError(f"joint {name!r} of {self.urdf} is {joints[name].kind}, it cannot move",
                                        source=source, field=f"{FIELD}.{key}")
        both = set(description.arm_joints) & set(description.finger_joints)
        if both:
            raise ScenarioError(f"{', '.join(sorted(both))} is both an arm and a finger joint", source=source,
                                field=f"{FIELD}.finger_joints")
        return [joints[name] for name in description.arm_joints], [joints[name] for name in description.finger_joints]

    def _home(self) -> tuple[float, ...]:
        """The description's `home` (default: zeros clipped to the limits), checked against the limits."""
        home = self.description.home
        if home is None:
            home = tuple(min(max(0.0, j.lower), j.upper) for j in self.joints)
        if len(home) != len(self.joints):
            raise ScenarioError(f"expected {len(self.joints)} positions (one per arm joint), got {len(home)}",
                                source=self.source, field=f"{FIELD}.home")
        for joint, position in zip(self.joints, home, strict=True):
            if not joint.lower - 1e-9 <= position <= joint.upper + 1e-9:
                raise ScenarioError(f"{position:g} is outside joint {joint.name!r}'s limits [{joint.lower:g}, "
                                    f"{joint.upper:g}]", source=self.source, field=f"{FIELD}.home")
        return tuple(float(v) for v in home)

    def spawn(self, client: int, position: tuple[float, float, float], yaw: float) -> int:
        import pybullet as p

        from pytest_ddenv.sim.arm.pybullet_arm import JointInfo, PybulletArm

        flags = p.URDF_USE_SELF_COLLISION | p.URDF_USE_SELF_COLLISION_EXCLUDE_PARENT
        try:
            with silenced():
                body = int(p.loadURDF(self.urdf, list(position), p.getQuaternionFromEuler([0.0, 0.0, yaw]),
                                      useFixedBase=True, flags=flags, physicsClientId=client))
        except p.error as error:
            raise ScenarioError(f"pybullet cannot load the arm's URDF {self.urdf}: {error}", source=self.source,
                                field=f"{FIELD}.urdf") from None
        self._links = {-1: p.getBodyInfo(body, physicsClientId=client)[0].decode()}
        indices: dict[str, int] = {}
        parents: dict[int, int] = {}
        fixed: set[int] = set()
        self._mass = float(p.getDynamicsInfo(body, -1, physicsClientId=client)[0])
        for index in range(p.getNumJoints(body, physicsClientId=client)):
            info = p.getJointInfo(body, index, physicsClientId=client)
            indices[info[1].decode()] = index
            self._links[index] = info[12].decode()
            parents[index] = int(info[16])
            if info[2] == p.JOINT_FIXED:
                fixed.add(index)
            self._mass += float(p.getDynamicsInfo(body, index, physicsClientId=client)[0])
        for a, b in _adjacent_pairs(parents, fixed):
            p.setCollisionFilterPair(body, body, a, b, 0, physicsClientId=client)
        link_index = {name: index for index, name in self._links.items()}

        def joint_info(j: UrdfJoint) -> JointInfo:
            return JointInfo(indices[j.name], j.lower, j.upper, j.effort, j.velocity)

        arm = PybulletArm(client, body, arm_joints=[joint_info(j) for j in self.joints],
                          finger_joints=[joint_info(j) for j in self.fingers], joint_names=self.description.arm_joints,
                          end_effector=link_index[self.description.end_effector], link_names=self._links,
                          parents=parents, home=self.home)
        arm.reset_joints(self.home)
        self.arm = arm
        return body

    @property
    def wheel_links(self) -> tuple[int, ...]:
        return ()

    @property
    def link_names(self) -> Mapping[int, str]:
        return self._links

    @property
    def mass(self) -> float:
        return self._mass

    def drive(self, linear: float, angular: float, scale_left: float = 1.0, scale_right: float = 1.0) -> None:
        raise ControllerError(f"the arm {self.name!r} takes JointTargets, EndEffectorTarget or GripperCommand, not a "
                              "mobile robot's Command")

    def measured_velocity(self) -> tuple[float, float]:
        return 0.0, 0.0


def _adjacent_pairs(parents: Mapping[int, int], fixed: set[int]) -> list[tuple[int, int]]:
    """Link pairs that never collide: each link with its parent, where links welded by fixed joints count as
    one (the Panda's hand is fixed to link 8, itself fixed to link 7, whose meshes overlap)."""

    def rigid_root(link: int) -> int:
        while link in fixed:
            link = parents[link]
        return link

    links = [-1, *parents]
    group = {link: rigid_root(link) for link in links}
    pairs = []
    for a in links:
        for b in links:
            if a >= b:
                continue
            ga, gb = group[a], group[b]
            if ga == gb or (parents.get(ga) is not None and group[parents[ga]] == gb) or \
                    (parents.get(gb) is not None and group[parents[gb]] == ga):
                pairs.append((a, b))
    return pairs


def panda() -> ArmRobot:
    """The built-in Franka Panda (registered as "panda")."""
    return ArmRobot(PANDA)



def robot_kind(robot: str | RobotDescription | ArmDescription, source: str | None = None) -> str:
    """"arm" or "mobile": the kind of a scenario's robot (a name of a registered factory is made to be told;
    a name not registered is "mobile", and its run says it is unknown)."""
    if isinstance(robot, ArmDescription):
        return "arm"
    if isinstance(robot, RobotDescription) or robot not in ROBOTS:
        return "mobile"
    return "arm" if robot == "panda" or isinstance(make_robot(robot, source), ArmRobot) else "mobile"


register_arm_factory(ArmRobot)
ROBOTS.setdefault("panda", panda)
