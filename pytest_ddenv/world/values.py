"""The values a world may hold, checked for every world however it was made: each number within what the
simulator takes (`limits.MAX_MAGNITUDE`, `limits.MAX_GRAVITY`), each shape valid for its kind: a world beyond
is refused with one error naming the file, the model and the field, never simulated with parts silently
missing.

The YAML reader checks each value as it reads it (`limits.magnitude_problem`, `check_shape`);
`check_world_values` checks a whole `World` the same way, for the worlds other readers and the Python API
make (`World.load`, `World.save`, `RobotWorld`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any

from pytest_ddenv.errors import ScenarioError, WorldError, shown
from pytest_ddenv.validation import expected, is_flag, is_real
from pytest_ddenv.world.files import regular_file_problem, resolve_relative
from pytest_ddenv.world.limits import (
    MAX_GRAVITY,
    MAX_MAGNITUDE,
    name_problem,
    number_problem,
    solver_iterations_problem,
    timestep_problem,
)
from pytest_ddenv.world.meshes import check_heightmap_image, polyline_problem
from pytest_ddenv.world.model import (
    ENGINES,
    SHAPE_KINDS,
    ArmDescription,
    Ground,
    LaserMount,
    Model,
    Physics,
    Pose,
    RobotDescription,
    Scenario,
    Shape,
    World,
)

Fail = Callable[[str, str], WorldError]
"""Makes the error for a field and a reason."""


def check_world_values(world: World) -> None:
    """Raise a `WorldError` (a `ScenarioError` for the scenario) naming the world's source, the model and the
    field of the first value the simulator cannot take: a wrong type, a number that is not finite or beyond
    MAX_MAGNITUDE (MAX_GRAVITY for gravity), a negative size, a bad name. Files are not opened."""
    if not isinstance(world, World):
        raise WorldError(expected("a World", world))
    for index, model in enumerate(world.models):
        check_model_values(model, index, world.source)
    if world.scenario is not None:
        _check_scenario(world.scenario, world.source)
    _check_physics(world.physics, world.source)
    if world.ground is not None:
        _check_ground(world.ground, world.source)


def check_model_values(model: Model, index: int, source: str | None) -> None:
    """`check_world_values` for the model at `index` of a world read from `source`."""
    if not isinstance(model, Model):
        raise WorldError(expected("a Model", model), source=source, model=f"#{index}")
    name = model.name
    problem = name_problem(name) if isinstance(name, str) else expected("a non-empty string", name)
    if problem is not None:
        raise WorldError(problem, source=source, model=f"#{index}", field="name")
    label = f"'{name}' (#{index})"

    def fail(field: str, reason: str) -> WorldError:
        return WorldError(reason, source=source, model=label, field=field)

    if not isinstance(model.shapes, (tuple, list)) or not model.shapes:
        raise fail("shapes", expected("a non-empty tuple of Shapes", model.shapes))
    for number, shape in enumerate(model.shapes):
        where = f"shapes[{number}]"
        if not isinstance(shape, Shape):
            raise fail(where, expected("a Shape", shape))
        _check_pose(shape.pose, f"{where}.pose", fail)
        check_shape(shape, source=source, model=label, field=where, static=model.static, files=False)
    _check_pose(model.pose, "pose", fail)
    for field in ("static", "keep"):
        if not is_flag(getattr(model, field)):
            raise fail(field, expected("true or false", getattr(model, field)))
    if model.mass is not None:
        _check_number(model.mass, "mass", fail, positive=True)
    for field in ("mu", "mu2", "restitution"):
        _check_number(getattr(model, field), field, fail, non_negative=True)
    color = model.color
    if not isinstance(color, (tuple, list)) or len(color) != 4 or not all(
            is_real(c) and 0.0 <= c <= 1.0 for c in color):
        raise fail("color", expected("4 components (red, green, blue, alpha) between 0 and 1", color))
    if not isinstance(model.tags, Mapping):
        raise fail("tags", expected("a mapping of tag names to values", model.tags))


def _check_number(value: Any, field: str, fail: Fail, *, positive: bool = False, non_negative: bool = False,
                  limit: float = MAX_MAGNITUDE) -> None:
    problem = number_problem(value, positive=positive, non_negative=non_negative, limit=limit)
    if problem is not None:
        raise fail(field, problem)


def _check_numbers(values: Iterable[tuple[str, Any]], fail: Fail, **rule: Any) -> None:
    for field, value in values:
        _check_number(value, field, fail, **rule)


def _check_pose(pose: Any, field: str, fail: Fail, axes: Sequence[str] = ()) -> None:
    if not isinstance(pose, Pose):
        raise fail(field, expected("a Pose", pose))
    values = pose.as_list()
    names = axes or [f"{field}[{index}]" for index in range(6)]
    _check_numbers(zip(names, values, strict=False), fail)


def _check_scenario(scenario: Scenario, source: str | None) -> None:
    def fail(field: str, reason: str) -> ScenarioError:
        return ScenarioError(reason, source=source, field=f"scenario.{field}")

    if not isinstance(scenario, Scenario):
        raise ScenarioError(expected("a Scenario", scenario), source=source, field="scenario")
    robot = scenario.robot
    if isinstance(robot, RobotDescription):
        _check_robot(robot, fail)
    elif isinstance(robot, ArmDescription):
        _check_numbers(((f"robot.home[{index}]", value) for index, value in enumerate(robot.home or ())), fail)
    elif not isinstance(robot, str) or not robot:
        raise fail("robot", expected("a registered robot's name, a RobotDescription or an ArmDescription", robot))
    _check_pose(scenario.start, "start", fail, [f"start.{axis}" for axis in ("x", "y", "z", "roll", "pitch", "yaw")])
    goal = scenario.goal
    if not isinstance(goal, (tuple, list)) or len(goal) != 3:
        raise fail("goal", expected("(x, y, z or None)", goal))
    _check_numbers(zip(("goal.x", "goal.y", "goal.z"), goal if goal[2] is not None else goal[:2], strict=False), fail)
    _check_number(scenario.goal_tolerance, "goal_tolerance", fail, positive=True)
    _check_number(scenario.timeout, "timeout", fail, positive=True)
    camera = scenario.camera
    if camera is not None:
        _check_numbers(((f"camera.{key}[{axis}]", value) for key in ("position", "look_at")
                        for axis, value in enumerate(getattr(camera, key))), fail)
        _check_number(camera.fov, "camera.fov", fail, positive=True)
        problem = camera.problem()
        if problem is not None:
            raise fail(f"camera.{problem[0]}", problem[1])


def _check_robot(robot: RobotDescription, fail: Fail) -> None:
    for field in ("wheel_radius", "track", "track_factor"):
        if getattr(robot, field) is not None:
            _check_number(getattr(robot, field), f"robot.{field}", fail, positive=True)
    _check_number(robot.max_wheel_torque, "robot.max_wheel_torque", fail, positive=True)
    if isinstance(robot.laser, LaserMount):
        mount = robot.laser
        _check_numbers(((f"robot.laser.{key}", getattr(mount, key)) for key in ("height", "x", "y", "yaw")), fail)
        _check_number(mount.min_range, "robot.laser.min_range", fail, non_negative=True)
    elif not is_flag(robot.laser):
        raise fail("robot.laser", expected("true, false or a LaserMount", robot.laser))


def _check_physics(physics: Physics, source: str | None) -> None:
    def fail(field: str, reason: str) -> WorldError:
        return WorldError(reason, source=source, field=f"physics.{field}")

    if not isinstance(physics, Physics):
        raise WorldError(expected("a Physics", physics), source=source, field="physics")
    gravity = physics.gravity
    if not isinstance(gravity, (tuple, list)) or len(gravity) != 3:
        raise fail("gravity", expected("3 numbers (m/s^2)", gravity))
    _check_numbers(((f"gravity[{axis}]", value) for axis, value in enumerate(gravity)), fail, limit=MAX_GRAVITY)
    _check_number(physics.timestep, "timestep", fail, positive=True)
    problem = timestep_problem(physics.timestep) or solver_iterations_problem(physics.solver_iterations)
    if problem is not None:
        raise fail("timestep" if "timestep" in problem else "solver_iterations", problem)
    if physics.engine not in ENGINES:
        raise fail("engine", expected(f"one of {', '.join(ENGINES)}", physics.engine))


def _check_ground(ground: Ground, source: str | None) -> None:
    def fail(field: str, reason: str) -> WorldError:
        return WorldError(reason, source=source, field=f"ground.{field}")

    if not isinstance(ground, Ground):
        raise WorldError(expected("a Ground or None", ground), source=source, field="ground")
    _check_number(ground.z, "z", fail)
    _check_numbers(((field, getattr(ground, field)) for field in ("mu", "mu2", "restitution")), fail,
                   non_negative=True)


def check_shape(shape: Shape, *, source: str | None = None, model: str | None = None, field: str | None = None,
                static: bool = True, keys: Mapping[str, str] | None = None, files: bool = True) -> None:
    """Raise a `WorldError` naming the file, model and field if `shape` is not a valid shape of its kind.

    For readers of world files: `field` is where the shape is (e.g. "shapes[0].polyline"); the bad value is
    named `field.KEY` with KEY one of radius, length, size, points, height, file, scale, renamed by `keys`
    (e.g. {"points": "point", "file": "uri"} for SDF). `static`: whether the model is static (a heightmap
    must be: it is terrain). Sizes are positive numbers within `limits.MAX_MAGNITUDE`. `files`: whether
    the mesh or heightmap file is checked too (a regular file; a heightmap's image opens).
    """
    from pytest_ddenv.world.limits import number_problem

    def fail(key: str | None, message: str) -> WorldError:
        name = None if key is None else (keys or {}).get(key, key)
        where = field if name is None else (name if field is None else f"{field}.{name}")
        return WorldError(message, source=source, model=model, field=where)

    def positive(key: str, value: float | None) -> None:
        if value is None:
            raise fail(key, f"missing; a {shape.kind} needs a {key}")
        problem = number_problem(value, positive=True)
        if problem is not None:
            raise fail(key, problem)

    def sizes(key: str, values: object) -> None:
        if not isinstance(values, (tuple, list)) or len(values) != 3:
            raise fail(key, f"expected 3 {key}s (x, y, z), got {shown(values)}")
        for value in values:
            problem = number_problem(value, positive=True)
            if problem is not None:
                raise fail(key, f"{problem} (in {shown(list(values))})")

    if shape.kind not in SHAPE_KINDS:
        raise fail(None, f"unknown shape kind {shape.kind!r}; expected one of {', '.join(SHAPE_KINDS)}")
    if shape.kind in ("box", "heightmap"):
        sizes("size", shape.size)
    if shape.kind in ("cylinder", "capsule", "sphere"):
        positive("radius", shape.radius)
    if shape.kind in ("cylinder", "capsule"):
        positive("length", shape.length)
    if shape.kind == "cone":
        positive("radius", shape.radius)
        positive("length", shape.length)
    if shape.kind == "polyline":
        problem = polyline_problem(shape.points or ())
        if problem is not None:
            raise fail("points", problem)
        positive("height", shape.height)
    if shape.kind == "mesh":
        sizes("scale", shape.scale)
    if shape.kind in ("mesh", "heightmap") and (not shape.mesh or not isinstance(shape.mesh, str)):
        raise fail("file", f"missing; a {shape.kind} needs a file")
    if shape.kind == "heightmap" and not static:
        raise fail(None, "a heightmap is terrain and must be static; remove the model's mass or 'static: false'")
    if files and shape.kind in ("mesh", "heightmap"):
        assert shape.mesh is not None
        path = resolve_relative(shape.mesh, source)
        problem = regular_file_problem(path, "mesh file" if shape.kind == "mesh" else "heightmap image file")
        if problem is not None:
            raise fail("file", problem)
        if shape.kind == "heightmap":
            check_heightmap_image(path, fail)
