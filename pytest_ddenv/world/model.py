"""The world model: immutable `World`s made of `Model`s, sub-worlds, bounds and distances.

This layer knows YAML and geometry only (no pybullet, no pytest). A `World` also satisfies the reduction
engine's `Geometry` protocol (`centroids(names)` and `distances(points, names)`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import math
import os
import re
import sys
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from pytest_ddenv.errors import WorldError, shown, shown_path
from pytest_ddenv.validation import expected, is_finite_number, is_integer
from pytest_ddenv.world import geometry
from pytest_ddenv.world.files import MISSING, file_kind, read_regular, regular_file_problem
from pytest_ddenv.world.geometry import FloatArray

if TYPE_CHECKING:
    import PIL.Image
    import shapely

ShapeKind = Literal["box", "cylinder", "sphere", "mesh", "capsule", "polyline", "heightmap", "cone"]
SHAPE_KINDS: tuple[ShapeKind, ...] = ("box", "cylinder", "sphere", "mesh", "capsule", "polyline", "heightmap", "cone")
TagValue = str | int | float | bool
YAML_SUFFIXES = (".yaml", ".yml")
SDF_SUFFIXES = (".sdf", ".world")
MAX_NAME_LENGTH = 256
"""Longest model (or world, robot, joint) name."""
MAX_SOLVER_ITERATIONS = 10_000
TIMESTEP_RANGE = (1e-6, 1.0)
"""Smallest and largest simulation timestep (s)."""
MAX_MESH_BYTES = 256 * 1024 * 1024
"""Largest mesh file read."""
MAX_IMAGE_BYTES = 64 * 1024 * 1024
"""Largest heightmap image file read."""
HEIGHTMAP_SIDE = 1025 if sys.platform != "darwin" else 257
MAX_HEIGHTMAP_PIXELS = HEIGHTMAP_SIDE * HEIGHTMAP_SIDE
"""Most pixels of a heightmap image. pybullet passes a heightfield's heights through a buffer of 8 MiB of float32
(1 MiB on macOS): 2 097 152 heights (262 144); past it the heights it reads are garbage or the process crashes
(measured on Linux, pybullet 3.2.7: 1448 x 1448 and 2048 x 1024 pixels right, 1449 x 1449 and 2049 x 1024
wrong, 4096 x 4096 a segmentation fault). The limit is about half of that (a quarter on macOS)."""
_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f\ud800-\udfff\ufffe\uffff]")


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
class Scenario:
    """What the robot does in the world: start pose, goal, time limit (simulated seconds).

    `robot` is the name of a registered robot ("husky" by default) or a `RobotDescription`.
    """

    robot: str | RobotDescription = "husky"
    start: Pose = Pose()
    start_z_given: bool = False
    goal: tuple[float, float, float | None] = (0.0, 0.0, None)
    goal_tolerance: float = 0.3
    timeout: float = 60.0


@dataclass(frozen=True)
class Physics:
    """Simulation settings that are part of a run's reproducibility key."""

    gravity: tuple[float, float, float] = (0.0, 0.0, -9.81)
    timestep: float = 1.0 / 240.0
    solver_iterations: int = 50


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

    # -- files ---------------------------------------------------------------------------------------
    @classmethod
    def load(cls, path: str | os.PathLike[str], *, model_paths: Sequence[str | os.PathLike[str]] = (),
             skip_unsupported: bool = False) -> World:
        """Read a world file: YAML (`.yaml`, `.yml`) or Gazebo SDF (`.world`, `.sdf`) by extension.

        `model_paths` are extra folders searched for SDF `<include>`s of `model://NAME`; `skip_unsupported`
        drops SDF models that cannot be simulated (each named in `World.notes`) instead of refusing the file.
        """
        from pytest_ddenv.world import yaml_format as world_yaml

        if not isinstance(path, (str, os.PathLike)):
            raise WorldError(expected("a world file's path (a str or os.PathLike)", path, "World.load(path=...)"))
        path = Path(path)
        if path.suffix.lower() in SDF_SUFFIXES:
            return cls.from_sdf(path, model_paths=model_paths, skip_unsupported=skip_unsupported)
        return world_yaml.load_yaml(path)

    @classmethod
    def from_sdf(cls, path: str | os.PathLike[str], *, model_paths: Sequence[str | os.PathLike[str]] = (),
                 skip_unsupported: bool = False) -> World:
        """Import a Gazebo SDF world or model file as Gazebo simulates it (see docs/sdf.md); its values must be
        within what the simulator takes (`world_values`)."""
        from pytest_ddenv import sdf
        from pytest_ddenv.world.values import check_world_values

        world = sdf.load_sdf(Path(path), model_paths=[Path(folder) for folder in model_paths],
                             skip_unsupported=skip_unsupported)
        check_world_values(world)
        return world

    def to_sdf(self) -> str:
        """An SDF 1.6 world that Gazebo loads, SDF 1.8 if it has a capsule (see docs/sdf.md)."""
        from pytest_ddenv import sdf

        return sdf.dump_sdf(self)

    @classmethod
    def from_yaml(cls, text: str, *, source: str | os.PathLike[str] | None = None) -> World:
        """Parse YAML text; `source` names it in errors and anchors relative mesh paths."""
        from pytest_ddenv.world import yaml_format as world_yaml

        return world_yaml.parse_yaml(text, source=source)

    def to_yaml(self, *, relative_to: str | os.PathLike[str] | None = None) -> str:
        """The world as YAML text. Give `relative_to` (the folder the text goes to) to keep relative mesh
        and URDF paths working from there; `save` does this."""
        from pytest_ddenv.world import yaml_format as world_yaml

        return world_yaml.dump_yaml(self, None if relative_to is None else Path(relative_to))

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the world, as YAML (`.yaml`, `.yml`) or SDF (`.sdf`, `.world`) by extension, atomically (write
        then rename). A value the simulator cannot take (`world_values`), another extension or a place that
        cannot be written is a WorldError naming the file; nothing is left behind."""
        from pytest_ddenv.world.values import check_world_values

        if not isinstance(path, (str, os.PathLike)):
            raise WorldError(expected("a file path (a str or os.PathLike)", path, "World.save(path=...)"))
        path = Path(path)
        suffix = path.suffix.lower()
        if suffix not in (*YAML_SUFFIXES, *SDF_SUFFIXES):
            raise WorldError(f"unknown world file extension {suffix or '(none)'!r}; name it .yaml or .yml (ddenv "
                             "YAML), or .sdf or .world (Gazebo SDF)", source=path)
        check_world_values(self)
        kind = file_kind(path)
        if kind is not None and kind != MISSING:  # a folder, a device, a FIFO: never replaced by the file
            raise WorldError(f"is {kind}, not a world file; give the world file's name", source=path)
        text = self.to_sdf() if suffix in SDF_SUFFIXES else self.to_yaml(relative_to=path.parent)
        temporary = path.with_name(f".{path.name}.tmp{os.getpid()}")
        try:
            temporary.write_text(text, encoding="utf-8")
            os.replace(temporary, path)
        except OSError as error:
            with contextlib.suppress(OSError):
                temporary.unlink()
            problem = error.strerror or str(error)
            if isinstance(error, FileNotFoundError) and not path.parent.is_dir():
                problem = f"the folder {shown_path(path.parent)} does not exist"
            raise WorldError(f"cannot write the world file: {problem}", source=path) from None

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


def resolve_mesh_path(mesh: str | None, source: str | None) -> Path:
    """A mesh path as given, or relative to the directory of the world file that names it."""
    if mesh is None:
        raise WorldError("a mesh shape needs a 'mesh' file", source=source)
    return resolve_relative(mesh, source)


def is_file(path: Path) -> bool:
    """Whether `path` is a file; False, not OSError, for names the system refuses (too long, ...)."""
    try:
        return path.is_file()
    except (OSError, ValueError):
        return False


def exists(path: Path) -> bool:
    """Whether `path` exists; False, not OSError, for names the system refuses (too long, ...)."""
    try:
        return path.exists()
    except (OSError, ValueError):
        return False


def resolve_relative(file: str, source: str | None) -> Path:
    """A file named in a world file: as given if absolute, else relative to the world file's folder."""
    path = Path(file).expanduser()
    if not path.is_absolute() and source is not None:
        path = Path(source).parent / path
    return path


@functools.lru_cache(maxsize=256)
def load_mesh(path: Path, scale: tuple[float, float, float]) -> object:
    """A trimesh.Trimesh of the file's geometry with `scale` applied (loaded once per process).

    The file is read only if it is a regular file within MAX_MESH_BYTES (`world_files.read_regular`). Only the
    geometry is read: materials and textures are not loaded (a texture file that is missing or unreadable
    costs nothing and logs nothing). A Collada file goes to trimesh without its appearance elements
    (`pytest_ddenv.sdf.collada_geometry`), since trimesh's Collada reader has no option to skip materials and
    logs a traceback for every texture it cannot open. A vertex that is not a finite number is an error
    (trimesh would drop it with its triangles).
    """
    import io

    import trimesh

    data = None if path.suffix.lower() == ".dae" else read_regular(path, MAX_MESH_BYTES, "mesh file")
    try:
        if data is None:
            from pytest_ddenv.sdf import collada_geometry

            geometry_only = io.BytesIO(collada_geometry(path))
            loaded = trimesh.load(geometry_only, file_type="dae", force="mesh", process=False)
        else:
            loaded = trimesh.load(io.BytesIO(data), file_type=path.suffix.lower().lstrip("."), force="mesh",
                                  skip_materials=True, process=False)
    except Exception as error:  # trimesh raises many types for unreadable files
        raise WorldError(f"cannot read mesh file: {error}", source=str(path)) from error
    if not np.all(np.isfinite(np.asarray(getattr(loaded, "vertices", ()), dtype=float))):
        raise WorldError(f"the mesh file {shown_path(path)} has vertices that are not finite numbers",
                         source=str(path))
    if callable(getattr(loaded, "process", None)):
        loaded.process()  # type: ignore[attr-defined]  # merge duplicate vertices, as trimesh.load does by default
    if math.prod(scale) != 1.0 or scale != (1.0, 1.0, 1.0):
        loaded.apply_scale(np.array(scale))  # type: ignore[no-untyped-call]  # trimesh leaves it unannotated
    return loaded


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


@functools.lru_cache(maxsize=256)
def cone_mesh(radius: float, length: float, sections: int = 32) -> object:
    """A trimesh.Trimesh of a cone (`Shape` kind "cone": base at z = -length/2, tip at +length/2)."""
    import trimesh

    mesh = trimesh.creation.cone(radius, length, sections=sections)
    mesh.apply_translation([0.0, 0.0, -length / 2.0])
    return mesh


# -- polylines and heightmaps -------------------------------------------------------------------------------
HEIGHTMAP_MODES_16_BIT = ("I;16", "I;16L", "I;16B", "I;16N", "I")


@functools.lru_cache(maxsize=256)
def polyline_polygon(points: tuple[tuple[float, float], ...]) -> shapely.Polygon:
    """The shapely Polygon of a polyline's outline (closed implicitly), cached."""
    import shapely

    return shapely.remove_repeated_points(shapely.Polygon(points))


@functools.lru_cache(maxsize=256)
def polyline_mesh(points: tuple[tuple[float, float], ...], height: float) -> object:
    """A trimesh.Trimesh of the outline `points` extruded along z from 0 to `height` (made once per process).

    A concave outline gives a concave (watertight) mesh; the outline must be a valid simple polygon.
    """
    import trimesh

    problem = polyline_problem(points)
    if problem is not None:
        raise WorldError(f"cannot extrude the polyline: {problem}", field="points")
    return trimesh.creation.extrude_polygon(polyline_polygon(points), height)


def polyline_problem(points: Sequence[Sequence[float]]) -> str | None:
    """What makes `points` an invalid polyline outline, or None: fewer than 3 points, non-finite numbers or
    numbers beyond `world_values.MAX_MAGNITUDE`, collinear points (no area), or an outline that crosses itself."""
    import shapely

    from pytest_ddenv.world.values import MAX_MAGNITUDE

    if len(points) < 3:
        return f"an outline needs at least 3 points, got {len(points)}"
    try:
        array = np.asarray(points, dtype=float)
    except (TypeError, ValueError, OverflowError):
        array = np.empty(0)
    if array.shape != (len(points), 2) or not np.all(np.isfinite(array)):
        return "every point must be two finite numbers [x, y]"
    if np.abs(array).max() > MAX_MAGNITUDE:
        return (f"every point must be within -1e9 to 1e9 m (the simulator does not handle larger numbers), got "
                f"{np.abs(array).max():g}")
    spread = np.linalg.svd(array - array.mean(axis=0), compute_uv=False)
    if spread[1] <= 1e-9 * max(spread[0], 1e-300):
        return "the points are collinear: the outline has no area"
    polygon = shapely.Polygon(array)
    if not polygon.is_valid:
        return f"the outline crosses or touches itself ({shapely.is_valid_reason(polygon)})"
    return None


@functools.lru_cache(maxsize=16)
def load_heightmap(path: Path) -> FloatArray:
    """The heights (rows, columns) in 0..1 of a grayscale image: black 0, white 1 (8-bit: value / 255,
    16-bit: value / 65535; colour images are converted to grey). Row 0 is the image's top row, which is
    the +y edge of the heightmap seen from above; column 0 is its -x edge. Read once per process, only if it
    is a regular file of at most MAX_IMAGE_BYTES and MAX_HEIGHTMAP_PIXELS pixels (WorldError otherwise)."""
    with _heightmap_image(path, lambda message: WorldError(message, source=path)) as image:
        try:
            if image.mode in HEIGHTMAP_MODES_16_BIT:
                heights = np.asarray(image, dtype=np.float64) / 65535.0
            else:
                heights = np.asarray(image.convert("L"), dtype=np.float64) / 255.0
        except (OSError, ValueError) as error:
            raise WorldError(f"cannot read the heightmap image: {error}", source=path) from error
    if heights.ndim != 2 or min(heights.shape) < 2:
        raise WorldError(f"a heightmap image needs at least 2 x 2 pixels, got {heights.shape[::-1]}", source=path)
    heights = np.clip(heights, 0.0, 1.0)
    heights.setflags(write=False)
    return heights


@contextlib.contextmanager
def _heightmap_image(path: Path, fail: Callable[[str], WorldError]) -> Iterator[PIL.Image.Image]:
    """The image at `path`, opened (its header read, its pixels not yet decoded) from the bytes of a regular
    file, with at least 2 x 2 and at most MAX_HEIGHTMAP_PIXELS pixels; `fail(reason)` otherwise."""
    import io
    import warnings

    from PIL import Image, UnidentifiedImageError

    problem = regular_file_problem(path, "heightmap image file")
    if problem is not None:
        raise fail(problem)
    data = read_regular(path, MAX_IMAGE_BYTES, "heightmap image")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)  # refused below, by its size
            image = Image.open(io.BytesIO(data))
    except Image.DecompressionBombError:
        raise fail(f"the heightmap image {shown_path(path)} has more than {2 * (Image.MAX_IMAGE_PIXELS or 0)} pixels; "
                   f"a heightmap has at most {MAX_HEIGHTMAP_PIXELS}") from None
    except (OSError, UnidentifiedImageError, ValueError) as error:
        raise fail(f"cannot read the heightmap image {shown_path(path)}: {error}") from error
    with image:
        width, height = image.size
        if min(width, height) < 2:
            raise fail(f"a heightmap image needs at least 2 x 2 pixels, {shown_path(path)} has {width} x {height}")
        if width * height > MAX_HEIGHTMAP_PIXELS:
            raise fail(f"the heightmap image {shown_path(path)} has {width} x {height} pixels; a heightmap has at "
                       f"most {MAX_HEIGHTMAP_PIXELS} ({HEIGHTMAP_SIDE} x {HEIGHTMAP_SIDE}): scale the image down")
        yield image


@functools.lru_cache(maxsize=16)
def heightmap_mesh(path: Path, size: tuple[float, float, float]) -> object:
    """A trimesh.Trimesh of the solid under the heightmap image at `path` stretched over `size` (x, y
    centred on the origin, z from 0 up), made once per process."""
    import trimesh

    vertices, faces = geometry.heightmap_solid(load_heightmap(path), size)
    return trimesh.Trimesh(vertices, faces, process=False)


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


# -- validation of shapes made from data --------------------------------------------------------------------
def check_shape(shape: Shape, *, source: str | None = None, model: str | None = None, field: str | None = None,
                static: bool = True, keys: Mapping[str, str] | None = None, files: bool = True) -> None:
    """Raise a `WorldError` naming the file, model and field if `shape` is not a valid shape of its kind.

    For readers of world files: `field` is where the shape is (e.g. "shapes[0].polyline"); the bad value is
    named `field.KEY` with KEY one of radius, length, size, points, height, file, scale, renamed by `keys`
    (e.g. {"points": "point", "file": "uri"} for SDF). `static`: whether the model is static (a heightmap
    must be: it is terrain). Sizes are positive numbers within `world_values.MAX_MAGNITUDE`. `files`: whether
    the mesh or heightmap file is checked too (a regular file; a heightmap's image opens).
    """
    from pytest_ddenv.world.values import number_problem

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
            _check_image(path, fail)


def _check_image(path: Path, fail: Callable[[str | None, str], WorldError]) -> None:
    """The heightmap image is a regular file that opens (its header) with 2 x 2 to MAX_HEIGHTMAP_PIXELS pixels."""
    with _heightmap_image(path, lambda reason: fail("file", reason)):
        pass


# -- validation of names, physics and mesh files (shared by the YAML and SDF readers) ---------------------
read_bounded = read_regular
"""The name the SDF reader imports (`world_files.read_regular`)."""


def text_problem(text: str, *, allowed: str = "") -> str | None:
    """Why `text` cannot be a value of a world file (written to SDF as XML and read back), or None: a
    control character (tab and newline included, unless `allowed`) or a lone surrogate."""
    for found in _CONTROL.finditer(text):
        if found.group() not in allowed:
            return f"the control character {found.group()!r} (at position {found.start()}) is not allowed"
    return None


def name_problem(name: str) -> str | None:
    """Why `name` cannot name a model, a world or a robot, or None. Names are written to SDF and read back
    unchanged: no control characters, no blanks at either end, at most MAX_NAME_LENGTH characters."""
    if not name or not name.strip():
        return "a name must not be empty"
    problem = text_problem(name)
    if problem is not None:
        return problem
    if name != name.strip():
        return "a name must not start or end with a blank (SDF readers strip them)"
    if len(name) > MAX_NAME_LENGTH:
        return f"a name is at most {MAX_NAME_LENGTH} characters, this one has {len(name)}"
    return None


def solver_iterations_problem(value: object) -> str | None:
    """Why `value` is not a solver iteration count, or None (a whole number from 1 to MAX_SOLVER_ITERATIONS;
    a float such as 1e3 counts when it is whole)."""
    if not (is_integer(value) or (is_finite_number(value) and float(value).is_integer())) \
            or not 1 <= value <= MAX_SOLVER_ITERATIONS:
        return f"expected a whole number from 1 to {MAX_SOLVER_ITERATIONS}, got {shown(value)}"
    return None


def timestep_problem(value: float) -> str | None:
    """Why `value` (s) is not a simulation timestep, or None."""
    low, high = TIMESTEP_RANGE
    if not low <= value <= high:
        return f"expected a timestep from {low:g} to {high:g} s, got {value:g}"
    return None


def check_mesh_file(path: Path, scale: tuple[float, float, float], fail: Callable[[str], WorldError]) -> None:
    """Raise `fail(reason)` unless `path` is a mesh file with triangles and finite vertices (read now, once per
    process, so that a garbage or non-mesh file is refused when the world is loaded, not in the simulator)."""
    problem = regular_file_problem(path, "mesh file")
    if problem is not None:
        raise fail(problem)
    try:
        size = path.stat().st_size
    except OSError as error:
        raise fail(f"cannot read the mesh file {shown_path(path)}: {error.strerror or error}") from None
    if size > MAX_MESH_BYTES:
        raise fail(f"the mesh file {shown_path(path)} is larger than the {MAX_MESH_BYTES} byte limit")
    try:
        mesh = load_mesh(path, scale)
    except WorldError as error:
        cause = error.__cause__
        if cause is None:  # vertices that are not finite
            raise fail(error.reason) from None
        # trimesh's own failures that say nothing about the file: an optional module missing, or (trimesh 4) a
        # TypeError when it decodes binary garbage as text with no encoding detector installed.
        detail = "" if isinstance(cause, (ImportError, TypeError)) else f" ({str(cause).splitlines()[0][:120]})"
        raise fail(f"not a mesh file: {shown_path(path)} cannot be read as {path.suffix or 'a mesh'}{detail}"
                   ) from None
    vertices = np.asarray(getattr(mesh, "vertices", ()), dtype=float)
    faces = np.asarray(getattr(mesh, "faces", ()))
    if len(faces) == 0 or len(vertices) == 0:
        raise fail(f"not a mesh file: {shown_path(path)} holds no triangles (supported: .stl, .obj, .dae)")
    if not np.all(np.isfinite(vertices)):
        raise fail(f"the mesh file {shown_path(path)} has vertices that are not finite numbers")
