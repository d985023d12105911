"""Import Gazebo SDF worlds and model files as a `World`, placed and made static the way Gazebo simulates them.

Each top-level `<model>` (or `<include>`) becomes one `Model`: its links, nested models and collisions are
merged into one rigid body (joints are not simulated; `World.notes` names them). The first `<state>` block is
applied as Gazebo's `World::SetState` does on load: model pose, link world poses and the model `<scale>` of the
collision shapes. A static model whose collisions are all horizontal planes is the world's ground setting.
With `skip_unsupported`, a model that holds something that cannot be simulated is dropped and named in the
notes; without it, that is an `UnsupportedSdfError`.
"""

from __future__ import annotations

import functools
import xml.etree.ElementTree as ET
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import TypeVar

from pytest_ddenv.errors import shown
from pytest_ddenv.sdf._bodies import BodyReader, Raw, State
from pytest_ddenv.sdf._collada import collada_unit
from pytest_ddenv.sdf._ddenv import DdenvElements
from pytest_ddenv.sdf._frames import Frame, Frames, compose
from pytest_ddenv.sdf._includes import Documents, IncludedLight, is_legacy
from pytest_ddenv.sdf._notes import Notes
from pytest_ddenv.sdf._paths import model_search_paths
from pytest_ddenv.sdf._shapes import GeometryReader
from pytest_ddenv.sdf._tree import ModelNode, TreeReader, plugin_name
from pytest_ddenv.sdf._values import UnsupportedSdfError, Values
from pytest_ddenv.sdf._xml import DDENV_NS, Lines, read_limited
from pytest_ddenv.world.limits import name_problem
from pytest_ddenv.world.model import Ground, Model, World

__all__ = ["DDENV_NS", "collada_unit", "load_sdf", "parse_sdf"]

T = TypeVar("T")


class _Loader:
    def __init__(self, source: str | None, model_paths: Iterable[str | Path], skip_unsupported: bool) -> None:
        self.source = source
        self.values = Values(Lines(), source)
        search_paths = model_search_paths(model_paths)
        self.documents = Documents(self.values, search_paths)
        self.trees = TreeReader(self.values, self.documents)
        self.notes = Notes()
        self.bodies = BodyReader(self.values, GeometryReader(self.values, search_paths), self.notes)
        self.ddenv = DdenvElements(self.values)
        self.skip_unsupported = skip_unsupported
        self.legacy = False  # the file is older than SDF 1.7

    def guarded(self, name: str, read: Callable[[], T]) -> T | None:
        """`read()`, or None when it raises UnsupportedSdfError and such models are skipped (with a note)."""
        try:
            return read()
        except UnsupportedSdfError as error:
            if not self.skip_unsupported:
                raise
            self.notes.drop(error.model or name, error)
            return None

    # documents ------------------------------------------------------------------------------------------
    def load(self, data: bytes | str, base_dir: Path | None) -> World:
        root = self.documents.read_root(data, self.source)
        self.legacy = is_legacy(root)
        worlds = root.findall("world")
        if len(worlds) > 1:
            first, second = worlds[0], worlds[1]
            raise self.values.error(
                f"a second <world> ({shown(second.get('name') or '')}; the first, {shown(first.get('name') or '')}, "
                f"is at line {self.values.lines.of(first)[1]}); pytest-ddenv reads one world per file: put each in a "
                "file of its own", second, field="world")
        if worlds:
            return self.world(worlds[0], base_dir)
        model = root.find("model")
        if model is not None:
            name = Path(self.source).stem if self.source else (model.get("name") or "")
            return self.model_file(root, base_dir, name)
        raise self.values.error("the file holds neither a <world> nor a <model>", root)

    def model_file(self, root: ET.Element, base_dir: Path | None, name: str) -> World:
        nodes = [self.guarded(model.get("name") or "", lambda model=model: self.trees.model(  # type: ignore[misc]
            model, base_dir, (model.get("name") or "").strip(), origin=model, legacy=self.legacy))
            for model in root.findall("model")]
        frames = Frames(self.values, None, {"world"})
        present = [node for node in nodes if node is not None]
        for node in present:
            self.add_frame(frames, node)
        frames.check()
        ground, models = self.assemble(present, frames, {})
        return World(models=tuple(models), scenario=None, ground=ground, name=name, source=self.source,
                     notes=self.notes.lines())

    def world(self, element: ET.Element, base_dir: Path | None) -> World:
        name = (element.get("name") or "").strip()
        problem = name_problem(name) if name else None
        if problem is not None:
            raise self.values.error(f"{problem}; got {shown(name)}", element, field="world/@name")
        self.ddenv.check_world(element)
        frames = Frames(self.values, None, {"world"})
        nodes: list[ModelNode] = []
        for child in element:
            label = (child.get("name") or "").strip()
            if child.tag == "model":
                node = self.guarded(label, lambda child=child, label=label: self.trees.model(  # type: ignore[misc]
                    child, base_dir, label, origin=child, legacy=self.legacy))
            elif child.tag == "include":
                node = self.guarded(label, lambda child=child: self.include(child, base_dir))  # type: ignore[misc]
            else:
                self.world_child(child, frames, label)
                continue
            if node is not None:
                nodes.append(node)
        for node in nodes:
            self.add_frame(frames, node)
        frames.check()
        state = element.find("state")
        states = self.states(state, {node.name: node.origin for node in nodes}) if state is not None else {}
        ground, models = self.assemble(nodes, frames, states)
        return World(
            models=tuple(models),
            scenario=self.ddenv.scenario(element, {model.name for model in models}),
            physics=self.ddenv.physics(element),
            ground=ground,
            name=name,
            source=self.source,
            notes=self.notes.lines(),
        )

    def world_child(self, child: ET.Element, frames: Frames, label: str) -> None:
        """A world element other than a model: frames, lights, plugins; actors and populations are unsupported."""
        if child.tag == "frame":
            pose, relative_to = self.values.pose(child, f"frame '{label}'", None)
            frames.add(label, Frame(pose, relative_to, child, default=(child.get("attached_to") or "").strip(),
                                    kind="frame"))
        elif child.tag == "light":
            self.notes.lights.append(label)
        elif child.tag == "plugin":
            self.notes.plugins.append(f"{plugin_name(child)} (world)")
        elif child.tag in ("actor", "population"):
            why = ("animated actors are not simulated" if child.tag == "actor"
                   else "populations (models repeated by Gazebo) are not simulated; write the models out")
            self.guarded(label, lambda: _raise(self.values.unsupported(child.tag, why, child, model=label or None)))

    def include(self, element: ET.Element, base_dir: Path | None) -> ModelNode | None:
        included = self.documents.include(element, base_dir, 0)
        if isinstance(included, IncludedLight):
            self.notes.lights.append(included.name)
            return None
        if included.merge:
            raise self.values.error("a merged include (merge=\"true\") needs a model around it, not the world",
                                    element, model=included.name, field="include/@merge")
        node = self.trees.model(
            included.model, included.base_dir, included.name, origin=element, static=included.static,
            pose=included.pose or (self.values.pose(included.model, "", included.name)[0], ""),
            placement=included.placement, legacy=included.legacy,
        )
        node.plugins.extend(plugin_name(plugin) for plugin in element.findall("plugin"))
        return node

    def add_frame(self, frames: Frames, node: ModelNode) -> None:
        pose, relative_to = node.pose
        frames.add(node.name, Frame(pose, relative_to, node.origin, placement=node.placement, kind="model"),
                   node.frames)

    # models -------------------------------------------------------------------------------------------
    def assemble(
        self, nodes: list[ModelNode], frames: Frames, states: dict[str, State]
    ) -> tuple[Ground | None, list[Model]]:
        ground: Ground | None = None
        ground_owner = ""
        models = []
        for node in nodes:
            raw = self.guarded(node.name, lambda node=node: self.raw(node, frames))  # type: ignore[misc]
            if raw is None:
                continue
            state = states.get(raw.name, State())
            model_pose = state.pose if state.pose is not None else raw.pose
            link_poses = [state.links.get(link.name, compose(model_pose, link.pose)) for link in raw.links]
            found = self.bodies.ground(raw, link_poses)
            if found is not None:
                if ground is not None:
                    raise self.values.error(
                        f"a second ground plane (the first is '{ground_owner}'); only one is supported", raw.element,
                        model=raw.name)
                ground, ground_owner = found, raw.name
                continue
            model = self.guarded(raw.name, functools.partial(self.bodies.model, raw, model_pose, link_poses,
                                                             state.scale))
            if model is not None:
                models.append(model)
                self.note(node)
        return ground, models

    def raw(self, node: ModelNode, frames: Frames) -> Raw:
        pose = frames.resolve(node.name, node.origin)
        keep = self.ddenv.keep(node.element, node.name)
        return self.bodies.raw(node, pose, keep, self.ddenv.tags(node.element, node.name))

    def note(self, node: ModelNode) -> None:
        """What a simulated model holds that is not simulated: plugins, sensors, lights."""
        for part in node.walk():
            self.notes.plugins.extend(f"{plugin} ({node.name})" for plugin in part.plugins)
            self.notes.sensors.extend(part.sensors)
            self.notes.lights.extend(part.lights)

    # state --------------------------------------------------------------------------------------------
    def states(self, element: ET.Element, models: dict[str, ET.Element]) -> dict[str, State]:
        """The model entries of a `<state>`; its `<insertions>` of models the world already has are refused (Gazebo
        would load a second model of that name), other insertions are noted (not read)."""
        values = self.values
        for inserted in element.findall("insertions/model"):
            name = (inserted.get("name") or "").strip()
            if name in models:
                raise values.error(f"the <state> inserts a model {shown(name)}, but the world already has a model "
                                   f"{shown(name)} (line {values.lines.of(models[name])[1]}); Gazebo would load two "
                                   "models of that name: remove one of them", inserted, model=name,
                                   field="state/insertions/model")
            self.notes.insertions.append(name)
        states = {}
        for model in element.findall("model"):
            name = model.get("name") or ""
            state = State()
            if model.find("pose") is not None:
                state.pose = values.pose(model, "state/pose", name)[0]
            scale = model.find("scale")
            if scale is not None:
                numbers = values.floats(scale, (3,), "state/scale", name)
                if min(numbers) <= 0:
                    raise values.error(f"scales must be positive, got {numbers}", scale, model=name,
                                       field="state/scale")
                state.scale = (numbers[0], numbers[1], numbers[2])
            self.state_links(model, "", state, name)
            states[name] = state
        return states

    def state_links(self, element: ET.Element, prefix: str, state: State, model: str) -> None:
        for link in element.findall("link"):
            if link.find("pose") is not None:
                state.links[f"{prefix}{link.get('name') or ''}"] = self.values.pose(link, "state/link/pose", model)[0]
        for nested in element.findall("model"):
            self.state_links(nested, f"{prefix}{nested.get('name') or ''}::", state, model)


def _raise(error: Exception) -> None:
    raise error


# -- entry points ---------------------------------------------------------------------------------------------
def parse_sdf(
    text: str | bytes, *, source: str | Path | None = None, model_paths: Iterable[str | Path] = (),
    skip_unsupported: bool = False,
) -> World:
    """Read SDF text; `source` names it in errors and anchors relative URIs (see `load_sdf`)."""
    source_name = str(source) if source is not None else None
    loader = _Loader(source_name, model_paths, skip_unsupported)
    base_dir = Path(source_name).resolve().parent if source_name is not None else None
    return loader.load(text, base_dir)


def load_sdf(path: str | Path, *, model_paths: Iterable[str | Path] = (), skip_unsupported: bool = False) -> World:
    """Read a Gazebo `.world` or `.sdf` file (SDF 1.2 and newer), applying its first `<state>` block.

    `model_paths` are searched for `model://` URIs before GAZEBO_MODEL_PATH, GZ_SIM_RESOURCE_PATH,
    IGN_GAZEBO_RESOURCE_PATH and SDF_PATH. What cannot be simulated (an actor, a Fuel URI, a mixed static and
    dynamic model, ...) raises `UnsupportedSdfError`, or with `skip_unsupported=True` drops the model that
    holds it; `World.notes` says what was dropped and what else is not simulated (joints, plugins, lights, ...).
    """
    path = Path(path)
    return parse_sdf(read_limited(path), source=path, model_paths=model_paths, skip_unsupported=skip_unsupported)

