"""Import Gazebo SDF (1.4-1.7) worlds and model files as a `World`, placed the way Gazebo simulates them.

Each top-level `<model>` (or `<include>`) becomes one `Model`: its links, nested models and collisions are
merged into one rigid body (joints are ignored). The first `<state>` block is applied as Gazebo's
`World::SetState` does on load: model pose, link world poses and the model `<scale>` of the collision shapes.
A static model whose collisions are all planes is the world's ground setting, not a model.
"""

from __future__ import annotations

import dataclasses
import math
import xml.etree.ElementTree as ET
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pytest_ddenv.errors import ScenarioError, WorldError
from pytest_ddenv.sdf import _poses
from pytest_ddenv.sdf._paths import UnresolvedURI, model_search_paths, resolve_uri
from pytest_ddenv.sdf._xml import Lines, local_name, parse_xml, read_limited
from pytest_ddenv.world import (
    DRIVE_KINDS,
    Ground,
    LaserMount,
    Model,
    Physics,
    Pose,
    RobotDescription,
    Scenario,
    Shape,
    TagValue,
    World,
    resolve_relative,
)

DDENV_NS = "https://github.com/pytest-ddenv/pytest-ddenv/sdf"
"""Namespace of the `ddenv:` elements that carry what SDF has no place for (scenario, tags, keep)."""

MIN_VERSION = (1, 4)
MAX_INCLUDE_DEPTH = 16
MESH_SUFFIXES = (".stl", ".obj", ".dae")
SUPPORTED_GEOMETRY = ("box", "cylinder", "sphere", "plane", "mesh")
GAZEBO_DEFAULT_MASS = 1.0  # Gazebo gives a link without <inertial> a mass of 1 kg
BUILTIN_GROUND = """<sdf version="1.6"><model name="ground_plane"><static>true</static><link name="link">
<collision name="collision"><geometry><plane><normal>0 0 1</normal><size>100 100</size></plane></geometry>
<surface><friction><ode><mu>100</mu><mu2>50</mu2></ode></friction></surface></collision></link></model></sdf>"""
"""Gazebo's stock `model://ground_plane`, used when that include is not on the model path."""
LIGHT_ONLY_MODELS = ("sun",)
"""Stock `model://` includes that hold only a light; skipped when they are not on the model path."""


# -- intermediate values -----------------------------------------------------------------------------------
@dataclass
class _Collision:
    name: str
    shape: Shape | None  # None for a plane
    normal: tuple[float, float, float] | None  # the plane's normal
    pose: Pose  # in the link frame
    mu: float | None
    mu2: float | None
    restitution: float | None
    unit: float  # the mesh file's unit in metres (1 for primitives)
    element: ET.Element


@dataclass
class _Link:
    name: str
    pose: Pose  # in the top-level model's frame
    collisions: list[_Collision]
    mass: float | None
    color: tuple[float, float, float, float] | None


@dataclass
class _Source:
    """A `<model>` element to read, with the overrides of the `<include>` that brought it in."""

    element: ET.Element
    base_dir: Path | None
    name: str | None = None
    pose: tuple[Pose, str] | None = None
    static: bool | None = None


@dataclass
class _Raw:
    name: str
    element: ET.Element
    static: bool
    pose: Pose  # body pose in the world
    links: list[_Link]
    keep: bool = False
    tags: dict[str, TagValue] = field(default_factory=dict)


@dataclass
class _State:
    pose: Pose | None = None
    scale: tuple[float, float, float] | None = None
    links: dict[str, Pose] = field(default_factory=dict)


# -- the loader --------------------------------------------------------------------------------------------
class _Loader:
    def __init__(self, source: str | None, model_paths: Iterable[str | Path]) -> None:
        self.source = source
        self.lines = Lines()
        self.search_paths = model_search_paths(model_paths)

    # errors ---------------------------------------------------------------------------------------------
    def error(
        self, message: str, element: ET.Element | None = None, *, model: str | None = None, field: str | None = None,
        kind: type[WorldError] = WorldError,
    ) -> WorldError:
        source, line = self.lines.of(element) if element is not None else (None, None)
        return kind(message, source=source or self.source, model=model, field=field, line=line)

    # scalar values --------------------------------------------------------------------------------------
    def floats(self, element: ET.Element, count: Sequence[int], where: str, model: str | None) -> list[float]:
        text = (element.text or "").split()
        try:
            values = [float(item) for item in text]
        except ValueError:
            raise self.error(f"expected numbers, got {element.text!r}", element, model=model, field=where) from None
        if len(values) not in count:
            expected = " or ".join(str(c) for c in count)
            raise self.error(f"expected {expected} numbers, got {len(values)}", element, model=model, field=where)
        if not all(math.isfinite(v) for v in values):
            raise self.error(f"expected finite numbers, got {element.text!r}", element, model=model, field=where)
        return values

    def number(self, element: ET.Element, where: str, model: str | None, *, positive: bool = False) -> float:
        value = self.floats(element, (1,), where, model)[0]
        if positive and value <= 0:
            raise self.error(f"expected a positive number, got {value}", element, model=model, field=where)
        return value

    def child_number(
        self, parent: ET.Element, tag: str, where: str, model: str | None, *, positive: bool = False
    ) -> float | None:
        child = parent.find(tag)
        return None if child is None else self.number(child, f"{where}/{tag}", model, positive=positive)

    def boolean(self, element: ET.Element, where: str, model: str | None) -> bool:
        text = (element.text or "").strip().lower()
        if text in ("1", "true"):
            return True
        if text in ("0", "false"):
            return False
        raise self.error(f"expected true/false or 1/0, got {element.text!r}", element, model=model, field=where)

    def pose(self, parent: ET.Element, where: str, model: str | None) -> tuple[Pose, str]:
        """The `<pose>` child of `parent` and the frame it is relative to ('' = the parent frame)."""
        element = parent.find("pose")
        if element is None:
            return _poses.IDENTITY, ""
        relative_to = (element.get("relative_to") or element.get("frame") or "").strip()
        field_name = f"{where}/pose" if where else "pose"
        if not (element.text or "").strip():
            return _poses.IDENTITY, relative_to
        if element.get("rotation_format", "euler_rpy") == "quat_xyzw":
            values = self.floats(element, (7,), field_name, model)
            try:
                return _poses.from_quaternion(*values), relative_to
            except ValueError as error:
                raise self.error(str(error), element, model=model, field=field_name) from None
        values = self.floats(element, (6,), field_name, model)
        if element.get("degrees", "false").strip().lower() in ("true", "1"):
            values[3:] = [math.radians(v) for v in values[3:]]
        return Pose(*values), relative_to

    # documents ------------------------------------------------------------------------------------------
    def read_root(self, data: bytes | str, source: str | None) -> ET.Element:
        root = parse_xml(data, source, self.lines)
        if root.tag != "sdf":
            raise self.error(f"expected an <sdf> root element, got <{root.tag}>", root)
        version = root.get("version")
        if version is None:
            raise self.error("the <sdf> element has no version attribute", root, field="version")
        try:
            numbers = tuple(int(part) for part in version.strip().split("."))
        except ValueError:
            raise self.error(f"unreadable SDF version {version!r}", root, field="version") from None
        if numbers < MIN_VERSION:
            raise self.error(
                f"SDF version {version} is not supported; convert it to 1.4 or newer (gz sdf -p)", root,
                field="version",
            )
        return root

    def load_world(self, root: ET.Element, base_dir: Path | None) -> World:
        world = root.find("world")
        if world is not None:
            return self.world(world, base_dir)
        model = root.find("model")
        if model is not None:
            name = Path(self.source).stem if self.source else (model.get("name") or "")
            return self.model_file(root, base_dir, name)
        raise self.error("the file holds neither a <world> nor a <model>", root)

    def model_file(self, root: ET.Element, base_dir: Path | None, name: str) -> World:
        sources = [_Source(element, base_dir) for element in root.findall("model")]
        raws = self.raws(sources, {})
        ground, models = self.split(raws, {})
        return World(models=tuple(models), scenario=None, ground=ground, name=name, source=self.source)

    def world(self, element: ET.Element, base_dir: Path | None) -> World:
        sources: list[_Source] = []
        world_frames: dict[str, tuple[Pose, str, ET.Element]] = {}
        for child in element:
            if child.tag == "model":
                sources.append(_Source(child, base_dir))
            elif child.tag == "include":
                included = self.include(child, base_dir, depth=0)
                if included is not None:
                    sources.append(included)
            elif child.tag == "frame":
                pose, relative_to = self.pose(child, f"frame '{child.get('name')}'", None)
                world_frames[child.get("name") or ""] = (pose, relative_to, child)
        raws = self.raws(sources, world_frames)
        state = element.find("state")
        states = self.states(state) if state is not None else {}
        ground, models = self.split(raws, states)
        return World(
            models=tuple(models),
            scenario=self.scenario(element),
            physics=self.physics(element),
            ground=ground,
            name=element.get("name") or "",
            source=self.source,
        )

    # includes -------------------------------------------------------------------------------------------
    def include(self, element: ET.Element, base_dir: Path | None, depth: int) -> _Source | None:
        uri_element = element.find("uri")
        if uri_element is None or not (uri_element.text or "").strip():
            raise self.error("an <include> needs a <uri>", element, field="include/uri")
        uri = (uri_element.text or "").strip()
        override_name = (element.findtext("name") or "").strip() or None
        if depth > MAX_INCLUDE_DEPTH:
            raise self.error(f"includes nested more than {MAX_INCLUDE_DEPTH} deep (a cycle?) at {uri!r}", element)
        try:
            path = resolve_uri(uri, base_dir, self.search_paths)
        except UnresolvedURI as unresolved:
            return self.builtin_include(uri, unresolved, element, override_name)
        model_file = self.model_sdf_file(path, element)
        root = self.read_root(read_limited(model_file, what="included model file"), str(model_file))
        model = root.find("model")
        if model is None:
            if root.find("light") is not None or root.find("actor") is not None:
                return None  # a light (e.g. model://sun): nothing to simulate
            raise self.error(f"{uri!r} ({model_file}) holds no <model>", element, model=override_name)
        static = element.find("static")
        pose = self.pose(element, "include", override_name) if element.find("pose") is not None else None
        return _Source(
            model, model_file.parent, override_name, pose,
            self.boolean(static, "include/static", override_name) if static is not None else None,
        )

    def builtin_include(
        self, uri: str, unresolved: UnresolvedURI, element: ET.Element, name: str | None
    ) -> _Source | None:
        stock = uri.removeprefix("model://").strip("/")
        if uri.startswith("model://") and stock in LIGHT_ONLY_MODELS:
            return None
        if uri.startswith("model://") and stock == "ground_plane":
            root = parse_xml(BUILTIN_GROUND, "(built-in model://ground_plane)", self.lines)
            pose = self.pose(element, "include", name) if element.find("pose") is not None else None
            return _Source(root[0], None, name, pose)
        raise self.error(f"cannot resolve include {unresolved.describe()}", element, model=name or uri, field="include/uri")

    def model_sdf_file(self, path: Path, element: ET.Element) -> Path:
        """The model file of a model directory (model.config's <sdf>, else model.sdf), or `path` itself."""
        if path.is_file():
            return path
        config = path / "model.config"
        if config.is_file():
            root = parse_xml(read_limited(config, what="model.config"), str(config), self.lines)
            choices = [(child.get("version") or "0", (child.text or "").strip()) for child in root.findall("sdf")]
            choices = [(version, name) for version, name in choices if name]
            if choices:
                supported = [c for c in choices if _version(c[0]) <= (1, 7)] or choices
                chosen = max(supported, key=lambda c: _version(c[0]))[1]
                if (path / chosen).is_file():
                    return path / chosen
                raise self.error(f"{config} names {chosen!r}, which does not exist", element, field="include/uri")
        if (path / "model.sdf").is_file():
            return path / "model.sdf"
        raise self.error(f"model directory {path} has no model.config or model.sdf", element, field="include/uri")

    # models -------------------------------------------------------------------------------------------
    def raws(self, sources: list[_Source], world_frames: dict[str, tuple[Pose, str, ET.Element]]) -> list[_Raw]:
        names = [source.name or source.element.get("name") or "" for source in sources]
        frames = dict(world_frames)
        for name, source in zip(names, sources, strict=True):
            frames[name] = (*self.source_pose(source, name), source.element)
        scope = _Scope(self, frames, {"", "world"}, None)
        raws = []
        for name, source in zip(names, sources, strict=True):
            if not name:
                raise self.error("a model needs a name attribute", source.element, field="name")
            raws.append(self.raw(source, name, scope.resolve(name, source.element)))
        return raws

    def source_pose(self, source: _Source, name: str) -> tuple[Pose, str]:
        return source.pose if source.pose is not None else self.pose(source.element, "", name)

    def raw(self, source: _Source, name: str, pose: Pose) -> _Raw:
        element = source.element
        static_element = element.find("static")
        static = self.boolean(static_element, "static", name) if static_element is not None else False
        if source.static is not None:
            static = source.static
        links = self.model_links(element, source.base_dir, name, "", _poses.IDENTITY, depth=0)
        keep_element = element.find(f"{{{DDENV_NS}}}keep")
        return _Raw(
            name=name, element=element, static=static, pose=pose, links=links,
            keep=self.boolean(keep_element, "ddenv:keep", name) if keep_element is not None else False,
            tags=self.tags(element, name),
        )

    def model_links(
        self, element: ET.Element, base_dir: Path | None, model: str, prefix: str, offset: Pose, depth: int
    ) -> list[_Link]:
        """The links of a model element (and of its nested models), with poses in the top model's frame."""
        entries: dict[str, tuple[Pose, str, ET.Element]] = {}
        nested: list[tuple[str, _Source]] = []
        for child in element:
            if child.tag in ("link", "frame"):
                label = child.get("name") or ""
                entries[label] = (*self.pose(child, f"{child.tag} '{label}'", model), child)
            elif child.tag == "model":
                label = child.get("name") or ""
                entries[label] = (*self.pose(child, f"model '{label}'", model), child)
                nested.append((label, _Source(child, base_dir)))
            elif child.tag == "include":
                source = self.include(child, base_dir, depth + 1)
                if source is not None:
                    label = source.name or source.element.get("name") or ""
                    entries[label] = (*self.source_pose(source, model), child)
                    nested.append((label, source))
        scope = _Scope(self, entries, {"", "__model__", element.get("name") or "", model}, model)
        links = []
        for child in element.findall("link"):
            label = child.get("name") or ""
            link_pose = _compose(offset, scope.resolve(label, child))
            links.append(self.link(child, f"{prefix}{label}", link_pose, base_dir, model, scope))
        for label, source in nested:
            nested_pose = _compose(offset, scope.resolve(label, source.element))
            links.extend(self.model_links(source.element, source.base_dir, model, f"{prefix}{label}::", nested_pose,
                                          depth + 1))
        return links

    def link(
        self, element: ET.Element, name: str, pose: Pose, base_dir: Path | None, model: str, scope: _Scope
    ) -> _Link:
        where = f"link '{name}'"
        collisions = []
        for child in element.findall("collision"):
            collisions.append(self.collision(child, f"{where}/collision '{child.get('name') or ''}'", base_dir,
                                             model, scope, element.get("name") or "", pose))
        mass = None
        inertial = element.find("inertial")
        if inertial is not None:
            mass = self.child_number(inertial, "mass", f"{where}/inertial", model)
        return _Link(name, pose, collisions, mass, self.color(element, where, model))

    def collision(
        self, element: ET.Element, where: str, base_dir: Path | None, model: str, scope: _Scope, link: str,
        link_pose: Pose,
    ) -> _Collision:
        pose, relative_to = self.pose(element, where, model)
        if relative_to and relative_to != link:  # a frame of the model: re-express in the link frame
            pose = _poses.relative(scope.resolve(link, element), scope.resolve(relative_to, element).compose(pose))
        geometry = element.find("geometry")
        if geometry is None or len(geometry) == 0:
            raise self.error("a collision needs a <geometry>", element, model=model, field=f"{where}/geometry")
        if len(geometry) > 1:
            kinds = ", ".join(child.tag for child in geometry)
            raise self.error(f"a geometry holds exactly one shape, got {kinds}", geometry, model=model,
                             field=f"{where}/geometry")
        shape_element = geometry[0]
        shape, normal, unit = self.shape(shape_element, f"{where}/geometry/{shape_element.tag}", base_dir, model)
        surface = element.find("surface")
        mu, mu2, restitution = self.surface(surface, f"{where}/surface", model) if surface is not None else (None,) * 3
        return _Collision(element.get("name") or "", shape, normal, pose, mu, mu2, restitution, unit, element)

    def shape(
        self, element: ET.Element, where: str, base_dir: Path | None, model: str
    ) -> tuple[Shape | None, tuple[float, float, float] | None, float]:
        kind = element.tag
        if kind == "box":
            size_element = self.required(element, "size", where, model)
            size = self.floats(size_element, (3,), f"{where}/size", model)
            if min(size) <= 0:
                raise self.error(f"box sizes must be positive, got {size}", size_element, model=model,
                                 field=f"{where}/size")
            return Shape("box", size=(size[0], size[1], size[2])), None, 1.0
        if kind == "cylinder":
            radius = self.number(self.required(element, "radius", where, model), f"{where}/radius", model, positive=True)
            length = self.number(self.required(element, "length", where, model), f"{where}/length", model, positive=True)
            return Shape("cylinder", radius=radius, length=length), None, 1.0
        if kind == "sphere":
            radius = self.number(self.required(element, "radius", where, model), f"{where}/radius", model, positive=True)
            return Shape("sphere", radius=radius), None, 1.0
        if kind == "plane":
            normal_element = element.find("normal")
            normal = self.floats(normal_element, (3,), f"{where}/normal", model) if normal_element is not None else [
                0.0, 0.0, 1.0]
            return None, (normal[0], normal[1], normal[2]), 1.0
        if kind == "mesh":
            return self.mesh(element, where, base_dir, model)
        raise self.error(
            f"unsupported geometry <{kind}>; supported: {', '.join(SUPPORTED_GEOMETRY)}", element, model=model,
            field=where,
        )

    def required(self, parent: ET.Element, tag: str, where: str, model: str) -> ET.Element:
        child = parent.find(tag)
        if child is None:
            raise self.error(f"missing <{tag}>", parent, model=model, field=f"{where}/{tag}")
        return child

    def mesh(self, element: ET.Element, where: str, base_dir: Path | None, model: str) -> tuple[Shape, None, float]:
        if element.find("submesh") is not None:
            raise self.error("<submesh> is not supported; use a mesh file with only that part", element, model=model,
                             field=f"{where}/submesh")
        uri_element = self.required(element, "uri", where, model)
        uri = (uri_element.text or "").strip()
        try:
            path = resolve_uri(uri, base_dir, self.search_paths)
        except UnresolvedURI as unresolved:
            raise self.error(f"missing mesh file {unresolved.describe()}", uri_element, model=model,
                             field=f"{where}/uri") from None
        if not path.is_file():
            raise self.error(f"mesh {uri!r} is not a file: {path}", uri_element, model=model, field=f"{where}/uri")
        if path.suffix.lower() not in MESH_SUFFIXES:
            raise self.error(f"unsupported mesh format {path.suffix!r}; supported: {', '.join(MESH_SUFFIXES)}",
                             uri_element, model=model, field=f"{where}/uri")
        scale_element = element.find("scale")
        scale = self.floats(scale_element, (3,), f"{where}/scale", model) if scale_element is not None else [1.0] * 3
        if min(scale) <= 0:
            raise self.error(f"mesh scales must be positive, got {scale}", scale_element, model=model,
                             field=f"{where}/scale")
        unit = collada_unit(path) if path.suffix.lower() == ".dae" else 1.0
        shape = Shape("mesh", mesh=str(path.resolve()), scale=(scale[0] * unit, scale[1] * unit, scale[2] * unit))
        return shape, None, unit

    def surface(
        self, element: ET.Element, where: str, model: str
    ) -> tuple[float | None, float | None, float | None]:
        mu = mu2 = None
        friction = element.find("friction")
        if friction is not None:
            ode = friction.find("ode")
            bullet = friction.find("bullet")
            if ode is not None:
                mu = self.child_number(ode, "mu", f"{where}/friction/ode", model)
                mu2 = self.child_number(ode, "mu2", f"{where}/friction/ode", model)
            if bullet is not None:
                if mu is None:
                    mu = self.child_number(bullet, "friction", f"{where}/friction/bullet", model)
                if mu2 is None:
                    mu2 = self.child_number(bullet, "friction2", f"{where}/friction/bullet", model)
        for value, label in ((mu, "mu"), (mu2, "mu2")):
            if value is not None and value < 0:
                raise self.error(f"friction must be >= 0, got {value}", element, model=model, field=f"{where}/{label}")
        restitution = None
        bounce = element.find("bounce")
        if bounce is not None:
            restitution = self.child_number(bounce, "restitution_coefficient", f"{where}/bounce", model)
            if restitution is not None and restitution < 0:
                raise self.error(f"restitution must be >= 0, got {restitution}", bounce, model=model,
                                 field=f"{where}/bounce/restitution_coefficient")
        return mu, mu2, restitution

    def color(self, link: ET.Element, where: str, model: str) -> tuple[float, float, float, float] | None:
        for visual in link.findall("visual"):
            material = visual.find("material")
            if material is None:
                continue
            for tag in ("ambient", "diffuse"):
                element = material.find(tag)
                if element is not None:
                    rgba = self.floats(element, (3, 4), f"{where}/visual/material/{tag}", model)
                    rgba = [min(max(v, 0.0), 1.0) for v in rgba] + [1.0] * (4 - len(rgba))
                    return (rgba[0], rgba[1], rgba[2], rgba[3])
        return None

    def tags(self, element: ET.Element, model: str) -> dict[str, TagValue]:
        tags: dict[str, TagValue] = {}
        for tag in element.findall(f"{{{DDENV_NS}}}tag"):
            name = tag.get("name") or ""
            text = tag.text or ""
            kind = tag.get("type", "str")
            try:
                value: TagValue = {"str": str, "int": int, "float": float}[kind](text) if kind != "bool" else (
                    text.strip().lower() == "true")
            except (KeyError, ValueError):
                raise self.error(f"unreadable tag value {text!r} of type {kind!r}", tag, model=model,
                                 field=f"ddenv:tag '{name}'") from None
            tags[name] = value
        return tags

    # state --------------------------------------------------------------------------------------------
    def states(self, element: ET.Element) -> dict[str, _State]:
        states = {}
        for model in element.findall("model"):
            name = model.get("name") or ""
            state = _State()
            if model.find("pose") is not None:
                state.pose = self.pose(model, "state/pose", name)[0]
            scale = model.find("scale")
            if scale is not None:
                values = self.floats(scale, (3,), "state/scale", name)
                if min(values) <= 0:
                    raise self.error(f"scales must be positive, got {values}", scale, model=name, field="state/scale")
                state.scale = (values[0], values[1], values[2])
            self.state_links(model, "", state, name)
            states[name] = state
        return states

    def state_links(self, element: ET.Element, prefix: str, state: _State, model: str) -> None:
        for link in element.findall("link"):
            if link.find("pose") is not None:
                state.links[f"{prefix}{link.get('name') or ''}"] = self.pose(link, "state/link/pose", model)[0]
        for nested in element.findall("model"):
            self.state_links(nested, f"{prefix}{nested.get('name') or ''}::", state, model)

    # assembly -----------------------------------------------------------------------------------------
    def split(self, raws: list[_Raw], states: dict[str, _State]) -> tuple[Ground | None, list[Model]]:
        ground: Ground | None = None
        ground_owner = ""
        models = []
        for raw in raws:
            state = states.get(raw.name, _State())
            model_pose = state.pose if state.pose is not None else raw.pose
            link_poses = [state.links.get(link.name, _compose(model_pose, link.pose)) for link in raw.links]
            planes = [(link, c) for link in raw.links for c in link.collisions if c.shape is None]
            if planes:
                found = self.ground(raw, planes, link_poses)
                if ground is not None:
                    raise self.error(f"a second ground plane (the first is '{ground_owner}'); only one is supported",
                                     raw.element, model=raw.name)
                ground, ground_owner = found, raw.name
                continue
            model = self.model(raw, model_pose, link_poses, state.scale)
            if model is not None:
                models.append(model)
        return ground, models

    def ground(self, raw: _Raw, planes: list[tuple[_Link, _Collision]], link_poses: list[Pose]) -> Ground:
        first = planes[0][1]
        if not raw.static or any(c.shape is not None for link in raw.links for c in link.collisions):
            raise self.error(
                "plane collisions are supported only as the ground: a static model whose collisions are all planes",
                first.element, model=raw.name,
            )
        heights = []
        for link, collision in planes:
            world = _compose(link_poses[raw.links.index(link)], collision.pose)
            normal = world.rotation @ np.asarray(collision.normal, dtype=float)
            norm = float(np.linalg.norm(normal))
            if norm == 0 or abs(normal[2] / norm - 1.0) > 1e-6:
                raise self.error("only horizontal ground planes (normal along +z) are supported", collision.element,
                                 model=raw.name, field="geometry/plane/normal")
            heights.append(world.z)
        mu = first.mu if first.mu is not None else 1.0
        return Ground(
            z=max(heights), mu=mu, mu2=first.mu2 if first.mu2 is not None else mu,
            restitution=first.restitution or 0.0,
        )

    def model(
        self, raw: _Raw, model_pose: Pose, link_poses: list[Pose], scale: tuple[float, float, float] | None
    ) -> Model | None:
        solid = [(link, pose) for link, pose in zip(raw.links, link_poses, strict=True) if link.collisions]
        if not solid:
            return None  # nothing the robot could touch (visual-only models, lights, ...)
        anchor = solid[0][1]
        shapes = []
        for link, pose in solid:
            to_link = _poses.relative(anchor, pose)
            for collision in link.collisions:
                assert collision.shape is not None
                shape = _scaled(collision.shape, scale) if scale is not None else collision.shape
                shapes.append(dataclasses.replace(shape, pose=_compose(to_link, collision.pose)))
        first = next((c for link, _ in solid for c in link.collisions if c.mu is not None or c.mu2 is not None), None)
        mu = first.mu if first is not None and first.mu is not None else 1.0
        mu2 = first.mu2 if first is not None and first.mu2 is not None else mu
        restitution = next((c.restitution for link, _ in solid for c in link.collisions if c.restitution is not None),
                           0.0)
        masses = [link.mass for link in raw.links]
        if raw.static:
            mass = sum(m for m in masses if m is not None) if any(m is not None for m in masses) else None
        else:
            mass = sum(m if m is not None else GAZEBO_DEFAULT_MASS for m in masses)
            if mass <= 0:
                raise self.error(f"a dynamic model needs a positive mass, got {mass}", raw.element, model=raw.name,
                                 field="link/inertial/mass")
        model = Model(
            name=raw.name, shapes=tuple(shapes), pose=anchor, mass=mass, static=raw.static, mu=mu, mu2=mu2,
            restitution=restitution, keep=raw.keep, tags=raw.tags,
        )
        color = next((link.color for link in raw.links if link.color is not None), None)
        return model if color is None else dataclasses.replace(model, color=color)

    # world settings -----------------------------------------------------------------------------------
    def physics(self, world: ET.Element) -> Physics:
        default = Physics()
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
            timestep = self.attribute_number(settings, "timestep", timestep, positive=True)
            iterations_value = self.attribute_number(settings, "solver_iterations", float(iterations), positive=True)
            if iterations_value != int(iterations_value):
                raise self.error("solver_iterations must be an integer", settings, field="ddenv:physics")
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
            raise self.error(f"expected a {'positive ' if positive else ''}number, got {text!r}", element,
                             field=f"ddenv:{local_name(element.tag)}/@{name}", kind=kind)
        return value

    def scenario(self, world: ET.Element) -> Scenario | None:
        element = world.find(f"{{{DDENV_NS}}}scenario")
        if element is None:
            return None
        start = element.find(f"{{{DDENV_NS}}}start")
        goal = element.find(f"{{{DDENV_NS}}}goal")
        if start is None or goal is None:
            raise self.error("ddenv:scenario needs ddenv:start and ddenv:goal", element, field="ddenv:scenario",
                             kind=ScenarioError)
        default = Scenario()

        def number(owner: ET.Element, name: str, fallback: float, *, positive: bool = False) -> float:
            return self.attribute_number(owner, name, fallback, positive=positive, kind=ScenarioError)

        description = element.find(f"{{{DDENV_NS}}}robot_description")
        return Scenario(
            robot=element.get("robot", default.robot) if description is None else self.robot(description),
            start=Pose(x=number(start, "x", 0.0), y=number(start, "y", 0.0), z=number(start, "z", 0.0),
                       yaw=number(start, "yaw", 0.0)),
            start_z_given=start.get("z") is not None,
            goal=(number(goal, "x", 0.0), number(goal, "y", 0.0),
                  number(goal, "z", 0.0) if goal.get("z") is not None else None),
            goal_tolerance=number(element, "goal_tolerance", default.goal_tolerance, positive=True),
            timeout=number(element, "timeout", default.timeout, positive=True),
        )


    def robot(self, element: ET.Element) -> RobotDescription:
        """<ddenv:robot_description>, written by `dump_sdf` for a robot given as a mapping."""
        field = "ddenv:robot_description"

        def fail(message: str, name: str) -> WorldError:
            return self.error(message, element, field=f"{field}/@{name}", kind=ScenarioError)

        urdf = element.get("urdf", "")
        if not urdf or not resolve_relative(urdf, self.source).is_file():  # relative: to the SDF file
            raise fail(f"URDF file not found: {urdf!r}", "urdf")
        drive = element.get("drive", "differential")
        if drive not in DRIVE_KINDS:
            raise fail(f"expected one of {', '.join(DRIVE_KINDS)}, got {drive!r}", "drive")
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
                height, min_range = (float(v) for v in laser_text.split())
            except ValueError:
                raise fail(f"expected true, false or 'HEIGHT MIN_RANGE', got {laser_text!r}", "laser") from None
            laser = LaserMount(height, min_range)
        return RobotDescription(
            urdf=urdf, left_wheels=wheels["left_wheels"], right_wheels=wheels["right_wheels"], drive=drive,
            wheel_radius=optional("wheel_radius"), track=optional("track"), track_factor=optional("track_factor"),
            max_wheel_torque=optional("max_wheel_torque") or 20.0, laser=laser, name=element.get("name", ""),
        )


def collada_unit(path: Path) -> float:
    """The `<asset><unit meter>` of a Collada file in metres (trimesh does not apply it; Gazebo does)."""
    root = parse_xml(read_limited(path, what="Collada mesh"), str(path), Lines())
    for element in root.iter():
        if local_name(element.tag) == "unit" and element.get("meter") is not None:
            try:
                meter = float(element.get("meter", "1"))
            except ValueError:
                return 1.0
            return meter if meter > 0 and math.isfinite(meter) else 1.0
    return 1.0


class _Scope:
    """Named frames of one level (the world, or one model), each posed relative to another frame."""

    def __init__(
        self, loader: _Loader, entries: dict[str, tuple[Pose, str, ET.Element]], roots: set[str], model: str | None
    ) -> None:
        self.loader = loader
        self.entries = entries
        self.roots = roots
        self.model = model
        self.cache: dict[str, Pose] = {}

    def resolve(self, name: str, element: ET.Element, visiting: tuple[str, ...] = ()) -> Pose:
        """The pose of frame `name` in this scope's frame."""
        if name in self.cache:
            return self.cache[name]
        if name in self.entries:
            if name in visiting:
                chain = " -> ".join((*visiting, name))
                raise self.loader.error(f"pose frames form a cycle: {chain}", element, model=self.model,
                                        field="pose/@relative_to")
            pose, relative_to, owner = self.entries[name]
            parent = _poses.IDENTITY if relative_to in self.roots else self.resolve(relative_to, owner, (*visiting, name))
            result = _compose(parent, pose)
        elif name in self.roots:
            result = _poses.IDENTITY
        else:
            known = ", ".join(sorted(n for n in self.entries if n)) or "none"
            raise self.loader.error(f"unknown frame {name!r} in relative_to/frame (known frames: {known})", element,
                                    model=self.model, field="pose/@relative_to")
        self.cache[name] = result
        return result


def _compose(parent: Pose, child: Pose) -> Pose:
    """parent ∘ child, exact when either is the identity."""
    if parent == _poses.IDENTITY:
        return child
    return parent.compose(child)


def _scaled(shape: Shape, scale: tuple[float, float, float]) -> Shape:
    """A shape under a model `<scale>`, as Gazebo classic's Shape::SetScale does (offsets are not scaled)."""
    sx, sy, sz = scale
    if scale == (1.0, 1.0, 1.0):
        return shape
    if shape.kind == "box":
        assert shape.size is not None
        return dataclasses.replace(shape, size=(shape.size[0] * sx, shape.size[1] * sy, shape.size[2] * sz))
    if shape.kind == "cylinder":
        assert shape.radius is not None and shape.length is not None
        return dataclasses.replace(shape, radius=shape.radius * max(sx, sy), length=shape.length * sz)
    if shape.kind == "sphere":
        assert shape.radius is not None
        return dataclasses.replace(shape, radius=shape.radius * max(sx, sy, sz))
    return dataclasses.replace(shape, scale=(shape.scale[0] * sx, shape.scale[1] * sy, shape.scale[2] * sz))


def _version(text: str) -> tuple[int, ...]:
    try:
        return tuple(int(part) for part in text.strip().split("."))
    except ValueError:
        return (0,)


# -- entry points ---------------------------------------------------------------------------------------------
def parse_sdf(
    text: str | bytes, *, source: str | Path | None = None, model_paths: Iterable[str | Path] = ()
) -> World:
    """Read SDF text; `source` names it in errors and anchors relative URIs."""
    source_name = str(source) if source is not None else None
    loader = _Loader(source_name, model_paths)
    root = loader.read_root(text, source_name)
    base_dir = Path(source_name).resolve().parent if source_name is not None else None
    return loader.load_world(root, base_dir)


def load_sdf(path: str | Path, *, model_paths: Iterable[str | Path] = (), skip_unsupported: bool = False) -> World:
    """Read a Gazebo `.world` or `.sdf` file (SDF 1.4-1.7), applying its first `<state>` block.

    `model_paths` are searched for `model://` URIs before GAZEBO_MODEL_PATH, GZ_SIM_RESOURCE_PATH,
    IGN_GAZEBO_RESOURCE_PATH and SDF_PATH.
    """
    path = Path(path)
    del skip_unsupported  # not implemented yet (issue 15)
    return parse_sdf(read_limited(path), source=path, model_paths=model_paths)
