"""Export a `World` as an SDF world that Gazebo loads (1.6, or 1.8 with capsules): no `<state>` block, nothing
left of removed models.

Every model becomes one static or dynamic model with one link whose collisions and visuals are the model's
shapes. What SDF has no element for (the scenario, PyBullet's step and solver settings, `keep`, tags) is
written in `ddenv:` elements, which Gazebo ignores and `load_sdf` reads back, so that YAML -> SDF -> YAML is
lossless.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Sequence

from pytest_ddenv.sdf._reader import DDENV_NS, collada_unit
from pytest_ddenv.validation import is_flag
from pytest_ddenv.world.files import resolve_mesh_path, resolve_relative
from pytest_ddenv.world.model import (
    ArmDescription,
    Ground,
    LaserMount,
    Model,
    Pose,
    RobotDescription,
    Scenario,
    Shape,
    World,
)

SDF_VERSION = "1.6"
CAPSULE_SDF_VERSION = "1.8"
"""The first SDF version with `<capsule>` (libsdformat 11+); written only for worlds that have one."""
CONE_SDF_VERSION = "1.11"
"""The first SDF version with `<cone>` (libsdformat 14+, Gazebo Harmonic); written only for worlds that have one."""
GAZEBO_PHYSICS = {"max_step_size": "0.001", "real_time_factor": "1", "real_time_update_rate": "1000"}
GROUND_COLOR = (0.8, 0.8, 0.8, 1.0)
ET.register_namespace("ddenv", DDENV_NS)


def _number(value: float) -> str:
    return repr(float(value))


def _numbers(values: Sequence[float]) -> str:
    return " ".join(_number(v) for v in values)


def _pose(pose: Pose) -> str:
    return _numbers(pose.as_list())


def _sub(parent: ET.Element, tag: str, text: str | None = None, **attributes: str) -> ET.Element:
    element = ET.SubElement(parent, tag, attributes)
    if text is not None:
        element.text = text
    return element


def _ddenv(tag: str) -> str:
    return f"{{{DDENV_NS}}}{tag}"


# -- geometry -----------------------------------------------------------------------------------------------
def _geometry(parent: ET.Element, shape: Shape, source: str | None) -> None:
    geometry = _sub(parent, "geometry")
    if shape.kind == "box":
        assert shape.size is not None
        _sub(_sub(geometry, "box"), "size", _numbers(shape.size))
    elif shape.kind == "cylinder":
        cylinder = _sub(geometry, "cylinder")
        _sub(cylinder, "radius", _number(shape.radius or 0.0))
        _sub(cylinder, "length", _number(shape.length or 0.0))
    elif shape.kind == "sphere":
        _sub(_sub(geometry, "sphere"), "radius", _number(shape.radius or 0.0))
    elif shape.kind in ("capsule", "cone"):  # SDF 1.8+ and 1.11+: `dump_sdf` writes that version for them
        element = _sub(geometry, shape.kind)
        _sub(element, "radius", _number(shape.radius or 0.0))
        _sub(element, "length", _number(shape.length or 0.0))
    elif shape.kind == "polyline":
        assert shape.points is not None
        polyline = _sub(geometry, "polyline")
        for point in shape.points:
            _sub(polyline, "point", _numbers(point))
        _sub(polyline, "height", _number(shape.height or 0.0))
    elif shape.kind == "heightmap":
        assert shape.size is not None
        heightmap = _sub(geometry, "heightmap")
        _sub(heightmap, "uri", resolve_mesh_path(shape.mesh, source).resolve().as_uri())
        _sub(heightmap, "size", _numbers(shape.size))
    else:
        path = resolve_mesh_path(shape.mesh, source).resolve()
        unit = collada_unit(path) if path.suffix.lower() == ".dae" else 1.0
        mesh = _sub(geometry, "mesh")
        _sub(mesh, "uri", path.as_uri())
        _sub(mesh, "scale", _numbers([s / unit for s in shape.scale]))


def _surface(parent: ET.Element, mu: float, mu2: float, restitution: float) -> None:
    surface = _sub(parent, "surface")
    friction = _sub(surface, "friction")
    ode = _sub(friction, "ode")
    _sub(ode, "mu", _number(mu))
    _sub(ode, "mu2", _number(mu2))
    bullet = _sub(friction, "bullet")
    _sub(bullet, "friction", _number(mu))
    _sub(bullet, "friction2", _number(mu2))
    if restitution:
        _sub(_sub(surface, "bounce"), "restitution_coefficient", _number(restitution))


def _material(parent: ET.Element, color: Sequence[float]) -> None:
    material = _sub(parent, "material")
    for tag in ("ambient", "diffuse"):
        _sub(material, tag, _numbers(color))


# -- inertia ----------------------------------------------------------------------------------------------------
def _inertia(model: Model, source: str | None) -> tuple[Pose, tuple[float, float, float]]:
    """Centre of mass and principal moments: exact for one primitive, else the model's bounding box."""
    assert model.mass is not None
    mass = model.mass
    if len(model.shapes) == 1 and model.shapes[0].kind in ("box", "cylinder", "sphere"):
        shape = model.shapes[0]
        if shape.kind == "box":
            assert shape.size is not None
            x, y, z = shape.size
            return shape.pose, (mass * (y * y + z * z) / 12, mass * (x * x + z * z) / 12, mass * (x * x + y * y) / 12)
        assert shape.radius is not None
        r = shape.radius
        if shape.kind == "sphere":
            moment = 2 * mass * r * r / 5
            return shape.pose, (moment, moment, moment)
        h = shape.length or 0.0
        side = mass * (3 * r * r + h * h) / 12
        return shape.pose, (side, side, mass * r * r / 2)
    local = World(models=(Model(model.name, model.shapes),), ground=None, source=source)
    low, high = local.bounds(model.name)
    x, y, z = (float(v) for v in high - low)
    centre = (low + high) / 2.0
    return Pose(*(float(v) for v in centre)), (
        mass * (y * y + z * z) / 12, mass * (x * x + z * z) / 12, mass * (x * x + y * y) / 12)


def _inertial(link: ET.Element, model: Model, source: str | None) -> None:
    assert model.mass is not None
    inertial = _sub(link, "inertial")
    centre, (ixx, iyy, izz) = _inertia(model, source)
    _sub(inertial, "pose", _pose(centre))
    _sub(inertial, "mass", _number(model.mass))
    inertia = _sub(inertial, "inertia")
    for tag, value in (("ixx", ixx), ("ixy", 0.0), ("ixz", 0.0), ("iyy", iyy), ("iyz", 0.0), ("izz", izz)):
        _sub(inertia, tag, _number(value))


# -- models -------------------------------------------------------------------------------------------------------
def _model(parent: ET.Element, model: Model, source: str | None) -> None:
    element = _sub(parent, "model", name=model.name)
    _sub(element, "static", "true" if model.static else "false")
    _sub(element, "pose", _pose(model.pose))
    link = _sub(element, "link", name="link")
    if model.mass is not None:
        _inertial(link, model, source)
    for index, shape in enumerate(model.shapes):
        collision = _sub(link, "collision", name=f"collision_{index}")
        _sub(collision, "pose", _pose(shape.pose))
        _geometry(collision, shape, source)
        _surface(collision, model.mu, model.mu2, model.restitution)
    for index, shape in enumerate(model.shapes):
        visual = _sub(link, "visual", name=f"visual_{index}")
        _sub(visual, "pose", _pose(shape.pose))
        _geometry(visual, shape, source)
        _material(visual, model.color)
    if model.keep:
        _sub(element, _ddenv("keep"), "true")
    for name, value in model.tags.items():
        kind = "bool" if is_flag(value) else type(value).__name__
        text = ("true" if value else "false") if is_flag(value) else (
            repr(value) if isinstance(value, float) else str(value))
        _sub(element, _ddenv("tag"), text, name=name, type=kind)


def _ground(parent: ET.Element, ground: Ground, taken: set[str]) -> None:
    name = "ground_plane"
    while name in taken:
        name += "_"
    element = _sub(parent, "model", name=name)
    _sub(element, "static", "true")
    _sub(element, "pose", _pose(Pose(z=ground.z)))
    link = _sub(element, "link", name="link")
    collision = _sub(link, "collision", name="collision")
    plane = _sub(_sub(collision, "geometry"), "plane")
    _sub(plane, "normal", "0 0 1")
    _sub(plane, "size", "100 100")
    _surface(collision, ground.mu, ground.mu2, ground.restitution)
    visual = _sub(link, "visual", name="visual")
    plane = _sub(_sub(visual, "geometry"), "plane")
    _sub(plane, "normal", "0 0 1")
    _sub(plane, "size", "100 100")
    _material(visual, GROUND_COLOR)


def _sun(parent: ET.Element) -> None:
    light = _sub(parent, "light", name="sun", type="directional")
    _sub(light, "cast_shadows", "true")
    _sub(light, "pose", "0 0 10 0 0 0")
    _sub(light, "diffuse", "0.8 0.8 0.8 1")
    _sub(light, "specular", "0.2 0.2 0.2 1")
    attenuation = _sub(light, "attenuation")
    for tag, value in (("range", "1000"), ("constant", "0.9"), ("linear", "0.01"), ("quadratic", "0.001")):
        _sub(attenuation, tag, value)
    _sub(light, "direction", "-0.5 0.1 -0.9")


def _scenario(parent: ET.Element, scenario: Scenario, source: str | None,
              names: tuple[str, ...] | None = None) -> None:
    robot = scenario.robot
    name = robot if isinstance(robot, str) else robot.label
    named = {key: value for key, value in (("target", scenario.target), ("table", scenario.table)) if value}
    watch = " ".join(m for m in scenario.watch if names is None or m in names)  # a reduced world may lack some
    element = _sub(parent, _ddenv("scenario"), robot=name, timeout=_number(scenario.timeout),
                   goal_tolerance=_number(scenario.goal_tolerance), **named, **({"watch": watch} if watch else {}))
    if isinstance(robot, RobotDescription):
        _robot_description(element, robot, source)
    elif isinstance(robot, ArmDescription):
        _arm_description(element, robot, source)
    camera = scenario.camera
    if camera is not None:
        _sub(element, _ddenv("camera"), position=_numbers(camera.position), look_at=_numbers(camera.look_at),
             width=str(camera.width), height=str(camera.height), kind=camera.kind, fov=_number(camera.fov))
    start = {"x": _number(scenario.start.x), "y": _number(scenario.start.y)}
    if scenario.start_z_given:
        start["z"] = _number(scenario.start.z)
    start["yaw"] = _number(scenario.start.yaw)
    _sub(element, _ddenv("start"), **start)
    goal = {"x": _number(scenario.goal[0]), "y": _number(scenario.goal[1])}
    if scenario.goal[2] is not None:
        goal["z"] = _number(scenario.goal[2])
    _sub(element, _ddenv("goal"), **goal)


def _robot_description(parent: ET.Element, robot: RobotDescription, source: str | None) -> None:
    """The robot mapping as <ddenv:robot_description> (the URDF path made absolute: SDF files move)."""
    attributes = {"urdf": str(resolve_relative(robot.urdf, source).resolve()), "drive": robot.drive,
                  "left_wheels": " ".join(robot.left_wheels), "right_wheels": " ".join(robot.right_wheels),
                  "max_wheel_torque": _number(robot.max_wheel_torque)}
    for key in ("wheel_radius", "track", "track_factor"):
        if getattr(robot, key) is not None:
            attributes[key] = _number(getattr(robot, key))
    if isinstance(robot.laser, LaserMount):
        mount = robot.laser
        place = (mount.x, mount.y, mount.yaw)
        numbers = (mount.height, mount.min_range, *(place if any(place) else ()))
        attributes["laser"] = " ".join(_number(v) for v in numbers)
    else:
        attributes["laser"] = "true" if robot.laser else "false"
    if robot.name:
        attributes["name"] = robot.name
    _sub(parent, _ddenv("robot_description"), **attributes)


def _arm_description(parent: ET.Element, robot: ArmDescription, source: str | None) -> None:
    """The arm mapping as <ddenv:arm_description> (file paths made absolute: SDF files move)."""
    attributes = {"urdf": str(resolve_relative(robot.urdf, source).resolve()),
                  "arm_joints": " ".join(robot.arm_joints), "finger_joints": " ".join(robot.finger_joints),
                  "end_effector": robot.end_effector}
    if robot.home is not None:
        attributes["home"] = " ".join(_number(v) for v in robot.home)
    if robot.mjcf is not None:
        attributes["mjcf"] = str(resolve_relative(robot.mjcf, source).resolve())
    if robot.name:
        attributes["name"] = robot.name
    _sub(parent, _ddenv("arm_description"), **attributes)


def dump_sdf(world: World) -> str:
    """The world as SDF text (a `<world>` with a sun, Gazebo physics, the ground plane and the models): version
    1.6, or 1.8 when a model has a capsule (1.6 has no `<capsule>`), 1.11 when one has a cone."""
    kinds = {shape.kind for model in world.models for shape in model.shapes}
    version = CONE_SDF_VERSION if "cone" in kinds else CAPSULE_SDF_VERSION if "capsule" in kinds else SDF_VERSION
    root = ET.Element("sdf", version=version)
    element = _sub(root, "world", name=world.name or "default")
    _sub(element, "gravity", _numbers(world.physics.gravity))
    physics = _sub(element, "physics", name="default_physics", default="0", type="ode")
    for tag, value in GAZEBO_PHYSICS.items():
        _sub(physics, tag, value)
    _sub(element, _ddenv("physics"), timestep=_number(world.physics.timestep),
         solver_iterations=str(world.physics.solver_iterations))
    if world.scenario is not None:
        _scenario(element, world.scenario, world.source, world.names)
    _sun(element)
    if world.ground is not None:
        _ground(element, world.ground, set(world.names))
    for model in world.models:
        _model(element, model, world.source)
    ET.indent(root, space="  ")
    return '<?xml version="1.0" ?>\n' + ET.tostring(root, encoding="unicode") + "\n"

