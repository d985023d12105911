"""Hostile-input-safe XML reading with line numbers (defusedxml: no DTDs, no entities, no network).

The text is read as leniently as libsdformat (tinyxml2) reads it, by the smallest rewrite of the text that
keeps every line where it was: `--` inside comments, a stray `&`, an XML declaration that is not at the very
start or names an encoding expat does not know, a byte-order mark, bytes that are not UTF-8, and elements after
the root element are accepted. DTDs, entity declarations and external references are still refused.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import defusedxml
from defusedxml.ElementTree import DefusedXMLParser

from pytest_ddenv.errors import WorldError, shown
from pytest_ddenv.world.files import read_regular

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
        self.open: list[tuple[str, str, int]] = []  # the elements not yet closed: tag, name attribute, line

    def start(self, tag: str, attrs: dict[str, str]) -> ET.Element:
        element = self._builder.start(tag, attrs)
        line = int(self.parser.parser.CurrentLineNumber if self.parser is not None else 0)
        self._lines.where[id(element)] = (self._source, line)
        self._lines.keep.append(element)  # ids stay unique while the elements live
        self.open.append((local_name(tag), attrs.get("name", ""), line))
        return element

    def end(self, tag: str) -> ET.Element:
        if self.open:
            self.open.pop()
        return self._builder.end(tag)

    def context(self) -> tuple[str, str | None]:
        """Where a parse error happened: the innermost open element, and the model around it."""
        if not self.open:
            return "", None
        tag, name, line = self.open[-1]
        label = f" name={shown(name)}" if name else ""
        model = next((n for t, n, _ in reversed(self.open) if t == "model" and n), None)
        return f" (inside <{tag}{label}> opened at line {line})", model

    def data(self, data: str) -> None:
        self._builder.data(data)

    def close(self) -> ET.Element:
        return self._builder.close()


def read_limited(path: Path, *, what: str = "world file") -> bytes:
    """The bytes of `path`, refusing files over MAX_FILE_BYTES (without reading them whole) and devices."""
    return read_regular(path, MAX_FILE_BYTES, what)


def parse_xml(data: bytes | str, source: str | None, lines: Lines) -> ET.Element:
    """Parse XML text; DTDs, entity declarations and external references are refused (WorldError)."""
    if len(data) > MAX_FILE_BYTES:
        raise WorldError(f"XML text is larger than the {MAX_FILE_BYTES} byte limit; refusing to parse it",
                         source=source)
    text = declare_prefixes(lenient_text(data))
    target = _LineTarget(lines, source)
    parser = DefusedXMLParser(target=target, forbid_dtd=True, forbid_entities=True, forbid_external=True)
    target.parser = parser
    try:
        parser.feed(text)
        root = parser.close()
    except ET.ParseError as error:
        line = error.position[0] if getattr(error, "position", None) else None
        if getattr(error, "code", None) == _JUNK_AFTER_ROOT and _markup_follows(text, error.position):
            closed: ET.Element = target.close()  # tinyxml2 reads on; libsdformat uses the first <sdf>
            return closed
        inside, model = target.context()
        raise WorldError(f"malformed XML: {error}{inside}", source=source, line=line, model=model) from None
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


_JUNK_AFTER_ROOT = 9  # expat's XML_ERROR_JUNK_AFTER_DOC_ELEMENT
_DECLARATION = re.compile(r"\A\s*<\?xml\s.*?\?>", re.DOTALL)
_SPECIAL = re.compile(r"<!--|<!\[CDATA\[|<\?|&")
_REFERENCE = re.compile(r"&(?:amp|lt|gt|quot|apos|#[0-9]+|#x[0-9a-fA-F]+);")


def lenient_text(data: bytes | str) -> str:
    """`data` as text expat reads the way tinyxml2 reads the bytes, every line kept where it was.

    Bytes are UTF-8 (a byte-order mark is dropped); other bytes are taken one character each, as tinyxml2
    passes them through. The XML declaration is blanked (the text is already decoded, and tinyxml2 accepts it
    after whitespace, where expat does not). Inside comments, dashes become spaces (`--` is not allowed in XML
    comments; tinyxml2 ends a comment at the first `-->` whatever it holds). A `&` that starts no predefined or
    numeric character reference is escaped, so it stays literal text as in tinyxml2.
    """
    if isinstance(data, bytes):
        try:
            text = data.decode("utf-8-sig")
        except UnicodeDecodeError:
            text = data.decode("latin-1")
    else:
        text = data.removeprefix("\ufeff")
    declaration = _DECLARATION.match(text)
    if declaration is not None:
        text = _blank(declaration.group()) + text[declaration.end():]
    if "<!--" not in text and "&" not in text:
        return text
    parts: list[str] = []
    position = 0
    for match in _SPECIAL.finditer(text):
        start = match.start()
        if start < position:
            continue  # inside a comment, CDATA section or processing instruction already copied
        parts.append(text[position:start])
        token = match.group()
        if token == "&":
            parts.append("&" if _REFERENCE.match(text, start) else "&amp;")
            position = start + 1
            continue
        closing = {"<!--": "-->", "<?": "?>"}.get(token, "]]>")
        end = text.find(closing, start + len(token))
        if end < 0:
            parts.append(text[start:])  # unterminated: let expat report it
            position = len(text)
            break
        if token == "<!--":
            parts.append("<!--" + text[start + 4:end].replace("-", " ") + "-->")
        else:
            parts.append(text[start:end + len(closing)])
        position = end + len(closing)
    parts.append(text[position:])
    return "".join(parts)


DDENV_NS = "https://github.com/pytest-ddenv/pytest-ddenv/sdf"
"""Namespace of the `ddenv:` elements that carry what SDF has no place for (scenario, tags, keep)."""
UNDECLARED_NS = "urn:pytest-ddenv:undeclared:"
"""Namespace given to a prefix the file uses but never declares: `gz:x` is read as `{urn:...:gz}x`; an undeclared
`ddenv:` prefix is DDENV_NS."""
_NAME = r"[A-Za-z_][\w.-]*"
_PREFIXED = re.compile(rf"<\/?({_NAME}):{_NAME}|\s({_NAME}):{_NAME}\s*=")
_PROLOG = re.compile(r"(?:\s+|<!--.*?-->|<\?.*?\?>)*", re.DOTALL)
_ROOT_TAG = re.compile(rf"<({_NAME}(?::{_NAME})?)((?:\s+[^\s=/>]+\s*=\s*(?:\"[^\"]*\"|'[^']*'))*)\s*/?>")
_DECLARED = re.compile(rf"xmlns:({_NAME})\s*=")


def declare_prefixes(text: str) -> str:
    """`text` with each namespace prefix it uses but its root element does not declare declared there.

    The declarations go into the root's start tag, on its line, so every line stays where it was. A prefix
    declared on an inner element keeps that declaration inside it (XML scoping).
    """
    used = {name for match in _PREFIXED.finditer(text) for name in match.groups() if name} - {"xml", "xmlns"}
    if not used:
        return text
    prolog = _PROLOG.match(text)
    start = prolog.end() if prolog is not None else 0
    root = _ROOT_TAG.match(text, start)
    if root is None:
        return text  # no plain root start tag (a DTD, malformed XML): let the parser report it
    missing = sorted(used - set(_DECLARED.findall(root.group(2))))
    if not missing:
        return text
    declarations = "".join(f' xmlns:{name}="{DDENV_NS if name == "ddenv" else UNDECLARED_NS + name}"'
                           for name in missing)
    return text[:root.end(1)] + declarations + text[root.end(1):]


def _blank(text: str) -> str:
    """`text` with everything but its line breaks replaced by spaces."""
    return re.sub(r"[^\r\n]", " ", text)


def _markup_follows(text: str, position: tuple[int, int] | None) -> bool:
    """Whether what follows the root element at `position` (line, column) is markup, not text."""
    if position is None:
        return False
    line, column = position
    rest = "".join(text.splitlines(keepends=True)[line - 1:])[column:].lstrip()
    return rest.startswith("<")  # markup (tinyxml2 reads even a stray end tag there); text is an error in both


def _current_line(parser: DefusedXMLParser) -> int | None:
    try:
        return int(parser.parser.CurrentLineNumber)
    except AttributeError:  # pragma: no cover - parser already torn down
        return None


def local_name(tag: str) -> str:
    """The tag without its `{namespace}`."""
    return tag.rsplit("}", 1)[-1]
