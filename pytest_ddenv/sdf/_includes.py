"""SDF documents and `<include>`s: versions, `model://` and file URIs, `model.config`, the include overrides."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from pytest_ddenv.errors import PATH_CHARACTERS, shown
from pytest_ddenv.sdf._fuel import parse_fuel_uri
from pytest_ddenv.sdf._paths import UnresolvedURI, resolve_uri
from pytest_ddenv.sdf._values import Values
from pytest_ddenv.sdf._xml import Lines, parse_xml, read_limited
from pytest_ddenv.world.files import is_file
from pytest_ddenv.world.model import Pose

MIN_VERSION = (1, 2)
"""Oldest SDF read: libsdformat converts 1.2 and 1.3 to 1.4 without changing models (physics elements only)."""
MAX_CONFIG_VERSION = (1, 9)
MAX_INCLUDE_DEPTH = 16
MAX_INCLUDES = 10_000
"""Most `<include>`s read for one world, at every depth: a tree 16 deep and 8 wide would be 8**16 files."""
BUILTIN_GROUND = """<sdf version="1.6"><model name="ground_plane"><static>true</static><link name="link">
<collision name="collision"><geometry><plane><normal>0 0 1</normal><size>100 100</size></plane></geometry>
<surface><friction><ode><mu>100</mu><mu2>50</mu2></ode></friction></surface></collision></link></model></sdf>"""
"""Gazebo's stock `model://ground_plane`, used when that include is not on the model path."""
LIGHT_ONLY_MODELS = ("sun",)
"""Stock `model://` includes that hold only a light; skipped when they are not on the model path."""
FUEL_GROUND = ("ground plane", "ground_plane")
"""Fuel's `OpenRobotics/Ground Plane`: the built-in ground when it is not in the Fuel cache or on the model path."""


@dataclass
class Included:
    """The `<model>` an `<include>` brings in, with the include's overrides (None: not overridden)."""

    model: ET.Element
    base_dir: Path | None
    element: ET.Element  # the <include>
    name: str
    pose: tuple[Pose, str] | None
    static: bool | None
    placement: str
    merge: bool
    legacy: bool  # from a file before SDF 1.7 (libsdformat's name rules of then)


@dataclass
class IncludedLight:
    """An `<include>` of a file that holds only a light (e.g. `model://sun`)."""

    name: str


class Documents:
    """Reads SDF documents and resolves `<include>`s through the model search path."""

    def __init__(self, values: Values, search_paths: Sequence[Path]) -> None:
        self.values = values
        self.lines: Lines = values.lines
        self.search_paths = search_paths
        self.count = 0  # the includes read so far (MAX_INCLUDES)

    def read_root(self, data: bytes | str, source: str | None) -> ET.Element:
        root = parse_xml(data, source, self.lines)
        if root.tag != "sdf":
            raise self.values.error(f"expected an <sdf> root element, got <{root.tag}>", root)
        version = root.get("version")
        if version is None:
            raise self.values.error("the <sdf> element has no version attribute", root, field="version")
        numbers = version_numbers(version)
        if numbers is None:
            raise self.values.error(f"unreadable SDF version {shown(version)}", root, field="version")
        if numbers < MIN_VERSION:
            raise self.values.error(
                f"SDF version {version.strip()} is not supported; convert it to 1.4 or newer (gz sdf -p)", root,
                field="version",
            )
        return root

    def include(self, element: ET.Element, base_dir: Path | None, depth: int) -> Included | IncludedLight:
        """What an `<include>` names. Raises WorldError (UnsupportedSdfError for actors and remote URIs)."""
        values = self.values
        uri_element = element.find("uri")
        uri = (uri_element.text or "").strip() if uri_element is not None else ""
        if not uri:
            raise values.error("an <include> needs a <uri>", element, field="include/uri")
        name = (element.findtext("name") or "").strip()
        fuel = parse_fuel_uri(uri)
        label = name or (fuel.name if fuel is not None else uri.rstrip("/").rsplit("/", 1)[-1])
        shown_uri = shown(uri, PATH_CHARACTERS)
        if depth > MAX_INCLUDE_DEPTH:
            raise values.error(f"includes nested more than {MAX_INCLUDE_DEPTH} deep (a cycle?) at {shown_uri}", element,
                               model=label)
        self.count += 1
        if self.count > MAX_INCLUDES:
            raise values.error(f"more than {MAX_INCLUDES} <include>s in one world (counting every level; this one is "
                               f"{shown_uri}); flatten the model tree or split the world", element, model=label,
                               field="include")
        try:
            path = resolve_uri(uri, base_dir, self.search_paths)
        except UnresolvedURI as unresolved:
            return self.builtin(uri, unresolved, element, name, label)
        model_file = self.model_file(path, element, label)
        root = self.read_root(read_limited(model_file, what="included model file"), str(model_file))
        return self.included(root, model_file.parent, element, name, label, f"{shown_uri} ({model_file})")

    def included(
        self, root: ET.Element, base_dir: Path | None, element: ET.Element, name: str, label: str, what: str
    ) -> Included | IncludedLight:
        values = self.values
        model = root.find("model")
        if model is None:
            actor = root.find("actor")
            if actor is not None:
                raise values.unsupported("actor", "animated actors are not simulated", element,
                                         model=name or actor.get("name") or label)
            light = root.find("light")
            if light is not None:
                return IncludedLight(name or light.get("name") or label)
            raise values.error(f"{what} holds no <model>", element, model=label)
        static = values.child_boolean(element, "static", "include", label)
        pose = values.pose(element, "include", label) if element.find("pose") is not None else None
        placement = (element.findtext("placement_frame") or "").strip()
        if placement and pose is None:
            raise values.error("an <include> with a <placement_frame> needs a <pose>", element, model=label,
                               field="include/placement_frame")
        merge = (element.get("merge") or "").strip().lower() in ("true", "1")
        return Included(model, base_dir, element, name or model.get("name") or "", pose, static, placement, merge,
                        is_legacy(root))

    def builtin(
        self, uri: str, unresolved: UnresolvedURI, element: ET.Element, name: str, label: str
    ) -> Included | IncludedLight:
        """Gazebo's stock sun and ground plane (`model://` or Fuel) when they are not here; else the error."""
        if unresolved.fuel is not None:
            stock = unresolved.fuel.name.casefold()
            light, ground = stock in LIGHT_ONLY_MODELS, stock in FUEL_GROUND
        else:
            stock = uri.removeprefix("model://").strip("/")
            light = uri.startswith("model://") and stock in LIGHT_ONLY_MODELS
            ground = uri.startswith("model://") and stock == "ground_plane"
        if light:
            return IncludedLight(name or stock)
        if ground:
            root = parse_xml(BUILTIN_GROUND, "(built-in model://ground_plane)", self.lines)
            return self.included(root, None, element, name, label, uri)
        if unresolved.remote:  # what it names is not here: the model can be skipped
            raise self.values.unavailable("include", unresolved.reason, element.find("uri"), model=label,
                                          field="include/uri")
        raise self.values.error(f"cannot resolve include {unresolved.describe()}", element, model=label,
                                field="include/uri")

    def model_file(self, path: Path, element: ET.Element, label: str) -> Path:
        """The model file of a model folder (model.config's <sdf>, else model.sdf), or `path` itself."""
        if is_file(path):
            return path
        config = path / "model.config"
        if is_file(config):
            root = parse_xml(read_limited(config, what="model.config"), str(config), self.lines)
            choices = [(child.get("version") or "0", (child.text or "").strip()) for child in root.findall("sdf")]
            choices = [(version, name) for version, name in choices if name]
            if choices:
                supported = [c for c in choices if (version_numbers(c[0]) or (0,)) <= MAX_CONFIG_VERSION] or choices
                ordered = sorted(supported, key=lambda c: version_numbers(c[0]) or (0,), reverse=True)
                existing = [name for _, name in ordered if is_file(path / name)]
                if existing:  # the newest one there (libsdformat takes the newest even when it is missing)
                    return path / existing[0]
                chosen = ordered[0][1]
                raise self.values.error(f"{config} names {shown(chosen, PATH_CHARACTERS)}, which does not exist",
                                        element, model=label, field="include/uri")
        if is_file(path / "model.sdf"):
            return path / "model.sdf"
        raise self.values.error(f"model folder {path} has no model.config or model.sdf", element, model=label,
                                field="include/uri")


def version_numbers(text: str) -> tuple[int, ...] | None:
    """An SDF version as numbers, blanks ignored (libsdformat reads " 1.6 " and "1. 6" too), or None."""
    try:
        return tuple(int(part) for part in "".join(text.split()).split("."))
    except ValueError:
        return None


def is_legacy(root: ET.Element) -> bool:
    """Whether the document of `root` (an `<sdf>`) is older than SDF 1.7, whose name rules are looser."""
    return (version_numbers(root.get("version") or "") or (0,)) < (1, 7)
