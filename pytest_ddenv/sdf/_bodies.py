"""From a model tree to one rigid body: its collisions, mass, friction, colour; the ground plane apart.

Each top-level model is one `Model`: all its links static -> a static Model, all dynamic -> a dynamic one. A
model that mixes static and dynamic links cannot be one rigid body and is unsupported (it names the static
part). A static model whose collisions are all horizontal planes is the world's ground; planes of other static
models become thin boxes (a note says so); a plane in a dynamic model is unsupported.
"""

from __future__ import annotations

import dataclasses
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field

import numpy as np

from pytest_ddenv.sdf import _poses
from pytest_ddenv.sdf._frames import compose
from pytest_ddenv.sdf._notes import Notes
from pytest_ddenv.sdf._shapes import GeometryReader, plane_box
from pytest_ddenv.sdf._tree import LinkSpec, ModelNode
from pytest_ddenv.sdf._values import Values
from pytest_ddenv.world.model import Ground, Model, Pose, Shape, TagValue

GAZEBO_DEFAULT_MASS = 1.0  # Gazebo gives a link without <inertial> a mass of 1 kg
MAX_COLLISIONS = 50_000
"""Most collisions read for one world (in all its links); more are refused (bounded time)."""


@dataclass
class Collision:
    name: str
    shapes: list[Shape]  # posed in the collision frame
    normal: tuple[float, float, float] | None  # a plane's normal (then `shapes` is empty)
    plane_size: tuple[float, float]
    pose: Pose  # in the link frame
    mu: float | None
    mu2: float | None
    restitution: float | None
    element: ET.Element


@dataclass
class Link:
    spec: LinkSpec
    pose: Pose  # in the top-level model's frame
    collisions: list[Collision]
    mass: float | None
    color: tuple[float, float, float, float] | None

    @property
    def name(self) -> str:
        return self.spec.name


@dataclass
class Raw:
    """A top-level model read from the file, before `<state>` and the ground are applied."""

    name: str
    element: ET.Element
    static: bool
    pose: Pose  # the model frame in the world
    links: list[Link]
    joints: int = 0
    keep: bool = False
    tags: dict[str, TagValue] = field(default_factory=dict)


@dataclass
class State:
    pose: Pose | None = None
    scale: tuple[float, float, float] | None = None
    links: dict[str, Pose] = field(default_factory=dict)


class BodyReader:
    def __init__(self, values: Values, geometry: GeometryReader, notes: Notes) -> None:
        self.values = values
        self.geometry = geometry
        self.notes = notes
        self.collisions = 0  # the collisions read so far (MAX_COLLISIONS)

    # reading --------------------------------------------------------------------------------------------
    def raw(self, node: ModelNode, pose: Pose, keep: bool, tags: dict[str, TagValue]) -> Raw:
        """The links and collisions of a top-level model tree. Raises UnsupportedSdfError for a model that
        mixes static and dynamic links."""
        links = [self.link(spec, link_pose, node.name) for spec, link_pose in node.all_links()]
        solid = [link for link in links if link.collisions]
        static = node.static
        if solid:
            static = solid[0].spec.static
            other = next((link for link in solid if link.spec.static != static), None)
            if other is not None:
                fixed = other if other.spec.static else solid[0]
                moving = solid[0] if other.spec.static else other
                part = fixed.spec.static_from or node.name
                raise self.values.unsupported(
                    "model", f"static nested model '{part}' in a model whose link '{moving.name}' is dynamic: "
                    "not one rigid body (in Gazebo the static part stays put while the rest moves)",
                    fixed.spec.static_element, model=node.name, field=f"model '{part}'/static",
                )
        return Raw(node.name, node.element, static, pose, links, sum(n.joints for n in node.walk()), keep, tags)

    def link(self, spec: LinkSpec, pose: Pose, model: str) -> Link:
        where = f"link '{spec.name}'"
        collisions = []
        for child in spec.element.findall("collision"):
            self.collisions += 1
            if self.collisions > MAX_COLLISIONS:
                raise self.values.error(f"more than {MAX_COLLISIONS} collisions in one world; split the world", child,
                                        model=model, field=f"{where}/collision")
            collision = self.collision(child, f"{where}/collision '{child.get('name') or ''}'", spec, model)
            if collision is not None:
                collisions.append(collision)
        mass = None
        inertial = spec.element.find("inertial")
        if inertial is not None:
            mass = self.values.child_number(inertial, "mass", f"{where}/inertial", model)
        return Link(spec, pose, collisions, mass, self.color(spec.element, where, model))

    def collision(self, element: ET.Element, where: str, spec: LinkSpec, model: str) -> Collision | None:
        pose, relative_to = self.values.pose(element, where, model)
        # "__model__" of a merged link's collision stays the frame of the model around it, as in libsdformat 12
        if relative_to and relative_to != spec.local:  # a frame of the model: re-express in the link frame
            frames = spec.frames
            pose = _poses.relative(frames.resolve(spec.local, element), compose(frames.resolve(relative_to, element),
                                                                                pose))
        geometry_element = element.find("geometry")
        if geometry_element is None:
            return None  # libsdformat gives it an empty geometry: nothing to collide with
        geometry = self.geometry.read(geometry_element, where, spec.base_dir, model)
        if geometry is None:
            return None
        if geometry.holes:
            self.notes.holes.append((f"{model}::{spec.name}::{element.get('name') or ''}", geometry.holes))
        surface = element.find("surface")
        mu, mu2, restitution = self.surface(surface, f"{where}/surface", model) if surface is not None else (None,) * 3
        return Collision(element.get("name") or "", geometry.shapes, geometry.normal, geometry.plane_size, pose, mu,
                         mu2, restitution, element)

    def surface(self, element: ET.Element, where: str, model: str) -> tuple[float | None, float | None, float | None]:
        values = self.values
        mu = mu2 = None
        friction = element.find("friction")
        if friction is not None:
            ode = friction.find("ode")
            bullet = friction.find("bullet")
            if ode is not None:
                mu = values.child_number(ode, "mu", f"{where}/friction/ode", model)
                mu2 = values.child_number(ode, "mu2", f"{where}/friction/ode", model)
            if bullet is not None:
                if mu is None:
                    mu = values.child_number(bullet, "friction", f"{where}/friction/bullet", model)
                if mu2 is None:
                    mu2 = values.child_number(bullet, "friction2", f"{where}/friction/bullet", model)
        for value, label in ((mu, "mu"), (mu2, "mu2")):
            if value is not None and value < 0:
                raise values.error(f"friction must be >= 0, got {value}", element, model=model,
                                   field=f"{where}/{label}")
        restitution = None
        bounce = element.find("bounce")
        if bounce is not None:
            restitution = values.child_number(bounce, "restitution_coefficient", f"{where}/bounce", model)
            if restitution is not None and restitution < 0:
                raise values.error(f"restitution must be >= 0, got {restitution}", bounce, model=model,
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
                    rgba = self.values.floats(element, (3, 4), f"{where}/visual/material/{tag}", model)
                    rgba = [min(max(v, 0.0), 1.0) for v in rgba] + [1.0] * (4 - len(rgba))
                    return (rgba[0], rgba[1], rgba[2], rgba[3])
        return None

    # assembly -------------------------------------------------------------------------------------------
    def ground(self, raw: Raw, link_poses: list[Pose]) -> Ground | None:
        """The ground setting if `raw` is a static model whose collisions are all horizontal planes."""
        collisions = [(link_pose, c) for link, link_pose in zip(raw.links, link_poses, strict=True)
                      for c in link.collisions]
        if not raw.static or not collisions or any(c.normal is None for _, c in collisions):
            return None
        heights = []
        for link_pose, collision in collisions:
            world = compose(link_pose, collision.pose)
            normal = world.rotation @ np.asarray(collision.normal, dtype=float)
            if abs(normal[2] / float(np.linalg.norm(normal)) - 1.0) > 1e-6:
                return None
            heights.append(world.z)
        first = collisions[0][1]
        mu = first.mu if first.mu is not None else 1.0
        return Ground(z=max(heights), mu=mu, mu2=first.mu2 if first.mu2 is not None else mu,
                      restitution=first.restitution or 0.0)

    def model(
        self, raw: Raw, model_pose: Pose, link_poses: list[Pose], scale: tuple[float, float, float] | None
    ) -> Model | None:
        solid = [(link, pose) for link, pose in zip(raw.links, link_poses, strict=True) if link.collisions]
        if not solid:
            self.notes.without_collisions.append(raw.name)
            return None  # nothing the robot could touch (visual-only models, lights, ...)
        anchor = solid[0][1]
        shapes = []
        for link, pose in solid:
            to_link = _poses.relative(anchor, pose)
            for collision in link.collisions:
                parts = collision.shapes
                if collision.normal is not None:
                    if not raw.static:
                        raise self.values.unsupported("plane", "a collision plane of a dynamic model (Gazebo's "
                                                      "planes are infinite and static)", collision.element,
                                                      model=raw.name)
                    parts = [plane_box(collision.normal, collision.plane_size)]
                    if raw.name not in self.notes.planes:
                        self.notes.planes.append(raw.name)
                for shape in parts:
                    if shape.kind == "heightmap" and not raw.static:
                        raise self.values.unsupported("heightmap", "a heightmap in a dynamic model (Gazebo "
                                                      "simulates heightmaps as static terrain only)",
                                                      collision.element, model=raw.name)
                    placed = _scaled(shape, scale) if scale is not None else shape
                    shapes.append(dataclasses.replace(placed, pose=compose(compose(to_link, collision.pose),
                                                                           shape.pose)))
        first = next((c for link, _ in solid for c in link.collisions if c.mu is not None or c.mu2 is not None), None)
        mu = first.mu if first is not None and first.mu is not None else 1.0
        mu2 = first.mu2 if first is not None and first.mu2 is not None else mu
        restitution = next((c.restitution for link, _ in solid for c in link.collisions if c.restitution is not None),
                           0.0)
        if raw.static:
            masses = [link.mass for link in raw.links if link.mass is not None]
            mass = sum(masses) if masses else None
        else:
            mass = sum(link.mass if link.mass is not None else GAZEBO_DEFAULT_MASS for link in raw.links
                       if not link.spec.static)
            if mass <= 0:
                raise self.values.error(f"a dynamic model needs a positive mass, got {mass}", raw.element,
                                        model=raw.name, field="link/inertial/mass")
        if raw.joints:
            self.notes.joints.append((raw.name, raw.joints))
        model = Model(
            name=raw.name, shapes=tuple(shapes), pose=anchor, mass=mass, static=raw.static, mu=mu, mu2=mu2,
            restitution=restitution, keep=raw.keep, tags=raw.tags,
        )
        color = next((link.color for link in raw.links if link.color is not None), None)
        return model if color is None else dataclasses.replace(model, color=color)


def _scaled(shape: Shape, scale: tuple[float, float, float]) -> Shape:
    """A shape under a model `<scale>`, as Gazebo classic's Shape::SetScale does (offsets are not scaled)."""
    sx, sy, sz = scale
    if scale == (1.0, 1.0, 1.0) or shape.kind == "heightmap":
        return shape
    if shape.kind == "box":
        assert shape.size is not None
        return dataclasses.replace(shape, size=(shape.size[0] * sx, shape.size[1] * sy, shape.size[2] * sz))
    if shape.kind in ("cylinder", "capsule", "cone"):
        assert shape.radius is not None and shape.length is not None
        return dataclasses.replace(shape, radius=shape.radius * max(sx, sy), length=shape.length * sz)
    if shape.kind == "sphere":
        assert shape.radius is not None
        return dataclasses.replace(shape, radius=shape.radius * max(sx, sy, sz))
    if shape.kind == "polyline":
        assert shape.points is not None and shape.height is not None
        return dataclasses.replace(shape, points=tuple((x * sx, y * sy) for x, y in shape.points),
                                   height=shape.height * sz)
    return dataclasses.replace(shape, scale=(shape.scale[0] * sx, shape.scale[1] * sy, shape.scale[2] * sz))
