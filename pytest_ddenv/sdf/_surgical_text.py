"""The text side of the surgical export: a file's original characters, where its elements are, and the edit.

The reader parses a lenient rewrite of the text (`_xml.lenient_text`); every rewrite keeps the length except a
stray `&`, which becomes `&amp;`. Offsets found by expat in the rewrite are mapped back to the original
characters, and the edited text is encoded back the way the file was (UTF-8 with or without a byte-order mark,
or one byte per character), so that everything not cut stays byte for byte as written.
"""

from __future__ import annotations

import bisect
import xml.parsers.expat
from dataclasses import dataclass
from pathlib import Path

from pytest_ddenv.errors import WorldError
from pytest_ddenv.sdf._xml import lenient_text

STATE_PATHS = (("state", "model"), ("state", "insertions", "model"))
BOM = b"\xef\xbb\xbf"


class SurgeryError(WorldError):
    """The file cannot be cut surgically (the caller writes a regenerated export instead); says why."""


@dataclass(frozen=True)
class Span:
    path: tuple[str, ...]
    """Tags (as written, prefix included) from the container down to the element: ("model",), ("state", "model")."""
    start: int
    end: int
    """Character offsets in the original text: the element's '<' and one past its final '>'."""
    name: str
    """The element's name attribute, stripped."""


@dataclass(frozen=True)
class Original:
    """A file's text as written, and how to encode an edit of it back."""

    text: str
    encoding: str
    """"utf-8" or "latin-1" (each byte one character, as tinyxml2 reads bytes that are not UTF-8)."""
    bom: bool

    @classmethod
    def of(cls, data: bytes) -> Original:
        try:
            text = data.decode("utf-8-sig")
        except UnicodeDecodeError:
            return cls(data.decode("latin-1"), "latin-1", False)
        return cls(text, "utf-8", data.startswith(BOM))

    def encoded(self, text: str) -> bytes:
        data = text.encode(self.encoding, errors="xmlcharrefreplace")
        return BOM + data if self.bom else data


def element_spans(original: str, *, depth: int, path: Path | None = None) -> tuple[list[Span], int]:
    """Spans (in the original text) of every element `depth` levels below the root (the container's children)
    and of the `<state>` entries, in document order; and the offset just after the container's start tag."""
    rewritten = lenient_text(original)
    to_original = _offset_map(original, rewritten, path)
    encoded = rewritten.encode("utf-8")
    parser = xml.parsers.expat.ParserCreate()
    stack: list[tuple[str, int, str]] = []
    spans: list[Span] = []
    container_end = [-1]
    last = [0, 0]  # (byte, character) of the last offset asked for: events come in document order

    def offset(byte_index: int) -> int:
        if len(encoded) == len(rewritten):
            return byte_index
        byte, character = last
        if byte_index < byte:
            byte, character = 0, 0
        character += len(encoded[byte:byte_index].decode("utf-8"))
        last[:] = [byte_index, character]
        return character

    def start(tag: str, attributes: dict[str, str]) -> None:
        begin = offset(parser.CurrentByteIndex)
        if len(stack) == depth - 1:
            container_end[0] = rewritten.index(">", begin) + 1
        stack.append((tag, begin, (attributes.get("name") or "").strip()))

    def end(tag: str) -> None:
        _, begin, name = stack.pop()
        close = rewritten.index(">", offset(parser.CurrentByteIndex)) + 1
        where = (*(entry[0] for entry in stack[depth:]), tag)
        if len(stack) == depth or (where in STATE_PATHS and len(stack) >= depth):
            spans.append(Span(where, to_original(begin), to_original(close), name))

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    try:
        parser.Parse(encoded, True)
    except xml.parsers.expat.ExpatError as error:
        if "junk after document element" not in str(error):
            raise SurgeryError(f"cannot locate the elements: {error}", source=path) from None
    if container_end[0] < 0:
        raise SurgeryError("cannot locate the elements: no container element", source=path)
    return sorted(spans, key=lambda span: span.start), to_original(container_end[0])


def _offset_map(original: str, rewritten: str, path: Path | None) -> _Mapping:
    """The map from offsets in `rewritten` (`lenient_text(original)`) to offsets in `original`."""
    inserted: list[int] = []  # offsets in `rewritten` of each stray '&' written as "&amp;"
    position = original.find("&")
    while position >= 0:
        at = position + 4 * len(inserted)
        if rewritten.startswith("&amp;", at) and not original.startswith("&amp;", position):
            inserted.append(at)
        position = original.find("&", position + 1)
    if len(rewritten) != len(original) + 4 * len(inserted):
        raise SurgeryError("the parser rewrites the file's text in a way the export cannot map back", source=path)
    return _Mapping(inserted)


@dataclass(frozen=True)
class _Mapping:
    inserted: list[int]

    def __call__(self, offset: int) -> int:
        return offset - 4 * bisect.bisect_left(self.inserted, offset)


def extent(text: str, span: Span) -> tuple[int, int, bool]:
    """What cutting `span` removes: with the blank space before it on its line and the line break after it when
    nothing else is on those lines (then True: whole lines)."""
    start, end = span.start, span.end
    line_start = text.rfind("\n", 0, start) + 1
    line_end = text.find("\n", end)
    line_end = len(text) if line_end < 0 else line_end + 1
    if text[line_start:start].strip() or text[end:line_end].strip():
        return start, end, False
    return line_start, line_end, True


def edited(text: str, cuts: list[Span], inserts: list[tuple[int, str]]) -> str:
    """`text` without the `extent` of each cut span, with each (offset, text) of `inserts` put in."""
    edits = [(*extent(text, span)[:2], "") for span in cuts] + [(at, at, insert) for at, insert in inserts]
    pieces = []
    position = 0
    for start, end, insert in sorted(edits, key=lambda edit: (edit[0], edit[1])):
        pieces.append(text[position:max(position, start)] + insert)
        position = max(position, end)
    pieces.append(text[position:])
    return "".join(pieces)


def line_break(text: str) -> str:
    return "\r\n" if "\r\n" in text else "\r" if "\r" in text and "\n" not in text else "\n"


def indentation(text: str, offset: int) -> str | None:
    """The blank space before `offset` on its line, or None when something else is there."""
    line_start = max(text.rfind("\n", 0, offset), text.rfind("\r", 0, offset)) + 1
    before = text[line_start:offset]
    return None if before.strip() else before
