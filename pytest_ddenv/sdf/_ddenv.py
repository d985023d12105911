"""The `ddenv:` elements of an SDF world: what SDF has no place for (scenario, PyBullet physics, keep, tags)."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Collection

from pytest_ddenv.errors import ScenarioError, WorldError, shown
from pytest_ddenv.sdf._values import Values
from pytest_ddenv.sdf._xml import DDENV_NS as DDENV_NS  # re-exported: its home before _xml needed it
from pytest_ddenv.sdf._xml import local_name
from pytest_ddenv.world.files import is_file, resolve_relative
from pytest_ddenv.world.limits import solver_iterations_problem, timestep_problem
from pytest_ddenv.world.model import (
    DRIVE_KINDS,
    ArmDescription,
    Camera,
    LaserMount,
    Physics,
    Pose,
    RobotDescription,
    Scenario,
    TagValue,
)

WORLD_ELEMENTS = ("scenario", "physics")
MODEL_ELEMENTS = ("keep", "tag")
SCENARIO_ELEMENTS = ("start", "goal", "robot_description", "arm_description", "camera")
ATTRIBUTES = {
    "scenario": ("robot", "timeout", "goal_tolerance", "target", "table", "watch"),
    "start": ("x", "y", "z", "yaw"),
    "goal": ("x", "y", "z"),
    "physics": ("timestep", "solver_iterations"),
    "tag": ("name", "type"),
    "keep": (),
    "robot_description": ("urdf", "drive", "left_wheels", "right_wheels", "wheel_radius", "track", "track_factor",
                          "max_wheel_torque", "laser", "name"),
    "arm_description": ("urdf", "arm_joints", "finger_joints", "end_effector", "home", "mjcf", "name"),
    "camera": ("position", "look_at", "width", "height", "kind", "fov"),
}
"""The attributes of each `ddenv:` element (what `dump_sdf` writes); any other is a typo, refused."""
REQUIRED = {
    "start": 'give the robot\'s start as x=".." y=".." (and yaw=".." for its heading)',
    "goal": 'give the goal as x=".." y=".." (and z=".." for a 3D goal)',
}


class DdenvElements:
    """Reads the `ddenv:` elements (and the world's gravity) of a world read by `Values`.

    As strictly as the YAML reader reads a world's `scenario:` and `physics:`: an unknown `ddenv:` element or
    attribute, a second one of an element that is single, a start or goal without x or y are errors naming
    file:line and field (a goal without x was read as x = 0, the start: "reached the goal at t = 0.00 s").
    """

    def __init__(self, values: Values) -> None:
        self.values = values
        self.source = values.source

    def error(
        self, message: str, element: ET.Element | None = None, *, model: str | None = None, field: str | None = None,
        kind: type[WorldError] = WorldError,
    ) -> WorldError:
        return self.values.error(message, element, model=model, field=field, kind=kind)

    def floats(self, element: ET.Element, count: tuple[int, ...], where: str, model: str | None) -> list[float]:
        return self.values.floats(element, count, where, model)

    def boolean(self, element: ET.Element, where: str, model: str | None) -> bool:
        return self.values.boolean(element, where, model)

    # structure --------------------------------------------------------------------------------------------
    def check_world(self, world: ET.Element) -> None:
        """The world's `ddenv:` children: known, and each at most once."""
        self.known_children(world, WORLD_ELEMENTS, "the world", None, kind=WorldError)
        for tag in WORLD_ELEMENTS:
            self.single(world, tag, "a world", None, kind=ScenarioError if tag == "scenario" else WorldError)

    def keep(self, element: ET.Element, model: str) -> bool:
        """A top-level model's `<ddenv:keep>` (its `ddenv:` children checked: known, one keep at most)."""
        self.known_children(element, MODEL_ELEMENTS, f"model '{model}'", model, kind=WorldError)
        keep = self.single(element, "keep", "a model", model, kind=WorldError)
        if keep is None:
            return False
        self.known_attributes(keep, model, WorldError)
        return self.boolean(keep, "ddenv:keep", model)

    def known_children(
        self, parent: ET.Element, known: tuple[str, ...], where: str, model: str | None, *, kind: type[WorldError]
    ) -> None:
        for child in parent:
            name = ddenv_name(child.tag)
            if name is not None and name not in known:
                raise self.error(f"unknown element ddenv:{name} in {where}; expected: {', '.join(known)}", child,
                                 model=model, field=f"ddenv:{name}", kind=kind)

    def known_attributes(self, element: ET.Element, model: str | None, kind: type[WorldError]) -> None:
        name = local_name(element.tag)
        allowed = ATTRIBUTES[name]
        for key in element.attrib:
            attribute = ddenv_name(key) if key.startswith("{") else key
            if attribute is not None and attribute not in allowed:
                expected = f"expected one of: {', '.join(allowed)}" if allowed else "it takes none"
                raise self.error(f"unknown attribute {shown(attribute)}; {expected}", element, model=model,
                                 field=f"ddenv:{name}/@{attribute}", kind=kind)

    def single(
        self, parent: ET.Element, tag: str, holder: str, model: str | None, *, kind: type[WorldError]
    ) -> ET.Element | None:
        """`parent`'s only `ddenv:tag` child (None when it has none); a second one is an error."""
        found = parent.findall(f"{{{DDENV_NS}}}{tag}")
        if len(found) > 1:
            first = self.values.lines.of(found[0])[1]
            raise self.error(f"a second ddenv:{tag} (the first is at line {first}); {holder} has one", found[1],
                             model=model, field=f"ddenv:{tag}", kind=kind)
        return found[0] if found else None

    # values -----------------------------------------------------------------------------------------------
    def tags(self, element: ET.Element, model: str) -> dict[str, TagValue]:
        tags: dict[str, TagValue] = {}
        for tag in element.findall(f"{{{DDENV_NS}}}tag"):
            self.known_attributes(tag, model, WorldError)
            name = tag.get("name") or ""
            text = tag.text or ""
            kind = tag.get("type", "str")
            try:
                value: TagValue = {"str": str, "int": int, "float": float}[kind](text) if kind != "bool" else (
                    text.strip().lower() == "true")
            except (KeyError, ValueError):
                raise self.error(f"unreadable tag value {shown(text)} of type {shown(kind)}", tag, model=model,
                                 field=f"ddenv:tag '{name}'") from None
            tags[name] = value
        return tags


    def physics(self, world: ET.Element) -> Physics:
        """The world's gravity and `ddenv:physics`; Gazebo's own step (not simulated) must be a positive number."""
        default = Physics()
        for step in world.findall("physics/max_step_size"):
            self.values.number(step, "physics/max_step_size", None, positive=True)
        gravity_element = world.find("gravity")
        if gravity_element is None:
            gravity_element = world.find("physics/gravity")  # SDF 1.4
        gravity = default.gravity
        if gravity_element is not None:
            values = self.floats(gravity_element, (3,), "gravity", None)
            gravity = (values[0], values[1], values[2])
        settings = world.find(f"{{{DDENV_NS}}}physics")
        timestep, iterations = default.timestep, default.solver_iterations
        if settings is not None:
            self.known_attributes(settings, None, WorldError)
            timestep = self.attribute_number(settings, "timestep", timestep, positive=True)
            problem = timestep_problem(timestep)
            if problem is not None:
                raise self.error(problem, settings, field="ddenv:physics/@timestep")
            iterations_value = self.attribute_number(settings, "solver_iterations", float(iterations), positive=True)
            problem = solver_iterations_problem(iterations_value)
            if problem is not None:
                raise self.error(problem, settings, field="ddenv:physics/@solver_iterations")
            iterations = int(iterations_value)
        return Physics(gravity=gravity, timestep=timestep, solver_iterations=iterations)

    def attribute_number(
        self, element: ET.Element, name: str, default: float, *, positive: bool = False,
        kind: type[WorldError] = WorldError,
    ) -> float:
        text = element.get(name)
        if text is None:
            return default
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not math.isfinite(value) or (positive and value <= 0):
            raise self.error(f"expected a {'positive ' if positive else ''}number, got {shown(text)}", element,
                             field=f"ddenv:{local_name(element.tag)}/@{name}", kind=kind)
        return value

    def scenario(self, world: ET.Element, models: Collection[str] | None = None) -> Scenario | None:
        """The world's `ddenv:scenario` (None: none); its target, table and watch models checked to be among
        `models` when given."""
        element = self.single(world, "scenario", "a world", None, kind=ScenarioError)
        if element is None:
            return None
        self.known_attributes(element, None, ScenarioError)
        self.known_children(element, SCENARIO_ELEMENTS, "ddenv:scenario", None, kind=ScenarioError)
        start, goal, description, arm, camera = (self.single(element, tag, "a scenario", None, kind=ScenarioError)
                                                 for tag in SCENARIO_ELEMENTS)
        if description is not None and arm is not None:
            raise self.error("a scenario has one robot: ddenv:robot_description or ddenv:arm_description", arm,
                             field="ddenv:arm_description", kind=ScenarioError)
        if start is None or goal is None:
            raise self.error("ddenv:scenario needs ddenv:start and ddenv:goal", element, field="ddenv:scenario",
                             kind=ScenarioError)
        for point in (start, goal):
            self.known_attributes(point, None, ScenarioError)
            name = local_name(point.tag)
            for key in ("x", "y"):
                if point.get(key) is None:
                    raise self.error(f"missing; {REQUIRED[name]}", point, field=f"ddenv:{name}/@{key}",
                                     kind=ScenarioError)
        default = Scenario()

        def number(owner: ET.Element, name: str, fallback: float, *, positive: bool = False) -> float:
            return self.attribute_number(owner, name, fallback, positive=positive, kind=ScenarioError)

        robot: str | RobotDescription | ArmDescription = str(element.get("robot", default.robot))
        if description is not None:
            robot = self.robot(description)
        elif arm is not None:
            robot = self.arm(arm)
        named = {key: element.get(key) for key in ("target", "table")}
        watch = tuple(dict.fromkeys((element.get("watch") or "").split()))
        for key, names in (("target", [named["target"]]), ("table", [named["table"]]), ("watch", watch)):
            for model in names:
                if model is not None and models is not None and model not in models:
                    raise self.error(f"{shown(model)} is not a model of this world", element,
                                     field=f"ddenv:scenario/@{key}", kind=ScenarioError)
        return Scenario(
            robot=robot,
            start=Pose(x=number(start, "x", 0.0), y=number(start, "y", 0.0), z=number(start, "z", 0.0),
                       yaw=number(start, "yaw", 0.0)),
            start_z_given=start.get("z") is not None,
            goal=(number(goal, "x", 0.0), number(goal, "y", 0.0),
                  number(goal, "z", 0.0) if goal.get("z") is not None else None),
            goal_tolerance=number(element, "goal_tolerance", default.goal_tolerance, positive=True),
            timeout=number(element, "timeout", default.timeout, positive=True),
            target=named["target"], table=named["table"], watch=watch,
            camera=None if camera is None else self.camera(camera),
        )

    def camera(self, element: ET.Element) -> Camera:
        """<ddenv:camera position="X Y Z" look_at="X Y Z" width=".." height=".." kind="rgb|depth" fov=".."/>."""
        self.known_attributes(element, None, ScenarioError)
        points = []
        for key in ("position", "look_at"):
            try:
                point = [float(v) for v in (element.get(key) or "").split()]
            except ValueError:
                point = []
            if len(point) != 3 or not all(math.isfinite(v) for v in point):
                raise self.error(f"expected 3 numbers, got {shown(element.get(key) or '')}", element,
                                 field=f"ddenv:camera/@{key}", kind=ScenarioError)
            points.append((point[0], point[1], point[2]))
        size = {}
        for key in ("width", "height"):
            text = element.get(key, "64")
            size[key] = int(text) if text.isdigit() else -1
        camera = Camera(position=points[0], look_at=points[1], width=size["width"], height=size["height"],
                        kind=element.get("kind", "rgb"),
                        fov=self.attribute_number(element, "fov", 60.0, kind=ScenarioError))
        problem = camera.problem()
        if problem is not None:
            raise self.error(problem[1], element, field=f"ddenv:camera/@{problem[0]}", kind=ScenarioError)
        return camera

    def arm(self, element: ET.Element) -> ArmDescription:
        """<ddenv:arm_description>, written by `dump_sdf` for an arm given as a mapping."""
        field = "ddenv:arm_description"
        self.known_attributes(element, None, ScenarioError)

        def fail(message: str, name: str) -> WorldError:
            return self.error(message, element, field=f"{field}/@{name}", kind=ScenarioError)

        for key in ("urdf", "mjcf"):
            path = element.get(key)
            if (key == "urdf" or path is not None) and (not path or not is_file(resolve_relative(path, self.source))):
                raise fail(f"{key.upper()} file not found: {shown(path or '')}", key)
        joints = {key: tuple(element.get(key, "").split()) for key in ("arm_joints", "finger_joints")}
        for key, names in joints.items():
            if not names:
                raise fail("expected the joint names, separated by spaces", key)
        if not element.get("end_effector"):
            raise fail("expected the end effector's link name", "end_effector")
        home = None
        if element.get("home") is not None:
            try:
                home = tuple(float(v) for v in str(element.get("home")).split())
            except ValueError:
                home = ()
            if len(home) != len(joints["arm_joints"]) or not all(math.isfinite(v) for v in home):
                raise fail(f"expected {len(joints['arm_joints'])} numbers (one per arm joint), got "
                           f"{shown(element.get('home'))}", "home")
        return ArmDescription(
            urdf=str(element.get("urdf")), arm_joints=joints["arm_joints"], finger_joints=joints["finger_joints"],
            end_effector=str(element.get("end_effector")), home=home, mjcf=element.get("mjcf"),
            name=element.get("name", ""),
        )


    def robot(self, element: ET.Element) -> RobotDescription:
        """<ddenv:robot_description>, written by `dump_sdf` for a robot given as a mapping."""
        field = "ddenv:robot_description"

        def fail(message: str, name: str) -> WorldError:
            return self.error(message, element, field=f"{field}/@{name}", kind=ScenarioError)

        self.known_attributes(element, None, ScenarioError)

        urdf = element.get("urdf", "")
        if not urdf or not is_file(resolve_relative(urdf, self.source)):  # relative: to the SDF file
            raise fail(f"URDF file not found: {shown(urdf)}", "urdf")
        drive = element.get("drive", "differential")
        if drive not in DRIVE_KINDS:
            raise fail(f"expected one of {', '.join(DRIVE_KINDS)}, got {shown(drive)}", "drive")
        wheels = {side: tuple(element.get(side, "").split()) for side in ("left_wheels", "right_wheels")}
        for side, names in wheels.items():
            if not names:
                raise fail("expected the wheel joint names, separated by spaces", side)

        def optional(name: str) -> float | None:
            if element.get(name) is None:
                return None
            return self.attribute_number(element, name, 1.0, positive=True, kind=ScenarioError)

        laser_text = element.get("laser", "true")
        laser: bool | LaserMount = laser_text == "true"
        if laser_text not in ("true", "false"):
            try:
                numbers = [float(v) for v in laser_text.split()]
                if len(numbers) not in (2, 5) or not all(math.isfinite(v) for v in numbers):
                    raise ValueError(laser_text)
            except ValueError:
                raise fail(f"expected true, false, 'HEIGHT MIN_RANGE' or 'HEIGHT MIN_RANGE X Y YAW', got "
                           f"{shown(laser_text)}", "laser") from None
            laser = LaserMount(*numbers)
        return RobotDescription(
            urdf=urdf, left_wheels=wheels["left_wheels"], right_wheels=wheels["right_wheels"], drive=drive,
            wheel_radius=optional("wheel_radius"), track=optional("track"), track_factor=optional("track_factor"),
            max_wheel_torque=optional("max_wheel_torque") or 20.0, laser=laser, name=element.get("name", ""),
        )


def ddenv_name(tag: str) -> str | None:
    """The local name of a tag (or attribute key) in the `ddenv:` namespace, None for any other."""
    prefix = f"{{{DDENV_NS}}}"
    return tag[len(prefix):] if tag.startswith(prefix) else None
