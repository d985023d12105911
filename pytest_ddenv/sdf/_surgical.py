"""Surgical export: the user's own SDF file with the removed models deleted and nothing else changed.

The file is parsed twice: once by the reader's hostile-input-safe parser (which also gives the top-level
elements' model names, resolving `<include>`s as the import did), once by expat alone for the character
span of each top-level `<model>`/`<include>` and of each `<state>` entry. The spans of the removed models are
cut out of the original text (with the indentation and line break around them); comments, includes,
relative paths, plugins, lights, physics, scene and GUI stay as written.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
import xml.parsers.expat
from collections.abc import Collection, Iterable
from dataclasses import dataclass
from pathlib import Path

from pytest_ddenv.errors import WorldError
from pytest_ddenv.sdf._includes import Documents, IncludedLight
from pytest_ddenv.sdf._paths import UnresolvedURI, model_search_paths
from pytest_ddenv.sdf._values import Values
from pytest_ddenv.sdf._xml import Lines, lenient_text, parse_xml, read_limited

TOP_LEVEL = ("model", "include")
STATE_PATHS = (("state", "model"), ("state", "insertions", "model"))


class SurgeryError(WorldError):
    """The file cannot be cut surgically (the caller writes a regenerated export instead); says why."""


@dataclass(frozen=True)
class _Span:
    path: tuple[str, ...]
    """Tags from the container down to the element (("model",), ("state", "model"), ...)."""
    start: int
    end: int
    """Character offsets in the text: the element's '<' and one past its final '>'."""


def cut_models(path: Path, removed: Collection[str], *, model_paths: Iterable[str | Path] = ()) -> str:
    """The text of the SDF file `path` without the top-level models named in `removed` (nor their `<state>`
    entries). SurgeryError when that cannot be done exactly."""
    data = read_limited(path)
    text = lenient_text(data)
    original = _decoded(data)
    if len(text) != len(original):
        raise SurgeryError("the file has characters the parser rewrites with another length (a stray '&')",
                           source=path)
    root = parse_xml(data, str(path), Lines())
    container = root.find("world")
    if container is None:
        container = root
    names = _top_level_names(container, path, model_paths)
    spans = _spans(text, depth=2 if container is not root else 1)
    top = [span for span in spans if span.path in (("model",), ("include",))]
    if len(top) != len(names):
        raise SurgeryError(f"found {len(top)} top-level models by position and {len(names)} by name", source=path)
    cuts = [span for span, name in zip(top, names, strict=True) if name is not None and name in removed]
    found = {name for name in names if name is not None} & set(removed)
    missing = sorted(set(removed) - found)
    if missing:
        raise SurgeryError(f"no top-level element for model(s) {', '.join(missing)}", source=path)
    state_names = _state_names(container)
    state_spans = [span for span in spans if span.path in STATE_PATHS]
    cuts += [span for span, name in zip(state_spans, state_names, strict=True) if name in removed]
    return _without(original, cuts)


def _decoded(data: bytes) -> str:
    """The file's text as `lenient_text` decodes it, but otherwise unchanged."""
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError:
        return data.decode("latin-1")


def _top_level_names(container: ET.Element, path: Path, model_paths: Iterable[str | Path]) -> list[str | None]:
    """The model name of each top-level `<model>`/`<include>` (None for an include of a light)."""
    documents = Documents(Values(Lines(), str(path)), model_search_paths(model_paths))
    names: list[str | None] = []
    for child in container:
        if child.tag == "model":
            names.append((child.get("name") or "").strip())
        elif child.tag == "include":
            try:
                included = documents.include(child, path.resolve().parent, 0)
            except (UnresolvedURI, WorldError) as error:
                raise SurgeryError(f"cannot resolve an include again to name it: {error}", source=path) from None
            names.append(None if isinstance(included, IncludedLight) else included.name)
    return names


def _state_names(container: ET.Element) -> list[str]:
    names = []
    for state in container.findall("state"):
        names += [(model.get("name") or "").strip() for model in state.findall("model")]
        for insertions in state.findall("insertions"):
            names += [(model.get("name") or "").strip() for model in insertions.findall("model")]
    return names


def _spans(text: str, *, depth: int) -> list[_Span]:
    """Spans of the elements `depth` levels below the root (the container's children) and of the `<state>`
    entries, in document order."""
    encoded = text.encode("utf-8")
    parser = xml.parsers.expat.ParserCreate()
    stack: list[tuple[str, int]] = []
    spans: list[_Span] = []

    last = [0, 0]  # (byte, character) of the last offset asked for: events come in document order

    def offset(byte_index: int) -> int:
        if len(encoded) == len(text):
            return byte_index
        byte, character = last
        if byte_index < byte:
            byte, character = 0, 0
        character += len(encoded[byte:byte_index].decode("utf-8"))
        last[:] = [byte_index, character]
        return character

    def start(tag: str, attributes: dict[str, str]) -> None:
        stack.append((tag, offset(parser.CurrentByteIndex)))

    def end(tag: str) -> None:
        _, begin = stack.pop()
        close = text.index(">", offset(parser.CurrentByteIndex)) + 1
        path = (*(name for name, _ in stack[depth:]), tag)
        if (len(stack) == depth and tag in TOP_LEVEL) or (path in STATE_PATHS and len(stack) >= depth):
            spans.append(_Span(path, begin, close))

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    try:
        parser.Parse(encoded, True)
    except xml.parsers.expat.ExpatError as error:
        if "junk after document element" not in str(error):
            raise SurgeryError(f"cannot locate the elements: {error}") from None
    return sorted(spans, key=lambda span: span.start)


def _without(text: str, cuts: list[_Span]) -> str:
    """`text` without the cut spans, each with the blank space before it on its line and the line break
    after it when nothing else is on those lines."""
    pieces = []
    position = 0
    for span in sorted(cuts, key=lambda cut: cut.start):
        start, end = span.start, span.end
        line_start = text.rfind("\n", 0, start) + 1
        if not text[line_start:start].strip():
            start = line_start
        line_end = text.find("\n", end)
        line_end = len(text) if line_end < 0 else line_end + 1
        if not text[end:line_end].strip():
            end = line_end
        pieces.append(text[position:max(position, start)])
        position = max(position, end)
    pieces.append(text[position:])
    return "".join(pieces)
