"""The YAML world format (`format: 1`): strict parsing with errors that name file, model and field.

The format is documented field by field in docs/world-format.md. Reading is bounded for hostile files (see
docs/reliability.md): at most MAX_FILE_BYTES, then the limits of `_bounded_yaml`; every value shown in a
message is clipped (`errors.shown`).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, Literal

import yaml

from pytest_ddenv.errors import (
    SHOWN_CHARACTERS,
    ScenarioError,
    WorldError,
    shown,
)
from pytest_ddenv.validation import expected, is_flag, is_number
from pytest_ddenv.world._bounded_yaml import Dumper, load_document
from pytest_ddenv.world._robot_yaml import parse_robot, rebased, robot_dict
from pytest_ddenv.world.files import read_regular, regular_file_problem, resolve_mesh_path
from pytest_ddenv.world.limits import (
    MAX_GRAVITY,
    MAX_MAGNITUDE,
    engine_problem,
    magnitude_problem,
    name_problem,
    solver_iterations_problem,
    text_problem,
    timestep_problem,
)
from pytest_ddenv.world.meshes import check_mesh_file
from pytest_ddenv.world.model import (
    SHAPE_KINDS,
    Camera,
    Ground,
    Model,
    Physics,
    Pose,
    Scenario,
    Shape,
    TagValue,
    World,
)
from pytest_ddenv.world.values import check_shape

FORMAT_VERSION = 1
TOP_LEVEL_KEYS = ("format", "name", "physics", "ground", "scenario", "models")
MODEL_KEYS = (
    "name", "pose", "shapes", *SHAPE_KINDS, "static", "mass", "mu", "mu2", "restitution", "color", "keep", "tags",
)
SHAPE_KEYS = (*SHAPE_KINDS, "pose")
SCENARIO_KEYS = ("robot", "start", "goal", "goal_tolerance", "timeout", "target", "table", "watch", "camera")
CAMERA_KEYS = ("position", "look_at", "width", "height", "kind", "fov")
WRITTEN_DEFAULT_ENGINE = "pybullet"
"""The engine a written world leaves unnamed (files without `physics.engine` have always meant pybullet; a
file read where pybullet is not installed gets mujoco, `limits.default_engine`)."""
PHYSICS_KEYS = ("gravity", "timestep", "solver_iterations", "engine")
GROUND_KEYS = ("z", "mu", "mu2", "restitution")
MAX_FILE_BYTES = 50 * 1024 * 1024
class _Reader:
    """Validates one document; knows where it is (file, model) to build precise errors."""

    def __init__(self, source: str | None) -> None:
        self.source = source
        self.model: str | None = None
        self.error_type: type[WorldError] = WorldError

    def fail(self, field: str | None, message: str) -> WorldError:
        return self.error_type(message, source=self.source, model=self.model, field=field)

    def wrong(self, field: str | None, what: str, value: Any, hint: str = "") -> WorldError:
        """`value` at `field` is not `what`: "expected {what}, got {value, described}" (and `hint`)."""
        return self.fail(field, expected(what, value, got=_describe(value)) + hint)

    def mapping(self, value: Any, field: str, allowed: tuple[str, ...]) -> Mapping[str, Any]:
        if not isinstance(value, Mapping):
            raise self.wrong(field, f"a mapping of {', '.join(allowed)}", value)
        for key in value:
            if key not in allowed:
                name = key if isinstance(key, str) and not text_problem(key) else shown(key)
                path = f"{field}.{name}" if field else str(name)
                raise self.fail(
                    path if len(path) <= SHOWN_CHARACTERS else f"{path[:SHOWN_CHARACTERS - 3]}...",
                    f"unknown key {shown(key)}; expected one of: {', '.join(allowed)}",
                )
        return value

    def number(self, value: Any, field: str, *, positive: bool = False, non_negative: bool = False,
               limit: float = MAX_MAGNITUDE) -> float:
        """A finite number, at most `limit` in absolute value (what the simulator takes, `limits`)."""
        if not is_number(value):
            raise self.wrong(field, "a number", value, _number_hint(value))
        try:
            number = float(value)
        except OverflowError:  # an integer of hundreds of digits
            number = math.inf
        if not math.isfinite(number):
            raise self.fail(field, expected("a finite number", value))
        if positive and number <= 0:
            raise self.fail(field, expected("a positive number", number))
        if non_negative and number < 0:
            raise self.fail(field, expected("a number >= 0", number))
        problem = magnitude_problem(number, limit)
        if problem is not None:
            raise self.fail(field, problem)
        return number

    def numbers(self, value: Any, field: str, counts: tuple[int, ...], *, positive: bool = False,
                limit: float = MAX_MAGNITUDE) -> list[float]:
        if not isinstance(value, (list, tuple)) or len(value) not in counts:
            raise self.wrong(field, f"a list of {' or '.join(str(c) for c in counts)} numbers", value)
        return [self.number(item, f"{field}[{i}]", positive=positive, limit=limit) for i, item in enumerate(value)]

    def pose(self, value: Any, field: str) -> Pose:
        return Pose(*self.numbers(value, field, (3, 6)))

    def boolean(self, value: Any, field: str) -> bool:
        if not is_flag(value):
            raise self.wrong(field, "true or false", value)
        return value

    def text(self, value: Any, field: str) -> str:
        if not isinstance(value, str) or not value.strip():
            hint = (" (text that reads as a number or true/false must be quoted, e.g. '1e5')"
                    if isinstance(value, (int, float)) else "")
            raise self.wrong(field, "a non-empty string", value, hint)
        problem = text_problem(value)
        if problem is not None:
            raise self.fail(field, f"{problem}, got {shown(value)}")
        return value

    def name(self, value: Any, field: str) -> str:
        """A name that is written to SDF and read back unchanged (see `world.name_problem`)."""
        text = self.text(value, field)
        problem = name_problem(text)
        if problem is not None:
            raise self.fail(field, f"{problem}, got {shown(text)}")
        return text


def _describe(value: Any) -> str:
    if isinstance(value, str):
        return f"the string {shown(value)}"
    if value is None:
        return "nothing (null)"
    if isinstance(value, (list, tuple, Mapping)):
        return f"a {'mapping' if isinstance(value, Mapping) else 'list'} of {len(value)} items: {shown(value)}"
    return f"{type(value).__name__} {shown(value)}"


def _number_hint(value: Any) -> str:
    """Why a string that looks like a number is not one."""
    if isinstance(value, str) and value.strip() != value and _is_float(value.strip()):
        return " (quoted or padded: write the number alone)"
    if isinstance(value, str) and _is_float(value):
        return " (a number in quotes is a string: remove the quotes)"
    return ""


def _is_float(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def load_yaml(path: str | os.PathLike[str]) -> World:
    path = Path(path)
    data = read_regular(path, MAX_FILE_BYTES)
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as error:
        raise WorldError(
            f"not a world file: byte {error.object[error.start]:#04x} at offset {error.start} is not UTF-8 text "
            "(a world file is YAML, or SDF named .sdf or .world)", source=path,
        ) from None
    return parse_yaml(text, source=path)


def parse_yaml(text: str, *, source: str | os.PathLike[str] | None = None) -> World:
    if not isinstance(text, (str, bytes)):
        raise WorldError(expected("YAML text (a str)", text, "World.from_yaml(text=...)"))
    source_name = str(source) if source is not None else None
    document = load_document(text, source_name)
    reader = _Reader(source_name)
    root = _root(reader, document)
    if root["format"] != FORMAT_VERSION or isinstance(root["format"], bool):
        raise reader.fail("format", f"unknown format version {shown(root['format'])}; this reader supports "
                                    f"{FORMAT_VERSION}")
    name = reader.name(root["name"], "name") if "name" in root else (Path(source_name).stem if source_name else "")
    models_value = root.get("models")
    if models_value is None:  # no 'models' key, or 'models:' with nothing after it
        models_value = []
    if not isinstance(models_value, list):
        raise reader.wrong("models", "a list of models", models_value, " (write 'models: []' for none)")
    models = []
    seen: dict[str, int] = {}
    for index, item in enumerate(models_value):
        model = _parse_model(reader, item, index)
        if model.name in seen:
            raise WorldError(
                f"duplicate model name {shown(model.name)} (also model #{seen[model.name]}); names must be unique",
                source=source_name, model=f"#{index}", field="name",
            )
        seen[model.name] = index
        models.append(model)
    reader.model = None
    return World(
        models=tuple(models),
        scenario=_parse_scenario(reader, root["scenario"], seen) if root.get("scenario") is not None else None,
        physics=_parse_physics(reader, root.get("physics")),
        ground=_parse_ground(reader, root.get("ground", {})),
        name=name,
        source=source_name,
    )


def _root(reader: _Reader, document: Any) -> Mapping[str, Any]:
    """The top-level mapping, or a WorldError that says when the file is no world file at all."""
    world_file = f"a world file is a YAML mapping that starts with 'format: {FORMAT_VERSION}'"
    if document is None:
        raise reader.fail(None, f"the file is empty (or only comments); {world_file}")
    if not isinstance(document, Mapping):
        raise reader.fail(None, f"not a world file: {world_file}; this file holds {_describe(document)}")
    unknown = [key for key in document if key not in TOP_LEVEL_KEYS]
    if "format" not in document and unknown:
        keys = ", ".join(shown(key) for key in unknown[:5]) + (", ..." if len(unknown) > 5 else "")
        raise reader.fail(None, f"not a world file: no 'format' key and unknown keys {keys}; {world_file}")
    root = reader.mapping(document, "", TOP_LEVEL_KEYS)
    if "format" not in root:
        raise reader.fail("format", f"missing; this reader expects 'format: {FORMAT_VERSION}'")
    return root


def _parse_model(reader: _Reader, item: Any, index: int) -> Model:
    reader.model = f"#{index}"
    data = reader.mapping(item, "", MODEL_KEYS)
    if "name" not in data:
        raise reader.fail("name", "missing; every model needs a unique name")
    name = reader.name(data["name"], "name")
    reader.model = f"'{name}' (#{index})"
    inline = [kind for kind in SHAPE_KINDS if kind in data]
    if "shapes" in data and inline:
        raise reader.fail("shapes", f"give either 'shapes' or a single '{inline[0]}', not both")
    if len(inline) > 1:
        raise reader.fail(inline[1], f"a model has one inline shape; use 'shapes' for {', '.join(inline)}")
    shapes: tuple[Shape, ...]
    if inline:
        shapes = (_parse_shape(reader, {inline[0]: data[inline[0]]}, inline[0]),)
    elif "shapes" in data:
        raw_shapes = data["shapes"]
        if not isinstance(raw_shapes, list) or not raw_shapes:
            raise reader.wrong("shapes", "a non-empty list of shapes", raw_shapes)
        shapes = tuple(_parse_shape(reader, raw, f"shapes[{i}]") for i, raw in enumerate(raw_shapes))
    else:
        raise reader.fail("shapes", f"missing; give 'shapes' or one of {', '.join(SHAPE_KINDS)}")
    mass = reader.number(data["mass"], "mass") if "mass" in data else None
    static = reader.boolean(data["static"], "static") if "static" in data else mass is None
    if not static and (mass is None or mass <= 0):
        raise reader.fail("mass", f"a dynamic model needs a positive mass (kg), got {mass}")
    if not static and any(shape.kind == "heightmap" for shape in shapes):
        raise reader.fail("static" if "static" in data else "mass",
                          "a heightmap is terrain and must be static; remove the mass or 'static: false'")
    mu = reader.number(data.get("mu", 1.0), "mu", non_negative=True)
    color = reader.numbers(data.get("color", [0.6, 0.6, 0.6, 1.0]), "color", (3, 4))
    if any(not 0.0 <= c <= 1.0 for c in color):
        raise reader.fail("color", expected("components between 0 and 1", color))
    model = Model(
        name=name,
        shapes=shapes,
        pose=reader.pose(data["pose"], "pose") if "pose" in data else Pose(),
        mass=mass,
        static=static,
        mu=mu,
        mu2=reader.number(data.get("mu2", mu), "mu2", non_negative=True),
        restitution=reader.number(data.get("restitution", 0.0), "restitution", non_negative=True),
        color=(color[0], color[1], color[2], color[3] if len(color) == 4 else 1.0),
        keep=reader.boolean(data["keep"], "keep") if "keep" in data else False,
        tags=_parse_tags(reader, data.get("tags", {})),
    )
    return model


def _parse_shape(reader: _Reader, raw: Any, field: str) -> Shape:
    if isinstance(raw, Mapping):
        unknown = [key for key in raw if key not in SHAPE_KEYS]
        if unknown:
            raise reader.fail(
                field, f"unknown shape type {unknown[0]!r}; expected one of: {', '.join(SHAPE_KINDS)}"
            )
    data = reader.mapping(raw, field, SHAPE_KEYS)
    kinds = [kind for kind in SHAPE_KINDS if kind in data]
    if len(kinds) != 1:
        raise reader.fail(
            field, f"a shape needs exactly one of {', '.join(SHAPE_KINDS)}, got {', '.join(kinds) or 'none'}"
        )
    kind = kinds[0]
    value = data[kind]
    where = f"{field}.{kind}" if field != kind else kind
    pose = reader.pose(data["pose"], f"{field}.pose") if "pose" in data else Pose()
    if kind == "box":
        size = reader.numbers(value, where, (3,), positive=True)
        return Shape("box", size=(size[0], size[1], size[2]), pose=pose)
    if kind == "cylinder":
        return _radius_and_length(reader, value, where, pose, "cylinder", "a cylinder needs radius and length (m)")
    if kind == "sphere":
        spec = reader.mapping(value, where, ("radius",))
        _required(reader, spec, where, ("radius",), "a sphere needs a radius (m)")
        return Shape("sphere", radius=reader.number(spec["radius"], f"{where}.radius", positive=True), pose=pose)
    if kind in _SHAPE_PARSERS:
        return _SHAPE_PARSERS[kind](reader, value, where, pose)
    spec = reader.mapping(value, where, ("file", "scale"))
    if "file" not in spec:
        raise reader.fail(f"{where}.file", "missing; a mesh needs a file (.stl, .obj, .dae)")
    mesh_file = reader.text(spec["file"], f"{where}.file")
    path = resolve_mesh_path(mesh_file, reader.source)
    problem = regular_file_problem(path, "mesh file")
    if problem is not None:
        raise reader.fail(f"{where}.file", problem)
    scale_value = spec.get("scale", 1.0)
    if isinstance(scale_value, (list, tuple)):
        scale = reader.numbers(scale_value, f"{where}.scale", (3,), positive=True)
    else:
        scale = [reader.number(scale_value, f"{where}.scale", positive=True)] * 3
    shape = Shape("mesh", mesh=mesh_file, scale=(scale[0], scale[1], scale[2]), pose=pose)
    check_mesh_file(path, shape.scale, lambda reason: reader.fail(f"{where}.file", reason))
    return shape


def _required(reader: _Reader, spec: Mapping[str, Any], where: str, keys: tuple[str, ...], what: str) -> None:
    for key in keys:
        if key not in spec:
            raise reader.fail(f"{where}.{key}", f"missing; {what}")


def _radius_and_length(reader: _Reader, value: Any, where: str, pose: Pose,
                       kind: Literal["cylinder", "capsule", "cone"], needs: str) -> Shape:
    """A cylinder, capsule or cone: `needs` says what is missing when radius or length is."""
    spec = reader.mapping(value, where, ("radius", "length"))
    _required(reader, spec, where, ("radius", "length"), needs)
    return Shape(
        kind,
        radius=reader.number(spec["radius"], f"{where}.radius", positive=True),
        length=reader.number(spec["length"], f"{where}.length", positive=True),
        pose=pose,
    )


def _parse_capsule(reader: _Reader, value: Any, where: str, pose: Pose) -> Shape:
    return _radius_and_length(reader, value, where, pose, "capsule",
                              "a capsule needs radius and length (m, the cylinder part between the half-spheres)")


def _parse_cone(reader: _Reader, value: Any, where: str, pose: Pose) -> Shape:
    return _radius_and_length(reader, value, where, pose, "cone",
                              "a cone needs radius (of its base) and length (m, base to tip)")


def _parse_polyline(reader: _Reader, value: Any, where: str, pose: Pose) -> Shape:
    spec = reader.mapping(value, where, ("points", "height"))
    _required(reader, spec, where, ("points", "height"),
              "a polyline needs points (the outline [[x, y], ...]) and height (m)")
    raw = spec["points"]
    if not isinstance(raw, list):
        raise reader.wrong(f"{where}.points", "a list of [x, y] points", raw)
    points = []
    for index, point in enumerate(raw):
        x, y = reader.numbers(point, f"{where}.points[{index}]", (2,))
        points.append((x, y))
    shape = Shape("polyline", points=tuple(points),
                  height=reader.number(spec["height"], f"{where}.height", positive=True), pose=pose)
    check_shape(shape, source=reader.source, model=reader.model, field=where)
    return shape


def _parse_heightmap(reader: _Reader, value: Any, where: str, pose: Pose) -> Shape:
    spec = reader.mapping(value, where, ("file", "size"))
    _required(reader, spec, where, ("file", "size"),
              "a heightmap needs file (a grayscale image) and size [x, y, z] (m)")
    image = reader.text(spec["file"], f"{where}.file")
    size = reader.numbers(spec["size"], f"{where}.size", (3,), positive=True)
    shape = Shape("heightmap", mesh=image, size=(size[0], size[1], size[2]), pose=pose)
    check_shape(shape, source=reader.source, model=reader.model, field=where)
    return shape


_SHAPE_PARSERS: dict[str, Callable[[_Reader, Any, str, Pose], Shape]] = {
    "capsule": _parse_capsule, "polyline": _parse_polyline, "heightmap": _parse_heightmap, "cone": _parse_cone,
}


def _parse_tags(reader: _Reader, value: Any) -> dict[str, TagValue]:
    if not isinstance(value, Mapping):
        raise reader.wrong("tags", "a mapping of tag names to values", value)
    tags: dict[str, TagValue] = {}
    for key, tag in value.items():
        if not isinstance(key, str) or not isinstance(tag, (str, int, float, bool)):
            raise reader.wrong(f"tags.{shown(key)}", "a string key and a scalar value", tag)
        reader.name(key, f"tags.{shown(key)}")
        problem = text_problem(tag, allowed="\t\n") if isinstance(tag, str) else None
        if problem is not None:
            raise reader.fail(f"tags.{key}", f"{problem}, got {shown(tag)}")
        tags[key] = tag
    return tags


def _parse_scenario(reader: _Reader, value: Any, models: Mapping[str, int]) -> Scenario:
    reader.error_type = ScenarioError
    try:
        data = reader.mapping(value, "scenario", SCENARIO_KEYS)
        robot = parse_robot(reader, data.get("robot", "husky"))
        if "start" not in data:
            raise reader.fail("scenario.start", "missing; give the robot's start as {x: .., y: .., yaw: ..}")
        start = reader.mapping(data["start"], "scenario.start", ("x", "y", "z", "yaw"))
        for key in ("x", "y"):
            if key not in start:
                raise reader.fail(f"scenario.start.{key}", "missing")
        if "goal" not in data:
            raise reader.fail("scenario.goal", "missing; give the goal as {x: .., y: ..}")
        goal = reader.mapping(data["goal"], "scenario.goal", ("x", "y", "z"))
        for key in ("x", "y"):
            if key not in goal:
                raise reader.fail(f"scenario.goal.{key}", "missing")
        if "timeout" not in data:
            raise reader.fail("scenario.timeout", "missing; give the time limit in simulated seconds")
        return Scenario(
            robot=robot,
            start=Pose(
                x=reader.number(start["x"], "scenario.start.x"),
                y=reader.number(start["y"], "scenario.start.y"),
                z=reader.number(start["z"], "scenario.start.z") if "z" in start else 0.0,
                yaw=reader.number(start.get("yaw", 0.0), "scenario.start.yaw"),
            ),
            start_z_given="z" in start,
            goal=(
                reader.number(goal["x"], "scenario.goal.x"),
                reader.number(goal["y"], "scenario.goal.y"),
                reader.number(goal["z"], "scenario.goal.z") if "z" in goal else None,
            ),
            goal_tolerance=reader.number(data.get("goal_tolerance", 0.3), "scenario.goal_tolerance", positive=True),
            timeout=reader.number(data["timeout"], "scenario.timeout", positive=True),
            target=_model_name(reader, data.get("target"), "scenario.target", models),
            table=_model_name(reader, data.get("table"), "scenario.table", models),
            watch=_watched(reader, data.get("watch"), models),
            camera=_camera(reader, data["camera"]) if data.get("camera") is not None else None,
        )
    finally:
        reader.error_type = WorldError


def _model_name(reader: _Reader, value: Any, field: str, models: Mapping[str, int]) -> str | None:
    """A scenario field naming one of the world's models (None: not given)."""
    if value is None:
        return None
    name = reader.text(value, field)
    if name not in models:
        raise reader.fail(field, f"{shown(name)} is not a model of this world")
    return name


def _watched(reader: _Reader, value: Any, models: Mapping[str, int]) -> tuple[str, ...]:
    if value is None:
        return ()
    if not isinstance(value, list):
        raise reader.wrong("scenario.watch", "a list of model names", value)
    names = tuple(_model_name(reader, item, f"scenario.watch[{i}]", models) or "" for i, item in enumerate(value))
    return tuple(dict.fromkeys(names))


def _camera(reader: _Reader, value: Any) -> Camera:
    data = reader.mapping(value, "scenario.camera", CAMERA_KEYS)
    for key in ("position", "look_at"):
        if key not in data:
            raise reader.fail(f"scenario.camera.{key}", "missing; a camera needs a position and a point to look at")
    position, look_at = (reader.numbers(data[key], f"scenario.camera.{key}", (3,)) for key in ("position", "look_at"))
    camera = Camera(position=(position[0], position[1], position[2]), look_at=(look_at[0], look_at[1], look_at[2]),
                    width=data.get("width", 64), height=data.get("height", 64), kind=data.get("kind", "rgb"),
                    fov=reader.number(data.get("fov", 60.0), "scenario.camera.fov"))
    problem = camera.problem()
    if problem is not None:
        raise reader.fail(f"scenario.camera.{problem[0]}", problem[1])
    return camera


def camera_dict(camera: Camera) -> dict[str, Any]:
    """`scenario.camera` as written."""
    return {"position": list(camera.position), "look_at": list(camera.look_at), "width": camera.width,
            "height": camera.height, "kind": camera.kind, "fov": camera.fov}


def _parse_physics(reader: _Reader, value: Any) -> Physics:
    if value is None:
        return Physics()
    data = reader.mapping(value, "physics", PHYSICS_KEYS)
    default = Physics()
    gravity = reader.numbers(data.get("gravity", list(default.gravity)), "physics.gravity", (3,), limit=MAX_GRAVITY)
    iterations = data.get("solver_iterations", default.solver_iterations)
    problem = solver_iterations_problem(iterations)
    if problem is not None:
        raise reader.fail("physics.solver_iterations", problem + _number_hint(iterations))
    timestep = reader.number(data.get("timestep", default.timestep), "physics.timestep", positive=True)
    problem = timestep_problem(timestep)
    if problem is not None:
        raise reader.fail("physics.timestep", problem)
    engine = data.get("engine", default.engine)
    problem = engine_problem(engine) if "engine" in data else None
    if problem is not None:
        raise reader.fail("physics.engine", problem)
    return Physics(gravity=(gravity[0], gravity[1], gravity[2]), timestep=timestep, solver_iterations=int(iterations),
                   engine=engine)


def _parse_ground(reader: _Reader, value: Any) -> Ground | None:
    if value is None or value is False:
        return None
    data = reader.mapping(value, "ground", GROUND_KEYS)
    mu = reader.number(data.get("mu", 1.0), "ground.mu", non_negative=True)
    return Ground(
        z=reader.number(data.get("z", 0.0), "ground.z"),
        mu=mu,
        mu2=reader.number(data.get("mu2", mu), "ground.mu2", non_negative=True),
        restitution=reader.number(data.get("restitution", 0.0), "ground.restitution", non_negative=True),
    )


# -- writing ---------------------------------------------------------------------------------------------


def dump_yaml(world: World, relative_to: Path | None = None) -> str:
    """The world as YAML text. `relative_to`: the folder the text will be written to; relative mesh and
    URDF paths are rebased onto it (they are relative to `world.source`'s folder)."""
    document: dict[str, Any] = {"format": FORMAT_VERSION}
    if world.name:
        document["name"] = world.name
    if world.physics != Physics(engine=WRITTEN_DEFAULT_ENGINE):
        document["physics"] = {
            "gravity": list(world.physics.gravity),
            "timestep": world.physics.timestep,
            "solver_iterations": world.physics.solver_iterations,
        }
        if world.physics.engine != WRITTEN_DEFAULT_ENGINE:
            document["physics"]["engine"] = world.physics.engine
    document["ground"] = None if world.ground is None else _ground_dict(world.ground)
    if world.scenario is not None:
        document["scenario"] = _scenario_dict(world.scenario, world.source, relative_to, world.names)
    document["models"] = [_model_dict(model, world.source, relative_to) for model in world.models]
    return yaml.dump(document, Dumper=Dumper, sort_keys=False, default_flow_style=None, width=120)


def _ground_dict(ground: Ground) -> dict[str, float]:
    return {"z": ground.z, "mu": ground.mu, "mu2": ground.mu2, "restitution": ground.restitution}


def _scenario_dict(scenario: Scenario, source: str | None, relative_to: Path | None,
                   names: tuple[str, ...]) -> dict[str, Any]:
    """`scenario` as written; of its `watch` models, those still in the world (`names`: a reduced world's)."""
    watch = [name for name in scenario.watch if name in names]
    start: dict[str, float] = {"x": scenario.start.x, "y": scenario.start.y}
    if scenario.start_z_given:
        start["z"] = scenario.start.z
    start["yaw"] = scenario.start.yaw
    goal: dict[str, float] = {"x": scenario.goal[0], "y": scenario.goal[1]}
    if scenario.goal[2] is not None:
        goal["z"] = scenario.goal[2]
    return {
        "robot": robot_dict(scenario.robot, source, relative_to),
        "start": start,
        "goal": goal,
        "goal_tolerance": scenario.goal_tolerance,
        "timeout": scenario.timeout,
        **({"target": scenario.target} if scenario.target is not None else {}),
        **({"table": scenario.table} if scenario.table is not None else {}),
        **({"watch": watch} if watch else {}),
        **({"camera": camera_dict(scenario.camera)} if scenario.camera is not None else {}),
    }


def _shape_dict(shape: Shape, source: str | None, relative_to: Path | None) -> dict[str, Any]:
    if shape.kind == "box":
        assert shape.size is not None
        spec: Any = list(shape.size)
    elif shape.kind == "cylinder":
        spec = {"radius": shape.radius, "length": shape.length}
    elif shape.kind == "sphere":
        spec = {"radius": shape.radius}
    elif shape.kind in ("capsule", "cone"):
        spec = {"radius": shape.radius, "length": shape.length}
    elif shape.kind == "polyline":
        assert shape.points is not None
        spec = {"points": [[x, y] for x, y in shape.points], "height": shape.height}
    elif shape.kind == "heightmap":
        assert shape.mesh is not None and shape.size is not None
        spec = {"file": rebased(shape.mesh, source, relative_to), "size": list(shape.size)}
    else:
        assert shape.mesh is not None
        spec = {"file": rebased(shape.mesh, source, relative_to), "scale": list(shape.scale)}
    result: dict[str, Any] = {shape.kind: spec}
    if shape.pose != Pose():
        result["pose"] = shape.pose.as_list()
    return result


def _model_dict(model: Model, source: str | None, relative_to: Path | None) -> dict[str, Any]:
    result: dict[str, Any] = {"name": model.name}
    if model.pose != Pose():
        result["pose"] = model.pose.as_list()
    if len(model.shapes) == 1 and model.shapes[0].pose == Pose():
        result.update(_shape_dict(model.shapes[0], source, relative_to))
    else:
        result["shapes"] = [_shape_dict(shape, source, relative_to) for shape in model.shapes]
    mass = 1.0 if model.mass is None and not model.static else model.mass  # what a dynamic model simulates with
    if mass is not None:
        result["mass"] = mass
    if model.static != (mass is None):
        result["static"] = model.static
    if model.mu != 1.0 or model.mu2 != model.mu:
        result["mu"] = model.mu
    if model.mu2 != model.mu:
        result["mu2"] = model.mu2
    if model.restitution:
        result["restitution"] = model.restitution
    if model.color != (0.6, 0.6, 0.6, 1.0):
        result["color"] = list(model.color)
    if model.keep:
        result["keep"] = True
    if model.tags:
        result["tags"] = dict(model.tags)
    return result
