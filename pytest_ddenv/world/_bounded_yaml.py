"""Reading YAML from untrusted files within bounds, and writing it back so that it reads the same.

PyYAML's safe loader with an iterative composer (the C composer recurses and crashes the process on a
document nested 100000 deep) that enforces: nesting at most MAX_DEPTH deep, aliases that add at most
MAX_ALIAS_NODES nodes (no "billion laughs"), no recursive aliases, no duplicate keys, one document. Numbers
in YAML 1.2 form (`1e9`, `2.5E-3`) are numbers, not the strings PyYAML's YAML 1.1 rules make of them, and
`1:30` is a string, as in YAML 1.2, not a YAML 1.1 base-60 number (whose conversion is quadratic in its
length); a scalar with an explicit tag (`!!float abc`) must fit it. The `Dumper` quotes strings that would
read as numbers. Every error is a `WorldError` naming the line and, where known, the field.

The C reader (libyaml) of newer PyYAML wheels refuses nesting beyond its own limit (1000) while it scans ahead,
which can come before this composer counts 64 levels; the text up to where it stopped is then read again
with PyYAML's pure-Python parser, which has no such limit, so that the error is this module's, with its line
and field, whatever PyYAML is installed.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from dataclasses import field as dataclass_field
from typing import Any

import yaml

from pytest_ddenv.errors import SHOWN_CHARACTERS, WorldError, shown

MAX_DEPTH = 64
"""Deepest nesting of lists and mappings read (a world file needs about 8)."""
MAX_ALIAS_NODES = 100_000
"""The most nodes aliases may add to a document by repeating their anchors' values."""
_SafeLoader: type[yaml.SafeLoader] = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
_SafeDumper: type[yaml.SafeDumper] = getattr(yaml, "CSafeDumper", yaml.SafeDumper)
_MERGE_TAG = "tag:yaml.org,2002:merge"
_STR_TAG, _INT_TAG, _FLOAT_TAG = "tag:yaml.org,2002:str", "tag:yaml.org,2002:int", "tag:yaml.org,2002:float"
_TAGGED_VALUES = {_INT_TAG: "an integer", _FLOAT_TAG: "a number", "tag:yaml.org,2002:bool": "true or false",
                  "tag:yaml.org,2002:timestamp": "a date (YYYY-MM-DD, with a time or not)"}
"""What a scalar with each of these explicit tags must be, in words."""
_INTEGER = re.compile(r"^[-+]?(?:0b[01]+|0x[0-9a-fA-F]+|0[0-7]*|[1-9][0-9]*)$")
"""An integer as PyYAML's YAML 1.1 constructor reads it (underscores removed), base-60 left out."""


class _LimitError(yaml.MarkedYAMLError):
    """The document breaks one of the reader's limits (depth, aliases, duplicate keys, a second document)."""

    def __init__(self, problem: str, mark: Any, path: str | None = None) -> None:
        super().__init__(problem=problem, problem_mark=mark)
        self.path = path


@dataclass
class _Open:
    """A list or mapping being composed: its node, expanded size, pending key and the keys seen."""

    node: yaml.SequenceNode | yaml.MappingNode
    size: int = 1
    key: yaml.Node | None = None
    keys: dict[tuple[str, str], int] = dataclass_field(default_factory=dict)


_ComposerBase: Any = object  # a mixin of the loaders below: their methods as types-PyYAML leaves them (untyped)


class _BoundedComposer(_ComposerBase):  # type: ignore[misc]
    """An iterative composer that enforces the limits, for yaml's safe loaders: the C composer recurses and
    crashes the process on a document nested 100000 deep."""

    def get_single_node(self) -> yaml.Node | None:
        self.get_event()  # stream start
        node = None if self.check_event(yaml.StreamEndEvent) else self._compose_document()
        if not self.check_event(yaml.StreamEndEvent):
            raise _LimitError("a world file holds one YAML document; found a second one ('---')",
                              self.get_event().start_mark)
        self.get_event()
        return node

    def _compose_document(self) -> yaml.Node:
        self.get_event()  # document start
        anchors: dict[str, yaml.Node] = {}
        sizes: dict[int, int] = {}
        stack: list[_Open] = []
        added = 0
        node: yaml.Node
        while True:
            event = self.get_event()  # libyaml's own nesting limit: see _load
            if isinstance(event, (yaml.SequenceEndEvent, yaml.MappingEndEvent)):
                done = stack.pop()
                node, size = done.node, done.size
                node.end_mark = event.end_mark
                sizes[id(node)] = size
            elif isinstance(event, yaml.AliasEvent):
                anchor = event.anchor or ""  # the parser gives every alias its anchor's name
                aliased = anchors.get(anchor)
                if aliased is None:
                    raise _LimitError(f"alias *{anchor[:SHOWN_CHARACTERS]} names no anchor before it",
                                      event.start_mark)
                node = aliased
                if any(entry.node is node for entry in stack):
                    raise _LimitError(f"alias *{anchor[:SHOWN_CHARACTERS]} is inside its own anchor's value "
                                      "(a recursive structure); write the value out", event.start_mark, _path(stack))
                size = sizes[id(node)]
                added += size
                if added > MAX_ALIAS_NODES:
                    raise _LimitError(f"aliases expand the document by more than {MAX_ALIAS_NODES} nodes (an "
                                      "alias bomb?); write the repeated values out or use fewer aliases",
                                      event.start_mark, _path(stack))
            else:
                node = self._node(event, anchors, stack)
                if isinstance(node, (yaml.SequenceNode, yaml.MappingNode)):
                    if len(stack) >= MAX_DEPTH:
                        raise _LimitError(f"lists and mappings nested more than {MAX_DEPTH} deep", event.start_mark,
                                          _path(stack))
                    stack.append(_Open(node))
                    continue
                size = sizes[id(node)] = 1
            if not stack:
                self.get_event()  # document end
                return node
            self._add(stack[-1], node, size, stack)

    def _node(self, event: Any, anchors: dict[str, yaml.Node], stack: list[_Open]) -> yaml.Node:
        if event.anchor is not None and event.anchor in anchors:
            raise _LimitError(f"anchor &{event.anchor[:SHOWN_CHARACTERS]} is defined twice", event.start_mark,
                              _path(stack))
        kind: type[yaml.Node]
        if isinstance(event, yaml.ScalarEvent):
            explicit = event.tag not in (None, "!")
            tag = event.tag if explicit else self.resolve(yaml.ScalarNode, event.value, event.implicit)
            if not explicit and tag in (_INT_TAG, _FLOAT_TAG) and ":" in event.value:
                tag = _STR_TAG  # 1:30 is text, as in YAML 1.2, not a YAML 1.1 base-60 number (quadratic to read)
            # The C parser's marks are yaml._yaml.Mark, which types-PyYAML's nodes leave out.
            scalar = yaml.ScalarNode(tag, event.value, event.start_mark, event.end_mark,  # type: ignore[arg-type]
                                     style=event.style)
            problem = self._tagged_problem(scalar) if explicit else None
            if problem is not None:
                raise _LimitError(problem, event.start_mark, _path(stack))
            node: yaml.Node = scalar
        else:
            kind = yaml.SequenceNode if isinstance(event, yaml.SequenceStartEvent) else yaml.MappingNode
            tag = event.tag if event.tag not in (None, "!") else self.resolve(kind, None, event.implicit)
            node = kind(tag, [], event.start_mark, None, flow_style=event.flow_style)
        if event.anchor is not None:
            anchors[event.anchor] = node
        return node

    def _tagged_problem(self, node: yaml.ScalarNode) -> str | None:
        """Why the value of a scalar with an explicit tag (`!!float abc`) cannot be read as its tag says, or
        None. Checked while composing, where the field is known (constructing it later would say neither the
        field nor, for some tags, anything but a Python error)."""
        tag, value = node.tag, node.value
        what = _TAGGED_VALUES.get(tag)
        if what is None:
            return None
        written = f"{shown(value)} is not {what} (tag !!{tag.rsplit(':', 1)[-1]})"
        if tag in (_INT_TAG, _FLOAT_TAG) and ":" in value:
            return f"{written}: YAML 1.1 base-60 numbers (1:30) are not read; write the number in base 10"
        if tag == _INT_TAG:
            return None if _INTEGER.match(value.replace("_", "")) else written
        try:
            self.yaml_constructors[tag](self, node)
        except (ValueError, IndexError, KeyError, AttributeError, TypeError, OverflowError):
            return written
        return None

    def construct_yaml_int(self, node: yaml.ScalarNode) -> int:
        try:
            return super().construct_yaml_int(node)  # type: ignore[no-any-return]
        except ValueError:  # more than 4300 digits (Python's limit for reading integers)
            raise _LimitError(f"an integer of {len(node.value)} digits is too long to read", node.start_mark) from None

    @staticmethod
    def _add(parent: _Open, node: yaml.Node, size: int, stack: list[_Open]) -> None:
        parent.size += size
        if isinstance(parent.node, yaml.SequenceNode):
            parent.node.value.append(node)
        elif parent.key is None:
            if isinstance(node, yaml.ScalarNode) and node.tag != _MERGE_TAG:
                first = parent.keys.get((node.tag, node.value))
                if first is not None:
                    raise _LimitError(f"duplicate key {shown(node.value)} (first at line {first}); each key may "
                                      "appear once in a mapping", node.start_mark, _path(stack, node.value))
                parent.keys[(node.tag, node.value)] = node.start_mark.line + 1
            parent.key = node
        else:
            parent.node.value.append((parent.key, node))
            parent.key = None


def _path(stack: list[_Open], last: str | None = None) -> str | None:
    """Where in the document the stack is, as a field name (models[2].shapes[0])."""
    parts = []
    for entry in stack:
        if isinstance(entry.node, yaml.SequenceNode):
            parts.append(f"[{len(entry.node.value)}]")
        elif isinstance(entry.key, yaml.ScalarNode):
            parts.append(f".{entry.key.value[:SHOWN_CHARACTERS]}")
    if last is not None:
        parts.append(f".{last[:SHOWN_CHARACTERS]}")
    if len(parts) > 8:
        parts = [*parts[:4], "...", *parts[-2:]]
    text = "".join(parts).lstrip(".")
    return text or None


class _Loader(_BoundedComposer, _SafeLoader):  # type: ignore[valid-type,misc]
    """yaml's safe loader, the C one when available, with the bounded composer."""


class _PythonLoader(_BoundedComposer, yaml.SafeLoader):
    """yaml's pure-Python safe loader with the bounded composer: reads again what libyaml refused as nested
    too deep, to say where this module's limit is broken."""


class Dumper(_SafeDumper):  # type: ignore[valid-type,misc]
    """Quotes the strings `_Loader` would read as numbers (a model named 1e5 is written '1e5')."""


_EXPONENT_FLOAT = re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$")
for _first in "-+.0123456789":  # YAML 1.2 (and JSON) numbers with an exponent: 1e9, 2.5E-3
    for _resolving in (_Loader, _PythonLoader, Dumper):
        _resolving.add_implicit_resolver("tag:yaml.org,2002:float", _EXPONENT_FLOAT, [_first])
for _constructing in (_Loader, _PythonLoader):
    _constructing.add_constructor("tag:yaml.org,2002:int", _constructing.construct_yaml_int)


def load_document(text: str, source: str | None) -> Any:
    """The YAML document in `text`, read within the limits (WorldError naming the line otherwise)."""
    try:
        return _load(text)
    except _LimitError as error:
        line = error.problem_mark.line + 1 if error.problem_mark is not None else None
        raise WorldError(str(error.problem), source=source, line=line, field=error.path) from None
    except yaml.MarkedYAMLError as error:
        mark = error.problem_mark or error.context_mark
        line = mark.line + 1 if mark is not None else None
        problem = _clipped(error.problem or "invalid YAML")
        kind = "YAML syntax error" if isinstance(error, (yaml.scanner.ScannerError, yaml.parser.ParserError)) else (
            "YAML error")
        raise WorldError(f"{kind}: {problem}", source=source, line=line) from None
    except yaml.reader.ReaderError as error:
        code = error.character if isinstance(error.character, int) else ord(str(error.character)[:1] or "\0")
        raise WorldError(f"not a world file: the character U+{code:04X} at offset {error.position} is not allowed "
                         "in YAML text", source=source) from None
    except yaml.YAMLError as error:
        raise WorldError(f"YAML error: {_clipped(str(error))}", source=source) from None
    except (ValueError, OverflowError) as error:  # e.g. an integer of more than 4300 digits
        raise WorldError(f"unreadable value: {_clipped(str(error))}", source=source) from None


def _load(text: str) -> Any:
    try:
        return yaml.load(text, Loader=_Loader)
    except yaml.MarkedYAMLError as error:
        if isinstance(error, _LimitError) or "nesting depth" not in str(error.problem):
            raise
        refused = error
    # libyaml's own nesting limit (PyYAML 6.0.4 wheels) came first. The pure-Python parser (about 3 times
    # slower) reads the text up to where libyaml stopped, which holds this module's limit too, and says where.
    mark = refused.problem_mark
    try:
        yaml.load(text if mark is None else text[:mark.index + 1], Loader=_PythonLoader)
    except _LimitError:
        raise
    except yaml.YAMLError:
        pass
    raise _LimitError(f"lists and mappings nested more than {MAX_DEPTH} deep", mark)


def _clipped(text: str) -> str:
    first = text.strip().splitlines()[0] if text.strip() else text
    return first if len(first) <= 3 * SHOWN_CHARACTERS else f"{first[:3 * SHOWN_CHARACTERS - 3]}..."
