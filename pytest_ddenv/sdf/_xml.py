"""Hostile-input-safe XML reading with line numbers (defusedxml: no DTDs, no entities, no network)."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import defusedxml
from defusedxml.ElementTree import DefusedXMLParser

from pytest_ddenv.errors import WorldError

MAX_FILE_BYTES = 32 * 1024 * 1024
"""Largest SDF (or Collada) file read; larger files are refused before parsing."""


@dataclass
class Lines:
    """Where each parsed element came from (file and line), shared by every document of one load."""

    where: dict[int, tuple[str | None, int]] = field(default_factory=dict)
    keep: list[ET.Element] = field(default_factory=list)

    def of(self, element: ET.Element) -> tuple[str | None, int | None]:
        source, line = self.where.get(id(element), (None, None))
        return source, line


class _LineTarget:
    """A TreeBuilder that records the line of each start tag."""

    def __init__(self, lines: Lines, source: str | None) -> None:
        self._builder = ET.TreeBuilder()
        self._lines = lines
        self._source = source
        self.parser: DefusedXMLParser | None = None

    def start(self, tag: str, attrs: dict[str, str]) -> ET.Element:
        element = self._builder.start(tag, attrs)
        line = self.parser.parser.CurrentLineNumber if self.parser is not None else 0  # type: ignore[attr-defined]
        self._lines.where[id(element)] = (self._source, int(line))
        self._lines.keep.append(element)  # ids stay unique while the elements live
        return element

    def end(self, tag: str) -> ET.Element:
        return self._builder.end(tag)

    def data(self, data: str) -> None:
        self._builder.data(data)

    def close(self) -> ET.Element:
        return self._builder.close()


def read_limited(path: Path, *, what: str = "world file") -> bytes:
    """The bytes of `path`, refusing files over MAX_FILE_BYTES (without reading them whole)."""
    try:
        with path.open("rb") as handle:
            data = handle.read(MAX_FILE_BYTES + 1)
    except OSError as error:
        raise WorldError(f"cannot read {what}: {error.strerror or error}", source=path) from error
    if len(data) > MAX_FILE_BYTES:
        raise WorldError(
            f"{what} is larger than the {MAX_FILE_BYTES} byte limit; refusing to parse it", source=path
        )
    return data


def parse_xml(data: bytes | str, source: str | None, lines: Lines) -> ET.Element:
    """Parse XML text; DTDs, entity declarations and external references are refused (WorldError)."""
    if isinstance(data, str):
        data = data.encode("utf-8")
    if len(data) > MAX_FILE_BYTES:
        raise WorldError(f"XML text is larger than the {MAX_FILE_BYTES} byte limit; refusing to parse it", source=source)
    target = _LineTarget(lines, source)
    parser = DefusedXMLParser(target=target, forbid_dtd=True, forbid_entities=True, forbid_external=True)
    target.parser = parser
    try:
        parser.feed(data)
        root = parser.close()
    except ET.ParseError as error:
        line = error.position[0] if getattr(error, "position", None) else None
        raise WorldError(f"malformed XML: {error}", source=source, line=line) from None
    except defusedxml.DTDForbidden:
        raise WorldError(
            "XML document type declarations (<!DOCTYPE>) are not allowed: they enable entity-expansion "
            "and external-entity attacks", source=source, line=_current_line(parser),
        ) from None
    except defusedxml.EntitiesForbidden:
        raise WorldError("XML entity declarations are not allowed", source=source, line=_current_line(parser)) from None
    except defusedxml.DefusedXmlException as error:
        raise WorldError(f"forbidden XML construct: {error}", source=source, line=_current_line(parser)) from None
    return root


def _current_line(parser: DefusedXMLParser) -> int | None:
    try:
        return int(parser.parser.CurrentLineNumber)  # type: ignore[attr-defined]
    except AttributeError:  # pragma: no cover - parser already torn down
        return None


def local_name(tag: str) -> str:
    """The tag without its `{namespace}`."""
    return tag.rsplit("}", 1)[-1]
