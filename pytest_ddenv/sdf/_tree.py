"""The tree of one SDF model: its links, frames, joints, nested models and includes, as libsdformat reads it.

Static, as Gazebo simulates it: a link is static when its model or any model around it is static (gz-sim:
`isStatic = model.Static() || staticParent`); an `<include>`'s `<static>`, `<name>` and `<pose>` replace the
included model's. A merged include (`<include merge="true">`, SDF 1.9) adds the included model's links, frames,
joints and nested models to the model around it, placed by a proxy frame `_merged__NAME__model__`; as in
libsdformat 12, the merged model's own `<static>` (and the include's) no longer applies: the parent's does.
A model of a file before SDF 1.7 (`legacy`) is read in libsdformat's order (nested models, then links, joints,
frames), so that a link and a joint of the same name are renamed as libsdformat renames them.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from pytest_ddenv.errors import shown
from pytest_ddenv.sdf import _poses
from pytest_ddenv.sdf._frames import Frame, Frames, compose
from pytest_ddenv.sdf._includes import Documents, IncludedLight
from pytest_ddenv.sdf._values import Values
from pytest_ddenv.world.limits import name_problem
from pytest_ddenv.world.model import Pose

MAX_NESTING = 64
"""Deepest nesting of models in models (includes included); deeper trees are refused, not a RecursionError."""
MAX_MODELS = 10_000
"""Most models read for one world, nested and included ones counted; more are refused (bounded time)."""
MAX_LINKS = 50_000
"""Most links read for one world (in all its models); more are refused (bounded time)."""
LEGACY_ORDER = {"model": 0, "include": 0, "link": 1, "joint": 2, "frame": 3}
"""libsdformat's order of a model's children before SDF 1.7: who is renamed when two kinds share a name."""


@dataclass
class LinkSpec:
    """A `<link>` of the tree and the frames its pose and its collisions' poses are resolved in."""

    element: ET.Element
    name: str  # scoped from the top-level model ("inner::l"), as a world `<state>` names links
    local: str  # its name in `frames`
    frames: Frames
    base_dir: Path | None
    static: bool
    static_from: str  # the scoped name of the outermost static model around it ("" = the top-level model)
    static_element: ET.Element | None  # where that model is (its <model> or <include>)


@dataclass
class ModelNode:
    """One `<model>` (or included model) of the tree."""

    name: str  # in its parent's scope
    scoped: str  # from the top-level model, with a trailing "::" ("" for the top-level model)
    element: ET.Element  # the <model>
    origin: ET.Element  # the <model> or <include> that put it here
    base_dir: Path | None
    static: bool
    static_from: str  # the scoped name of the outermost static model around it ("" = the top-level model)
    static_element: ET.Element | None
    frames: Frames
    pose: tuple[Pose, str] = (_poses.IDENTITY, "")  # in its parent's scope
    placement: str = ""
    links: list[LinkSpec] = field(default_factory=list)
    children: list[ModelNode] = field(default_factory=list)
    joints: int = 0
    plugins: list[str] = field(default_factory=list)
    lights: list[str] = field(default_factory=list)
    sensors: list[str] = field(default_factory=list)
    level: int = 0  # how many models are around it

    def all_links(self, offset: Pose = _poses.IDENTITY) -> list[tuple[LinkSpec, Pose]]:
        """Every link of the tree with its pose in this model's frame: own (and merged) links first."""
        result = [(link, compose(offset, self.frames.resolve(link.local, link.element))) for link in self.links]
        for child in self.children:
            child_pose = compose(offset, self.frames.resolve(child.name, child.origin))
            result.extend(child.all_links(child_pose))
        return result

    def walk(self) -> list[ModelNode]:
        return [self, *(node for child in self.children for node in child.walk())]


class TreeReader:
    def __init__(self, values: Values, documents: Documents) -> None:
        self.values = values
        self.documents = documents
        self.count = 0  # the models read so far (MAX_MODELS)
        self.links = 0  # the links read so far (MAX_LINKS)

    def model(
        self, element: ET.Element, base_dir: Path | None, name: str, *, origin: ET.Element, top: str = "",
        static: bool | None = None, parent: ModelNode | None = None, depth: int = 0,
        pose: tuple[Pose, str] | None = None, placement: str = "", legacy: bool = False,
    ) -> ModelNode:
        """The tree of a `<model>` element named `name` (`static`: an include's override; `legacy`: from a file
        before SDF 1.7)."""
        if not name:
            raise self.values.error("a model needs a name attribute", element, model=top or None, field="name")
        problem = name_problem(name)
        if problem is not None:
            raise self.values.error(f"{problem}; got {shown(name)}", element, model=top or shown(name), field="name")
        level = 0 if parent is None else parent.level + 1
        if level > MAX_NESTING:
            raise self.values.error(f"models nested more than {MAX_NESTING} deep; flatten the model tree", element,
                                    model=top, field="model")
        self.count += 1
        if self.count > MAX_MODELS:
            raise self.values.error(f"more than {MAX_MODELS} models in one world (nested and included ones counted); "
                                    "split the world", element, model=top or name, field="model")
        top = top or name
        own = static if static is not None else bool(self.values.child_boolean(element, "static", "", top))
        scoped = f"{parent.scoped}{name}::" if parent is not None else ""
        if parent is not None and parent.static:
            static_from, static_element = parent.static_from, parent.static_element
        elif own:
            static_from, static_element = scoped.removesuffix("::"), origin
        else:
            static_from, static_element = "", None
        node = ModelNode(
            name=name, scoped=scoped, element=element, origin=origin, base_dir=base_dir,
            static=(parent is not None and parent.static) or own, static_from=static_from,
            static_element=static_element,
            frames=Frames(self.values, top, {"__model__", element.get("name") or "", name}, legacy=legacy),
            pose=pose if pose is not None else self.values.pose(element, "", top),
            placement=placement or (element.get("placement_frame") or "").strip(), level=level,
        )
        self.fill(node, element, base_dir, "", top, depth)
        node.frames.check()
        return node

    def fill(self, node: ModelNode, element: ET.Element, base_dir: Path | None, proxy: str, top: str,
             depth: int) -> None:
        """Add the children of `element` (the node's `<model>`, or a merged include's model) to `node`."""
        values = self.values

        def relative(frame: str) -> str:
            return proxy if proxy and frame in ("", "__model__") else frame

        children = list(element)
        if node.frames.legacy:
            children.sort(key=lambda child: LEGACY_ORDER.get(child.tag, len(LEGACY_ORDER)))
        for child in children:
            label = (child.get("name") or "").strip()
            where = f"{child.tag} '{node.scoped}{label}'"
            if child.tag in ("link", "frame", "joint") and not label:
                raise values.error(f"a <{child.tag}> needs a name attribute", child, model=top, field="name")
            if child.tag == "link":
                self.links += 1
                if self.links > MAX_LINKS:
                    raise values.error(f"more than {MAX_LINKS} links in one world; split the world", child, model=top,
                                       field="link")
                pose, relative_to = values.pose(child, where, top)
                label = node.frames.add(label, Frame(pose, relative(relative_to), child, kind="link"))
                node.links.append(LinkSpec(child, f"{node.scoped}{label}", label, node.frames, base_dir,
                                           node.static, node.static_from, node.static_element))
                node.sensors.extend(f"{top}::{node.scoped}{label}::{s.get('name') or ''}"
                                    for s in child.iter("sensor"))
                node.lights.extend(f"{top}::{node.scoped}{label}::{s.get('name') or ''}"
                                   for s in child.findall("light"))
            elif child.tag == "frame":
                pose, relative_to = values.pose(child, where, top)
                attached = (child.get("attached_to") or "").strip()
                node.frames.add(label, Frame(pose, relative(relative_to), child, default=relative(attached),
                                             kind="frame"))
            elif child.tag == "joint":
                node.joints += 1
                pose, relative_to = values.pose(child, where, top)
                node.frames.add(label, Frame(pose, relative(relative_to), child, kind="joint",
                                             default=(child.findtext("child") or "").strip(),
                                             parent=(child.findtext("parent") or "").strip()))
            elif child.tag == "model":
                pose, relative_to = values.pose(child, where, top)
                nested = self.model(child, base_dir, label, origin=child, top=top, parent=node, depth=depth,
                                    pose=(pose, relative(relative_to)), legacy=node.frames.legacy)
                self.add_nested(node, nested)
            elif child.tag == "include":
                self.include(node, child, base_dir, top, depth, relative)
            elif child.tag == "plugin":
                node.plugins.append(plugin_name(child))

    def include(
        self, node: ModelNode, element: ET.Element, base_dir: Path | None, top: str, depth: int,
        relative: Callable[[str], str],
    ) -> None:
        included = self.documents.include(element, base_dir, depth + 1)
        if isinstance(included, IncludedLight):
            node.lights.append(f"{top}::{node.scoped}{included.name}")
            return
        node.plugins.extend(plugin_name(plugin) for plugin in element.findall("plugin"))
        pose, relative_to = included.pose or (self.values.pose(included.model, "", top)[0], "")
        if included.merge:
            if included.placement:
                raise self.values.unsupported("placement_frame", "a placement frame of a merged include",
                                              element.find("placement_frame"), model=top)
            proxy = f"_merged__{included.name}__model__"
            node.frames.add(proxy, Frame(pose, relative(relative_to), element))
            self.fill(node, included.model, included.base_dir, proxy, top, depth + 1)
            return
        nested = self.model(included.model, included.base_dir, included.name, origin=element, top=top,
                            static=included.static, parent=node, depth=depth + 1,
                            pose=(pose, relative(relative_to)), placement=included.placement,
                            legacy=included.legacy)
        self.add_nested(node, nested)

    def add_nested(self, node: ModelNode, nested: ModelNode) -> None:
        pose, relative_to = nested.pose
        node.frames.add(nested.name, Frame(pose, relative_to, nested.origin, placement=nested.placement,
                                           kind="model"), nested.frames)
        node.children.append(nested)


def plugin_name(element: ET.Element) -> str:
    return (element.get("filename") or element.get("name") or "plugin").strip()
