"""The surgical export of a reduction of an MJCF scene: `minimal.xml` is the user's file with the removed top-level
bodies cut out of its text, nothing else changed.

Also cut, and said: an element of `<actuator>`, `<sensor>`, `<contact>`, `<equality>`, `<tendon>` that names
something inside a removed body (MuJoCo would refuse the file). When the reduction's scenario is not the
file's, the `ddenv:scenario` custom text is replaced (or added). The cut text is read back with MuJoCo and must
give exactly the minimal world; otherwise (or when a removed body lives in an included file) the scene is
regenerated instead: MuJoCo's `MjSpec` with the bodies deleted, written by `MjSpec.to_xml` (includes spliced in,
comments and formatting not kept), and the reason is kept for `summary.json`.
"""

from __future__ import annotations

import dataclasses
import xml.parsers.expat
from collections.abc import Collection
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from xml.sax.saxutils import quoteattr

from pytest_ddenv.errors import WorldError
from pytest_ddenv.mjcf._files import SceneFiles
from pytest_ddenv.mjcf._mujoco import mujoco_module
from pytest_ddenv.mjcf._reader import read_scene
from pytest_ddenv.mjcf._scenario import SCENARIO_TEXT
from pytest_ddenv.sdf._notes import listing
from pytest_ddenv.world.model import Scenario, World

REFERRING = ("actuator", "sensor", "contact", "equality", "tendon")
"""The sections whose elements name bodies, joints, geoms, sites or tendons elsewhere in the scene."""
FILE_ATTRIBUTES = ("file", "meshdir", "texturedir", "assetdir")
REGENERATED_TOLERANCE = 1e-5
"""How far a regenerated scene's numbers may be from the minimal world's (MuJoCo writes 6 significant digits)."""
COMPARED = ("models", "scenario", "physics", "ground", "name")
NAMESPACE_OF_TAG = {"freejoint": "joint", "xbody": "body"}
"""The namespace of a named element inside a body, when it is not the tag itself (MuJoCo keeps one per kind)."""
NAMESPACE_OF_ATTRIBUTE = {"body": "body", "body1": "body", "body2": "body", "joint": "joint", "joint1": "joint",
                          "joint2": "joint", "jointinparent": "joint", "geom": "geom", "geom1": "geom",
                          "geom2": "geom", "site": "site", "site1": "site", "site2": "site", "cranksite": "site",
                          "slidersite": "site", "camera": "camera", "light": "light", "tendon": "tendon",
                          "actuator": "actuator", "class": "default", "childclass": "default"}
"""What the attributes of `<actuator>`, `<sensor>`, ... refer to; any other attribute value may name anything."""
Named = tuple[str, str]
"""(namespace, name); a namespace of "" is any (an attribute whose kind is not known: cut when in doubt)."""


class MjcfSurgeryError(WorldError):
    """The scene cannot be cut (the caller regenerates it instead); says why."""


@dataclass
class _Element:
    tag: str
    attributes: dict[str, str]
    start: int
    end: int = -1
    names: set[Named] = field(default_factory=set)
    """Every `name` inside it (itself included), with its namespace."""
    values: set[Named] = field(default_factory=set)
    """Every attribute value inside it other than names (what it refers to), with the namespace it names in."""


@dataclass
class _Layout:
    """Where a file's top-level bodies, referring elements, scenario text and end are."""

    bodies: list[_Element] = field(default_factory=list)
    referring: list[_Element] = field(default_factory=list)
    scenario: _Element | None = None
    root_end: int = -1
    """Offset of the root's closing tag."""
    relative_files: list[str] = field(default_factory=list)
    """The relative paths its elements name (`file=`, `meshdir=`, `assetdir=`, ...)."""


def _layout(data: bytes, source: Path) -> _Layout:
    parser = xml.parsers.expat.ParserCreate()
    layout = _Layout()
    stack: list[_Element] = []

    def start(tag: str, attributes: dict[str, str]) -> None:
        element = _Element(tag, attributes, parser.CurrentByteIndex)
        if data[_tag_end(data, element.start) - 2:_tag_end(data, element.start)] == b"/>":
            element.end = _tag_end(data, element.start)
        path = [entry.tag for entry in stack]
        if path == ["mujoco", "worldbody"] and tag == "body":
            layout.bodies.append(element)
        elif len(path) == 2 and path[0] == "mujoco" and path[1] in REFERRING:
            layout.referring.append(element)
        elif path == ["mujoco", "custom"] and tag == "text" and attributes.get("name") == SCENARIO_TEXT:
            layout.scenario = element
        layout.relative_files.extend(value for key, value in attributes.items()
                                     if key in FILE_ATTRIBUTES and value and not Path(value).is_absolute())
        named = {(NAMESPACE_OF_TAG.get(tag, tag), attributes["name"])} if "name" in attributes else set()
        refers = _references(tag, attributes)
        for entry in (*stack, element):
            entry.names.update(named)
            entry.values.update(refers)
        stack.append(element)

    def end(tag: str) -> None:
        element = stack.pop()
        if element.end < 0:
            element.end = _tag_end(data, parser.CurrentByteIndex)
        if not stack:
            layout.root_end = parser.CurrentByteIndex

    parser.StartElementHandler, parser.EndElementHandler = start, end
    try:
        parser.Parse(data, True)
    except xml.parsers.expat.ExpatError as error:
        raise MjcfSurgeryError(f"cannot locate the elements: {error}", source=source) from None
    return layout


def _references(tag: str, attributes: dict[str, str]) -> set[Named]:
    """What an element's attributes may name: (namespace, name), namespace "" when the attribute's is not known
    (`objname` names in its `objtype`, `refname` in its `reftype`)."""
    refers: set[Named] = set()
    for key, value in attributes.items():
        if key == "name":
            continue
        namespace = (attributes.get("objtype", "") if key == "objname" else attributes.get("reftype", "")
                     if key == "refname" else NAMESPACE_OF_ATTRIBUTE.get(key, ""))
        refers.add((NAMESPACE_OF_TAG.get(namespace, namespace), value))
    return refers


def _names_any(values: set[Named], gone: set[Named]) -> bool:
    """Whether a reference in `values` names one of `gone` (in its namespace, or in any for an unknown one)."""
    names = {name for _, name in gone}
    return any((namespace, name) in gone if namespace else name in names for namespace, name in values)


def _tag_end(data: bytes, at: int) -> int:
    """Just past the '>' that closes the tag starting at `at` (a '>' inside a quoted value skipped)."""
    quote = 0
    for index in range(at, len(data)):
        byte = data[index]
        if quote:
            quote = 0 if byte == quote else quote
        elif byte in b"\"'":
            quote = byte
        elif byte == ord(">"):
            return index + 1
    return len(data)


def _extent(data: bytes, start: int, end: int) -> tuple[int, int]:
    """`start, end` widened to whole lines when nothing else is on them (no blank line is left behind)."""
    line_start = data.rfind(b"\n", 0, start) + 1
    line_end = data.find(b"\n", end)
    line_end = len(data) if line_end < 0 else line_end + 1
    if data[line_start:start].strip() or data[end:line_end].strip():
        return start, end
    return line_start, line_end


def scenario_text(scenario: Scenario) -> str | None:
    """The `ddenv:scenario` data of `scenario`, None when it cannot say it (a robot given as a description)."""
    if not isinstance(scenario.robot, str):
        return None
    start, goal = scenario.start, scenario.goal
    goal_text = ",".join(f"{v!r}" for v in (goal[0], goal[1], *(() if goal[2] is None else (goal[2],))))
    return (f"robot={scenario.robot} start={start.x!r},{start.y!r},{start.yaw!r} goal={goal_text} "
            f"timeout={scenario.timeout!r} tolerance={scenario.goal_tolerance!r}")


@dataclass(frozen=True)
class Cut:
    data: bytes
    also_cut: tuple[str, ...]
    """The elements cut because they named something in a removed body."""
    scenario_written: bool


def cut_bodies(path: str | Path, removed: Collection[str], *, write_scenario: bool = False,
               scenario: Scenario | None = None) -> Cut:
    """The scene at `path` with the top-level bodies `removed` cut out of its text; with `write_scenario`, its
    `ddenv:scenario` replaced by `scenario` (None: removed). MjcfSurgeryError when it cannot be cut."""
    source = Path(path)
    scene = SceneFiles.read(source)
    removed = set(removed)
    data = scene.files[source.resolve()]
    for body in scene.bodies:
        if body.name in removed and body.file.resolve() != source.resolve():
            raise MjcfSurgeryError(f"body {body.name} is in the included file {body.file}, which is not copied",
                                   source=source)
    layout = _layout(data, source)
    cuts = [element for element in layout.bodies if element.attributes.get("name", "").strip() in removed]
    found = {element.attributes.get("name", "").strip() for element in cuts}
    if found != removed:
        raise MjcfSurgeryError(f"cannot find the bodies {', '.join(sorted(removed - found))} in the file's "
                               "<worldbody>", source=source)
    gone: set[Named] = set().union(*(element.names for element in cuts)) if cuts else set()
    also = [element for element in layout.referring if _names_any(element.values, gone)]
    also_cut = tuple(f"<{e.tag} {e.attributes.get('name') or ''}>".replace(" >", ">") for e in also)
    for file, text in list(scene.files.items())[1:]:  # included files are not edited
        if any(_names_any(element.values, gone) for element in _layout(text, file).referring):
            raise MjcfSurgeryError(f"the included file {file} names something inside a removed body", source=source)
    edits: list[tuple[int, int, bytes]] = [(*_extent(data, e.start, e.end), b"") for e in (*cuts, *also)]
    if write_scenario:
        edits.append(_scenario_edit(data, layout, scenario, source))
    pieces, position = [], 0
    for start, end, insert in sorted(edits):
        pieces.append(data[position:max(position, start)] + insert)
        position = max(position, end)
    pieces.append(data[position:])
    return Cut(b"".join(pieces), also_cut, write_scenario)


def _scenario_edit(data: bytes, layout: _Layout, scenario: Scenario | None, source: Path) -> tuple[int, int, bytes]:
    text = None if scenario is None else scenario_text(scenario)
    if scenario is not None and text is None:
        raise MjcfSurgeryError("the reduction's robot is a description, which a ddenv:scenario text cannot hold",
                               source=source)
    element = f"<text name={quoteattr(SCENARIO_TEXT)} data={quoteattr(text or '')}/>".encode()
    if layout.scenario is not None:
        if text is None:
            return (*_extent(data, layout.scenario.start, layout.scenario.end), b"")
        return layout.scenario.start, layout.scenario.end, element
    if text is None:
        return 0, 0, b""
    return layout.root_end, layout.root_end, b"  <custom>\n    " + element + b"\n  </custom>\n"


def minimal_xml(source: Path, minimal: World, removed: Collection[str]) -> tuple[bytes, str]:
    """`minimal.xml` of a reduction of the scene `source` to `minimal`, and how it was made:
    "cut from FILE[; ...]" or "regenerated: why not cut". WorldError when neither gives the minimal world."""
    dropped = any(note.startswith("dropped ") for note in minimal.notes)
    in_file = read_scene(source, None, skip_unsupported=dropped).scenario
    write_scenario = minimal.scenario != in_file
    try:
        cut = cut_bodies(source, removed, write_scenario=write_scenario, scenario=minimal.scenario)
        _check(cut.data, source, minimal, dropped)
    except MjcfSurgeryError as error:
        data = _regenerated(source, removed, minimal.scenario if write_scenario else in_file)
        try:
            _check(data, source, minimal, dropped, tolerance=REGENERATED_TOLERANCE)
        except MjcfSurgeryError as second:
            raise MjcfSurgeryError(f"{error.reason}; the regenerated scene neither: {second.reason}",
                                   source=source) from None
        return data, (f"regenerated: {error.reason} (written by MuJoCo, which rounds numbers to 6 significant "
                      f"digits: equal to the minimal world within {REGENERATED_TOLERANCE:g})")
    how = f"cut from {source}"
    if cut.also_cut:
        how += f"; also cut, as they name something in a removed body: {listing(cut.also_cut)}"
    if cut.scenario_written:
        how += "; its ddenv:scenario written from the reduction's scenario (not the file's)"
    relative = _layout(cut.data, source).relative_files
    if relative:
        how += (f"; its relative paths ({listing(relative)}) are relative to the original's folder "
                f"{source.resolve().parent}: copy minimal.xml beside the original to open it")
    return cut.data, how


def _check(data: bytes, source: Path, minimal: World, dropped: bool, *, tolerance: float = 0.0) -> None:
    try:
        reread = read_scene(source, data, skip_unsupported=dropped)
    except WorldError as error:
        raise MjcfSurgeryError(f"the cut file does not load: {error}", source=source) from None
    reread = dataclasses.replace(reread, physics=dataclasses.replace(reread.physics, engine=minimal.physics.engine))
    differ = [part for part in COMPARED if not _close(getattr(reread, part), getattr(minimal, part), tolerance)]
    if differ:
        raise MjcfSurgeryError(f"the cut file does not give the minimal world (its {', '.join(differ)} differ)",
                               source=source)


def _close(first: object, second: object, tolerance: float) -> bool:
    """Equal, numbers within `tolerance` (absolute, or relative to the larger), in dataclasses and tuples too."""
    if first == second:
        return True
    if isinstance(first, float | int) and isinstance(second, float | int) and tolerance:
        return abs(first - second) <= tolerance * max(1.0, abs(first), abs(second))
    if dataclasses.is_dataclass(first) and type(first) is type(second):
        return all(_close(getattr(first, f.name), getattr(second, f.name), tolerance)
                   for f in dataclasses.fields(first) if f.compare)
    if isinstance(first, tuple) and isinstance(second, tuple) and len(first) == len(second):
        return all(_close(a, b, tolerance) for a, b in zip(first, second, strict=True))
    return False


def _regenerated(source: Path, removed: Collection[str], scenario: Scenario | None) -> bytes:
    """The scene as MuJoCo writes it (`MjSpec.to_xml`) without the removed bodies, with `scenario`."""
    mujoco = mujoco_module(source)
    spec: Any = mujoco.MjSpec.from_file(str(source))
    try:
        for name in removed:
            spec.delete(spec.body(name))
        for text in [text for text in spec.texts if text.name == SCENARIO_TEXT]:
            spec.delete(text)
        data = None if scenario is None else scenario_text(scenario)
        if data is not None:
            spec.add_text(name=SCENARIO_TEXT, data=data)
        return str(spec.to_xml()).encode("utf-8")
    except (ValueError, TypeError) as error:
        raise MjcfSurgeryError(f"MuJoCo cannot write the scene without the bodies: {error}", source=source) from None
