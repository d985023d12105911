"""Surgical export: the user's own SDF file with the removed models deleted and nothing else changed.

The file is parsed twice: once by the reader's hostile-input-safe parser (which gives the top-level elements'
model names, resolving local `<include>`s as the import did), once by expat alone for the character span of each
top-level element and of each `<state>` entry (`_surgical_text`). The spans of the removed models are cut out of
the original text (with the indentation and line break around them); comments, includes, relative paths,
plugins, lights, physics, scene and GUI stay as written, byte for byte. Only the `ddenv:scenario` element is
rewritten, when the reduction's scenario is not the file's (given on the command line, for instance).
"""

from __future__ import annotations

import enum
import xml.etree.ElementTree as ET
from collections.abc import Collection, Iterable
from dataclasses import dataclass
from pathlib import Path

from pytest_ddenv.errors import DdenvError, WorldError
from pytest_ddenv.sdf._ddenv import DDENV_NS, DdenvElements
from pytest_ddenv.sdf._includes import Documents, IncludedLight
from pytest_ddenv.sdf._paths import UnresolvedURI, model_search_paths
from pytest_ddenv.sdf._surgical_refs import relative_paths, removed_reference
from pytest_ddenv.sdf._surgical_text import (
    STATE_PATHS,
    Original,
    Span,
    SurgeryError,
    edited,
    element_spans,
    extent,
    indentation,
    line_break,
)
from pytest_ddenv.sdf._values import UnsupportedSdfError, Values
from pytest_ddenv.sdf._writer import _scenario as write_scenario_element
from pytest_ddenv.sdf._xml import Lines, parse_xml, read_limited
from pytest_ddenv.world.model import Scenario

__all__ = ["KEEP", "Cut", "SurgeryError", "cut_file", "cut_models"]

SCENARIO = f"{{{DDENV_NS}}}scenario"
BEFORE_SCENARIO = ("gravity", "physics", f"{{{DDENV_NS}}}physics")
"""World elements the writer puts before `ddenv:scenario`: a scenario added goes after the last of them."""


class Keep(enum.Enum):
    KEEP = "keep"


KEEP = Keep.KEEP
"""`cut_file(scenario=KEEP)`: leave the file's `ddenv:scenario` (or its absence) as written."""


@dataclass(frozen=True)
class Cut:
    """A cut SDF file: its bytes (encoded as the original), its text, and what else the export should say."""

    data: bytes
    text: str
    scenario_written: bool
    """Whether the `ddenv:scenario` element was written (replaced, added or deleted) to the reduction's one."""
    relative_paths: tuple[str, ...]
    """Relative file paths the kept elements hold (they resolve against the original file's folder)."""


def cut_models(path: Path, removed: Collection[str], *, model_paths: Iterable[str | Path] = ()) -> str:
    """The text of the SDF file `path` without the top-level models named in `removed` (nor their `<state>`
    entries). SurgeryError when that cannot be done exactly."""
    return cut_file(path, removed, model_paths=model_paths).text


def cut_file(path: Path, removed: Collection[str], *, model_paths: Iterable[str | Path] = (),
             scenario: Scenario | Keep | None = KEEP) -> Cut:
    """`cut_models` as the file's bytes, with `ddenv:scenario` written for `scenario` when it is not the file's
    (None: no scenario). SurgeryError when that cannot be done exactly, or when a kept element refers to a
    removed model (the cut file would not load)."""
    data = read_limited(path)
    original = Original.of(data)
    root = parse_xml(data, str(path), Lines())
    container = root.find("world")
    if container is None:
        container = root
    children = list(container)
    spans, container_end = element_spans(original.text, depth=2 if container is not root else 1, path=path)
    top = [span for span in spans if len(span.path) == 1]
    if len(top) != len(children):
        raise SurgeryError(f"found {len(top)} elements in the {container.tag} by position and {len(children)} "
                           "by parsing", source=path)
    names = _top_level_names(children, path, model_paths)
    removed_set = set(removed)
    missing = sorted(removed_set - {name for name in names if name is not None})
    if missing:
        raise SurgeryError(f"no top-level element for model(s) {', '.join(missing)}", source=path)
    cut = [index for index, name in enumerate(names) if name is not None and name in removed_set]
    kept = [child for index, child in enumerate(children) if index not in cut]
    problem = removed_reference(kept, removed_set)
    if problem is not None:
        raise SurgeryError(f"{problem}; the cut file would not load", source=path)
    cuts = [top[index] for index in cut]
    cuts += [span for span in spans if span.path in STATE_PATHS and span.name in removed_set]
    inserts: list[tuple[int, str]] = []
    written = scenario is not KEEP and _file_scenario(container, path) != scenario
    if written:
        assert not isinstance(scenario, Keep)
        _write_scenario(original.text, scenario, children, top, container_end, cuts, inserts, path)
    text = edited(original.text, cuts, inserts)
    return Cut(original.encoded(text), text, written, tuple(relative_paths(kept)))


def _top_level_names(children: list[ET.Element], path: Path, model_paths: Iterable[str | Path]) -> list[str | None]:
    """The model name of each top-level element: None for an element that is no model (a light, a plugin, an
    include of a light); an include that is unsupported or not on this machine (a Fuel model not downloaded)
    named as the import names it when it drops it (its `<name>`, else the model's name in the URI)."""
    documents = Documents(Values(Lines(), str(path)), model_search_paths(model_paths))
    names: list[str | None] = []
    for child in children:
        if child.tag == "model":
            names.append((child.get("name") or "").strip())
        elif child.tag == "include":
            uri = (child.findtext("uri") or "").strip()
            label = (child.findtext("name") or "").strip() or uri.rstrip("/").rsplit("/", 1)[-1]
            try:
                included = documents.include(child, path.resolve().parent, 0)
            except UnsupportedSdfError as error:
                names.append(error.model or label)
                continue
            except (UnresolvedURI, WorldError) as error:
                raise SurgeryError(f"cannot resolve an include again to name it: {error}", source=path) from None
            names.append(None if isinstance(included, IncludedLight) else included.name)
        else:
            names.append(None)
    return names


def _file_scenario(container: ET.Element, path: Path) -> Scenario | Keep | None:
    """The scenario the file holds (KEEP when it cannot be read: it is rewritten then)."""
    try:
        return DdenvElements(Values(Lines(), str(path))).scenario(container)
    except DdenvError:
        return KEEP


def _write_scenario(text: str, scenario: Scenario | None, children: list[ET.Element], top: list[Span],
                    container_end: int, cuts: list[Span], inserts: list[tuple[int, str]], path: Path) -> None:
    """Add to `cuts` and `inserts` the edits that make the file's `ddenv:scenario` the reduction's `scenario`:
    the element written by the same writer as the regenerated export, in place of the file's one, or after the
    world's physics settings, or first in the world."""
    old = [span for child, span in zip(children, top, strict=True) if child.tag == SCENARIO]
    cuts += old
    if scenario is None:
        return
    first = top[0] if top else None
    indent = indentation(text, first.start) if first is not None else None
    if indent is None:
        indent = "    "
    br = line_break(text)
    holder = ET.Element("world")
    write_scenario_element(holder, scenario, str(path))
    ET.indent(holder[0], space="  ")
    element = ET.tostring(holder[0], encoding="unicode").replace("\n", br + indent)
    anchors = old[:1] or [span for child, span in zip(children, top, strict=True) if child.tag in BEFORE_SCENARIO][-1:]
    if anchors:
        start, end, whole_lines = extent(text, anchors[0])
        if whole_lines:
            inserts.append((start if old else end, indent + element + br))
        else:
            inserts.append((anchors[0].start, element) if old else (anchors[0].end, br + indent + element))
    else:
        inserts.append((container_end, br + indent + element))
