"""The world model: immutable `World`s made of `Model`s, sub-worlds, bounds and distances.

No file format (the format layer, `formats`, reads and writes worlds), no pybullet, no pytest. A `World` also
satisfies the reduction engine's `Geometry` protocol (`centroids(names)` and `distances(points, names)`).
"""

from __future__ import annotations

import dataclasses
import functools
import os
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, Protocol

import numpy as np

from pytest_ddenv.errors import WorldError
from pytest_ddenv.validation import expected
from pytest_ddenv.world import geometry
from pytest_ddenv.world.files import resolve_mesh_path
from pytest_ddenv.world.geometry import FloatArray
from pytest_ddenv.world.limits import ENGINE_PACKAGES, default_engine
from pytest_ddenv.world.meshes import heightmap_mesh, load_heightmap, load_mesh, polyline_mesh, polyline_polygon

ShapeKind = Literal["box", "cylinder", "sphere", "mesh", "capsule", "polyline", "heightmap", "cone"]
ENGINES = tuple(ENGINE_PACKAGES)
"""The physics engines a world can name in `physics.engine`."""
SHAPE_KINDS: tuple[ShapeKind, ...] = ("box", "cylinder", "sphere", "mesh", "capsule", "polyline", "heightmap", "cone")
TagValue = str | int | float | bool


@dataclass(frozen=True)
class Pose:
    """A rigid pose: position in metres, fixed-axis roll/pitch/yaw in radians."""

    x: float = 0.0
    y: float = 0.0
    z: float = 0.0
    roll: float = 0.0
    pitch: float = 0.0
    yaw: float = 0.0

    @property
    def position(self) -> FloatArray:
        return np.array([self.x, self.y, self.z])

    @property
    def rotation(self) -> FloatArray:
        return geometry.rotation_matrix(self.roll, self.pitch, self.yaw)

    def as_list(self) -> list[float]:
        return [self.x, self.y, self.z, self.roll, self.pitch, self.yaw]

    def compose(self, child: Pose) -> Pose:
        """The pose of `child` (given in this pose's frame) in this pose's parent frame."""
        if child == Pose():
            return self
        rotation = self.rotation
        position = self.position + rotation @ child.position
        roll, pitch, yaw = geometry.rpy_from_matrix(rotation @ child.rotation)
        return Pose(float(position[0]), float(position[1]), float(position[2]), roll, pitch, yaw)


@dataclass(frozen=True)
class Shape:
    """One collision shape of a model, placed at `pose` in the model's frame.

    box: `size` (x, y, z full lengths). cylinder: `radius` and `length` (axis along local z).
    sphere: `radius`. capsule: `radius` and `length` (of the cylinder between the two half-spheres, axis along
    local z, as in SDF). mesh: `mesh` (a file path, absolute or relative to the world file) and `scale`.
    polyline: `points` (the outline in the local xy plane, closed implicitly) extruded along z from 0 to
    `height`, as Gazebo extrudes an SDF `<polyline>`. heightmap: `mesh` (a grayscale image, absolute or
    relative to the world file; black = 0, white = the full height) stretched over `size` (x, y extent and the
    z range), centred on the shape's pose in x and y, from z = 0 up. cone: `radius` (of its base) and `length`
    (axis along local z, the base at -length/2 and the tip at +length/2, as SDF's `<cone>`).
    """

    kind: ShapeKind
    size: tuple[float, float, float] | None = None
    radius: float | None = None
    length: float | None = None
    mesh: str | None = None
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    pose: Pose = Pose()
    points: tuple[tuple[float, float], ...] | None = None
    height: float | None = None


@dataclass(frozen=True)
class Model:
    """A reducible object of the world: a named rigid body made of one or more shapes."""

    name: str
    shapes: tuple[Shape, ...]
    pose: Pose = Pose()
    mass: float | None = None
    static: bool = True
    mu: float = 1.0
    mu2: float = 1.0
    restitution: float = 0.0
    color: tuple[float, float, float, float] = (0.6, 0.6, 0.6, 1.0)
    keep: bool = False
    tags: Mapping[str, TagValue] = field(default_factory=dict, hash=False)

    @property
    def dynamic(self) -> bool:
        return not self.static


DRIVE_KINDS = ("differential", "skid-steer")


@dataclass(frozen=True)
class LaserMount:
    """Where a robot's 2D laser sits: `height` (m) above the robot's base frame, at `x` (forward) and `y`
    (left) from the base's origin (m), turned by `yaw` (rad, counterclockwise); rays start `min_range` (m)
    from the laser, outside the robot's own body."""

    height: float
    min_range: float
    x: float = 0.0
    y: float = 0.0
    yaw: float = 0.0


@dataclass(frozen=True)
class RobotDescription:
    """A wheeled robot given as data: the mapping form of a world file's `scenario.robot`.

    `urdf` is a path, absolute or relative to the world file. The wheels are continuous joints named in
    `left_wheels` and `right_wheels`; `drive` is "differential" or "skid-steer". `wheel_radius` and `track`
    (the distance between the left and right wheels) are read from the URDF when None. `track_factor`
    scales the track in the kinematics (None: 1 for differential, 1.5 for skid-steer, whose wheels slip
    sideways when turning). `laser`: True (a laser on top of the robot, mounted automatically), False (no
    laser) or a `LaserMount`. `name` defaults to the URDF's file name without extension.
    """

    urdf: str
    left_wheels: tuple[str, ...]
    right_wheels: tuple[str, ...]
    drive: str = "differential"
    wheel_radius: float | None = None
    track: float | None = None
    track_factor: float | None = None
    max_wheel_torque: float = 20.0
    laser: bool | LaserMount = True
    name: str = ""

    @property
    def label(self) -> str:
        """The robot's name in runs and reports."""
        return self.name or Path(self.urdf).stem


@dataclass(frozen=True)
class ArmDescription:
    """A fixed-base arm with a parallel gripper given as data: the `arm:` mapping form of a world file's
    `scenario.robot` (docs/world-format.md, "An arm on a table").

    `urdf` is a path, absolute or relative to the world file (`mjcf`, optional, the same arm as an MJCF for
    the MuJoCo engine). `arm_joints` name the position-controlled joints from the base outwards,
    `finger_joints` the gripper's prismatic joints (one command moves them together), `end_effector` the
    link whose pose is the tool's (between the fingertips). `home`: the arm joints' positions at the start
    (None: zero, clipped to the limits). `name` defaults to the URDF's file name without extension.
    """

    urdf: str
    arm_joints: tuple[str, ...]
    finger_joints: tuple[str, ...]
    end_effector: str
    home: tuple[float, ...] | None = None
    mjcf: str | None = None
    name: str = ""

    @property
    def label(self) -> str:
        """The robot's name in runs and reports."""
        return self.name or Path(self.urdf).stem


CAMERA_KINDS = ("rgb", "depth")
MAX_CAMERA_PIXELS = 1024
"""The widest and tallest camera picture (pixels): it is drawn every control tick."""


@dataclass(frozen=True)
class Camera:
    """A camera an arm's controller sees through (`ArmObservation.image`, docs/writing-tests.md "Arms"): at
    `position`, looking at `look_at` (world frame, m), `width` x `height` pixels, `kind` "rgb" ((H, W, 3)
    uint8) or "depth" ((H, W) float32, m along the view axis), vertical field of view `fov` degrees."""

    position: tuple[float, float, float]
    look_at: tuple[float, float, float]
    width: int = 64
    height: int = 64
    kind: str = "rgb"
    fov: float = 60.0

    def problem(self) -> tuple[str, str] | None:
        """(field, what is wrong) of a camera that cannot be rendered, or None."""
        if tuple(self.position) == tuple(self.look_at):
            return "look_at", "the camera cannot look at its own position"
        for key in ("width", "height"):
            number = getattr(self, key)
            if not (isinstance(number, int) and not isinstance(number, bool) and 1 <= number <= MAX_CAMERA_PIXELS):
                return key, f"expected a whole number of pixels from 1 to {MAX_CAMERA_PIXELS}, got {number!r}"
        if self.kind not in CAMERA_KINDS:
            return "kind", f"expected one of {', '.join(CAMERA_KINDS)}, got {self.kind!r}"
        if not 0 < self.fov < 180:
            return "fov", f"expected a vertical field of view between 0 and 180 degrees, got {self.fov!r}"
        return None


@dataclass(frozen=True)
class Scenario:
    """What the robot does in the world: start pose, goal, time limit (simulated seconds).

    `robot` is the name of a registered robot ("husky" by default; "panda" is the built-in arm), a
    `RobotDescription` (a wheeled robot) or an `ArmDescription` (an arm).

    For an arm (docs/writing-tests.md, "Arms"): `start` is the pose of the arm's base (z given: on or beside
    the table), `target` the model to pick, `goal` the centre of the place region and `goal_tolerance` its
    radius (m, planar), `table` the model the objects stand on, `watch` further models whose poses the
    controller observes and the predicates see. The reduction never removes the table or the target.
    `camera`: a `Camera` whose picture the arm's controller sees each tick (None: none).
    """

    robot: str | RobotDescription | ArmDescription = "husky"
    start: Pose = Pose()
    start_z_given: bool = False
    goal: tuple[float, float, float | None] = (0.0, 0.0, None)
    goal_tolerance: float = 0.3
    timeout: float = 60.0
    target: str | None = None
    table: str | None = None
    watch: tuple[str, ...] = ()
    camera: Camera | None = None


@dataclass(frozen=True)
class Physics:
    """Simulation settings that are part of a run's reproducibility key."""

    gravity: tuple[float, float, float] = (0.0, 0.0, -9.81)
    timestep: float = 1.0 / 240.0
    solver_iterations: int = 50
    engine: str = field(default_factory=default_engine)
    """The physics engine that simulates the world: one of `ENGINES` (docs/simulation.md, "The engine seam");
    unnamed, pybullet where it is installed, otherwise mujoco (`limits.default_engine`)."""


@dataclass(frozen=True)
class Ground:
    """The infinite ground plane: a world setting, never a reducible model."""

    z: float = 0.0
    mu: float = 1.0
    mu2: float = 1.0
    restitution: float = 0.0


@dataclass(frozen=True)
class World:
    """An ordered, immutable collection of models plus scenario, physics and ground settings.

    The model order is the canonical creation order of the simulation; sub-worlds keep it.
    """

    models: tuple[Model, ...] = ()
    scenario: Scenario | None = None
    physics: Physics = Physics()
    ground: Ground | None = Ground()
    name: str = ""
    source: str | None = field(default=None, compare=False)
    notes: tuple[str, ...] = field(default=(), compare=False)
    """What the world file holds that is not simulated, and why (joints, plugins, lights, dropped models)."""

    def __post_init__(self) -> None:
        if isinstance(self.models, list):
            object.__setattr__(self, "models", tuple(self.models))
        if not isinstance(self.models, tuple):
            raise WorldError(expected("a tuple of Models", self.models, "World(models=...)"), source=self.source)
        seen: set[str] = set()
        for index, model in enumerate(self.models):
            if not isinstance(model, Model):
                raise WorldError(expected("a Model", model, "World(models=...)"), source=self.source,
                                 model=f"#{index}")
            if model.name in seen:
                raise WorldError(
                    f"duplicate model name '{model.name}'; names must be unique",
                    source=self.source,
                    model=f"#{index}",
                    field="name",
                )
            seen.add(model.name)

    # -- files: read and written by the format layer (`world.formats`) -------------------------------
    @classmethod
    def load(cls, path: str | os.PathLike[str], *, model_paths: Sequence[str | os.PathLike[str]] = (),
             skip_unsupported: bool = False) -> World:
        """Read a world file: YAML (`.yaml`, `.yml`) or Gazebo SDF (`.world`, `.sdf`) by extension.

        `model_paths` are extra folders searched for SDF `<include>`s of `model://NAME`; `skip_unsupported`
        drops SDF models that cannot be simulated (each named in `World.notes`) instead of refusing the file.
        """
        if not isinstance(path, (str, os.PathLike)):
            raise WorldError(expected("a world file's path (a str or os.PathLike)", path, "World.load(path=...)"))
        return _world_files().load(Path(path), None, model_paths, skip_unsupported)

    @classmethod
    def from_sdf(cls, path: str | os.PathLike[str], *, model_paths: Sequence[str | os.PathLike[str]] = (),
                 skip_unsupported: bool = False) -> World:
        """Import a Gazebo SDF world or model file as Gazebo simulates it (see docs/sdf.md); its values must be
        within what the simulator takes (`values`)."""
        return _world_files().load(Path(path), "sdf", model_paths, skip_unsupported)

    def to_sdf(self) -> str:
        """An SDF 1.6 world that Gazebo loads, SDF 1.8 if it has a capsule (see docs/sdf.md)."""
        return _world_files().dump(self, "sdf", None)

    @classmethod
    def from_yaml(cls, text: str, *, source: str | os.PathLike[str] | None = None) -> World:
        """Parse YAML text; `source` names it in errors and anchors relative mesh paths."""
        return _world_files().parse(text, "yaml", source)

    def to_yaml(self, *, relative_to: str | os.PathLike[str] | None = None) -> str:
        """The world as YAML text. Give `relative_to` (the folder the text goes to) to keep relative mesh
        and URDF paths working from there; `save` does this."""
        return _world_files().dump(self, "yaml", None if relative_to is None else Path(relative_to))

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the world, as YAML (`.yaml`, `.yml`) or SDF (`.sdf`, `.world`) by extension, atomically (write
        then rename). A value the simulator cannot take (`values`), another extension or a place that
        cannot be written is a WorldError naming the file; nothing is left behind."""
        if not isinstance(path, (str, os.PathLike)):
            raise WorldError(expected("a file path (a str or os.PathLike)", path, "World.save(path=...)"))
        _world_files().save(self, Path(path))

    # -- models --------------------------------------------------------------------------------------
    @property
    def names(self) -> tuple[str, ...]:
        return tuple(model.name for model in self.models)

    @property
    def reducible_names(self) -> tuple[str, ...]:
        """Names of the models a reduction may remove (all but `keep: true`)."""
        return tuple(model.name for model in self.models if not model.keep)

    def __len__(self) -> int:
        return len(self.models)

    REPR_MODELS = 4
    """How many model names `repr()` shows."""

    def __repr__(self) -> str:
        """One short line: the name, the number of models and the first names (a world may hold hundreds of
        models; `World.save` writes all of it)."""
        count = len(self.models)
        names = ", ".join(self.names[:self.REPR_MODELS]) + (", ..." if count > self.REPR_MODELS else "")
        models = f"{count} model{'s' if count != 1 else ''}: {names}" if count else "no models"
        return f"World({f'{self.name!r}, ' if self.name else ''}{models})"

    def _repr_pretty_(self, printer: Any, cycle: bool) -> None:
        """The same short line in Hypothesis' and IPython's pretty printers (they print a dataclass field by
        field otherwise)."""
        printer.text(repr(self))

    def __iter__(self) -> Iterator[Model]:
        return iter(self.models)

    def __contains__(self, name: object) -> bool:
        return name in self._index

    def model(self, name: str) -> Model:
        try:
            return self.models[self._index[name]]
        except KeyError:
            raise WorldError(f"no model named '{name}' in this world", source=self.source) from None

    def select(self, names: Iterable[str]) -> World:
        """The sub-world with only the named models, in this world's order. Unknown names are an error."""
        wanted = self._checked(names)
        return dataclasses.replace(self, models=tuple(m for m in self.models if m.name in wanted))

    def with_engine(self, engine: str) -> World:
        """This world simulated by `engine` (one of `ENGINES`): `physics.engine` replaced."""
        return dataclasses.replace(self, physics=dataclasses.replace(self.physics, engine=engine))

    def without(self, names: Iterable[str]) -> World:
        """The sub-world without the named models, in this world's order. Unknown names are an error."""
        unwanted = self._checked(names)
        return dataclasses.replace(self, models=tuple(m for m in self.models if m.name not in unwanted))

    def _checked(self, names: Iterable[str]) -> frozenset[str]:
        if isinstance(names, str):
            raise TypeError("pass a collection of model names, not a single string")
        if not isinstance(names, Iterable):
            raise TypeError(expected("a collection of model names", names))
        chosen = frozenset(names)
        unknown = sorted(map(repr, chosen - self._index.keys()))
        if unknown:
            raise WorldError(
                f"unknown model name(s) {', '.join(unknown)}; "
                f"the world has: {', '.join(self.names) or '(no models)'}",
                source=self.source,
            )
        return chosen

    @functools.cached_property
    def _index(self) -> dict[str, int]:
        return {model.name: index for index, model in enumerate(self.models)}

    # -- geometry ------------------------------------------------------------------------------------
    def bounds(self, name: str) -> FloatArray:
        """Axis-aligned bounds of a model in the world frame: a (2, 3) array [min, max]."""
        return _model_geometry(self.model(name), self.source).bounds

    def centroid(self, name: str) -> FloatArray:
        """Centre of the model's axis-aligned bounds in the world frame."""
        low, high = self.bounds(name)
        centre: FloatArray = (low + high) / 2.0
        return centre

    def centroids(self, names: Sequence[str] | None = None) -> FloatArray:
        """Centroids (E, 3) of the named models (all models by default)."""
        chosen = self.names if names is None else tuple(names)
        if not chosen:
            return np.zeros((0, 3))
        return np.stack([self.centroid(name) for name in chosen])

    def distances(self, points: FloatArray, names: Sequence[str] | None = None) -> FloatArray:
        """Distance (N, E) from each point to the surface of each named model; 0 inside a model.

        Uses every shape's real extent (a 20 m slab is 0 m away from a robot driving on it).
        """
        if isinstance(names, str):
            raise TypeError("pass a collection of model names, not a single string")
        chosen = self.names if names is None else tuple(names)
        points = _points(points)
        result = np.empty((len(points), len(chosen)))
        for column, name in enumerate(chosen):
            result[:, column] = _model_geometry(self.model(name), self.source).distance(points)
        return result


def _points(points: object) -> FloatArray:
    """`points` as an (N, 3) array of finite numbers (WorldError naming the first bad point otherwise)."""
    try:
        array = np.asarray(points, dtype=float)
    except (TypeError, ValueError, OverflowError):
        array = np.empty((0, 0))
    if array.ndim not in (1, 2) or array.shape[-1] != 3:
        raise WorldError(expected("points x, y, z (an array of shape (3,) or (N, 3))", points,
                                  "World.distances(points=...)"))
    array = array.reshape(-1, 3)
    bad = np.flatnonzero(~np.all(np.isfinite(array), axis=1))
    if len(bad):
        raise WorldError(f"World.distances(points=...): point #{bad[0]} is not finite: {array[bad[0]].tolist()}")
    return array


@dataclass(frozen=True)
class _PlacedShape:
    shape: Shape
    translation: FloatArray
    rotation: FloatArray
    mesh_path: Path | None
    """The mesh file of a mesh, the image of a heightmap."""


class _ModelGeometry:
    """World-frame placement of a model's shapes with cached distance queries."""

    def __init__(self, model: Model, source: str | None) -> None:
        self.model = model
        self.placed: list[_PlacedShape] = []
        for shape in model.shapes:
            pose = model.pose.compose(shape.pose)
            mesh_path = resolve_mesh_path(shape.mesh, source) if shape.kind in ("mesh", "heightmap") else None
            self.placed.append(_PlacedShape(shape, pose.position, pose.rotation, mesh_path))
        self.bounds = self._bounds()

    def _bounds(self) -> FloatArray:
        lows, highs = [], []
        for placed in self.placed:
            shape = placed.shape
            if shape.kind == "box":
                assert shape.size is not None
                corners = geometry.box_corners(np.array(shape.size))
                world_points = placed.translation + corners @ placed.rotation.T
                lows.append(world_points.min(axis=0))
                highs.append(world_points.max(axis=0))
            elif shape.kind == "cylinder":
                assert shape.radius is not None and shape.length is not None
                axis = placed.rotation[:, 2]
                half = np.abs(axis) * shape.length / 2.0 + shape.radius * np.sqrt(np.clip(1.0 - axis**2, 0, 1))
                lows.append(placed.translation - half)
                highs.append(placed.translation + half)
            elif shape.kind == "sphere":
                assert shape.radius is not None
                lows.append(placed.translation - shape.radius)
                highs.append(placed.translation + shape.radius)
            elif shape.kind in ("capsule", "cone"):
                assert shape.radius is not None and shape.length is not None
                bounds = geometry.capsule_bounds if shape.kind == "capsule" else geometry.cone_bounds
                low, high = bounds(placed.translation, placed.rotation, shape.radius, shape.length)
                lows.append(low)
                highs.append(high)
            else:  # mesh, polyline, heightmap: their vertices
                vertices = _mesh_vertices_world(placed)
                lows.append(vertices.min(axis=0))
                highs.append(vertices.max(axis=0))
        return np.stack([np.min(lows, axis=0), np.max(highs, axis=0)])

    def distance(self, points: FloatArray) -> FloatArray:
        best = np.full(len(points), np.inf)
        for placed in self.placed:
            shape = placed.shape
            local = geometry.to_local(points, placed.translation, placed.rotation)
            if shape.kind == "box":
                assert shape.size is not None
                d = geometry.box_distance(local, np.array(shape.size))
            elif shape.kind == "cylinder":
                assert shape.radius is not None and shape.length is not None
                d = geometry.cylinder_distance(local, shape.radius, shape.length)
            elif shape.kind == "sphere":
                assert shape.radius is not None
                d = geometry.sphere_distance(local, shape.radius)
            elif shape.kind == "capsule":
                assert shape.radius is not None and shape.length is not None
                d = geometry.capsule_distance(local, shape.radius, shape.length)
            elif shape.kind == "cone":
                assert shape.radius is not None and shape.length is not None
                d = geometry.cone_distance(local, shape.radius, shape.length)
            elif shape.kind == "polyline":
                d = _polyline_distance(shape, local)
            elif shape.kind == "heightmap":
                d = _heightmap_distance(placed, local)
            else:
                d = _mesh_distance(placed, local)
            best = np.minimum(best, d)
        return best


@functools.lru_cache(maxsize=4096)
def _model_geometry(model: Model, source: str | None) -> _ModelGeometry:
    return _ModelGeometry(model, source)


def _mesh_vertices_world(placed: _PlacedShape) -> FloatArray:
    vertices: FloatArray = np.asarray(_shape_mesh(placed).vertices, dtype=np.float64)  # type: ignore[attr-defined]
    return placed.translation + vertices @ placed.rotation.T


def _shape_mesh(placed: _PlacedShape) -> object:
    """The trimesh of a mesh, polyline or heightmap shape (in the shape's frame), cached."""
    shape = placed.shape
    if shape.kind == "polyline":
        assert shape.points is not None and shape.height is not None
        return polyline_mesh(shape.points, shape.height)
    assert placed.mesh_path is not None
    if shape.kind == "heightmap":
        assert shape.size is not None
        return heightmap_mesh(placed.mesh_path, shape.size)
    return load_mesh(placed.mesh_path, shape.scale)


def _mesh_distance(placed: _PlacedShape, local: FloatArray) -> FloatArray:
    import trimesh

    assert placed.mesh_path is not None
    mesh = load_mesh(placed.mesh_path, placed.shape.scale)
    _, distance, _ = trimesh.proximity.closest_point(mesh, local)  # type: ignore[no-untyped-call]  # unannotated
    distance = np.asarray(distance, dtype=float)
    if getattr(mesh, "is_watertight", False):
        inside = mesh.contains(local)  # type: ignore[attr-defined]
        distance = np.where(inside, 0.0, distance)
    return distance


def _polyline_distance(shape: Shape, local: FloatArray) -> FloatArray:
    import shapely

    assert shape.points is not None and shape.height is not None
    polygon = polyline_polygon(shape.points)
    planar = np.asarray(shapely.distance(polygon, shapely.points(local[:, :2])), dtype=float)
    return geometry.prism_distance(planar, local[:, 2], shape.height)


def _heightmap_distance(placed: _PlacedShape, local: FloatArray) -> FloatArray:
    import trimesh

    shape = placed.shape
    assert placed.mesh_path is not None and shape.size is not None
    surface = geometry.heightmap_height(load_heightmap(placed.mesh_path), shape.size, local[:, :2])
    with np.errstate(invalid="ignore"):
        inside = (local[:, 2] >= 0.0) & (local[:, 2] <= surface)  # NaN (outside the rectangle) compares False
    distance = np.zeros(len(local))
    outside = ~inside
    if outside.any():
        mesh = heightmap_mesh(placed.mesh_path, shape.size)
        _, found, _ = trimesh.proximity.closest_point(mesh, local[outside])  # type: ignore[no-untyped-call]  # unannotated
        distance[outside] = np.asarray(found, dtype=float)
    return distance


# -- the format layer, installed by `pytest_ddenv.world.formats` ----------------------------------------------
class WorldFiles(Protocol):
    """How `World.load`, `World.save`, `World.from_*` and `World.to_*` read and write world files. The format
    layer (`pytest_ddenv.world.formats`) installs it with `use_world_files` when `pytest_ddenv.world` is
    imported: the model knows no file format and imports no format's module."""

    def load(self, path: Path, format_name: str | None, model_paths: Sequence[str | os.PathLike[str]],
             skip_unsupported: bool) -> World:
        """The world in the file at `path`, read in `format_name` (None: the format of its suffix)."""

    def parse(self, text: str, format_name: str, source: str | os.PathLike[str] | None) -> World:
        """The world in `text`, in `format_name`; `source` names it in errors and anchors relative paths."""

    def dump(self, world: World, format_name: str, relative_to: Path | None) -> str:
        """`world` as text in `format_name`, its relative file paths from the folder `relative_to`."""

    def save(self, world: World, path: Path) -> None:
        """Write `world` to `path` in the format of its suffix."""


_installed: list[WorldFiles] = []


def use_world_files(files: WorldFiles) -> None:
    """Make `files` the format layer of every `World`."""
    _installed[:] = [files]


def _world_files() -> WorldFiles:
    assert _installed, "pytest_ddenv.world.formats installs the world file formats when pytest_ddenv.world loads"
    return _installed[0]
