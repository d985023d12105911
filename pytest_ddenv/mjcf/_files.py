"""The files of an MJCF scene as text, before MuJoCo reads them: bounded, safe, and where each element is.

MuJoCo's own parser (tinyxml2) reads whatever it is given, so the scene is first read here with `defusedxml`
(DTDs, entity declarations and external references refused; `sdf._xml.parse_xml`), file by file through its
`<include file=...>` elements (relative to the main file's folder, as MuJoCo resolves them), within the limits
the SDF reader uses. What this gives the reader: the top-level bodies (name, file, line) in MuJoCo's order,
and which file holds an element MuJoCo names only by its tag and line.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

from pytest_ddenv.errors import WorldError, shown
from pytest_ddenv.sdf._xml import MAX_FILE_BYTES, Lines, local_name, parse_xml, read_limited

MAX_INCLUDES = 10_000
"""Most `<include>` elements read for one scene, at every depth."""
MAX_INCLUDE_DEPTH = 16
MAX_BODIES = 50_000
"""Most `<body>` elements in one scene, nested ones and those of included files counted."""
MAX_GEOMS = 50_000
MAX_NESTING = 64
"""Deepest nesting of bodies in bodies; deeper trees are refused before MuJoCo reads them."""

__all__ = ["MAX_BODIES", "MAX_FILE_BYTES", "MAX_GEOMS", "MAX_INCLUDES", "MAX_NESTING", "SceneFiles", "TopBody"]


@dataclass(frozen=True)
class TopBody:
    """A direct child `<body>` of a `<worldbody>`, where it is written."""

    name: str
    file: Path
    line: int


@dataclass
class SceneFiles:
    """The main file and every file it includes (at any depth), read and checked."""

    main: Path
    files: dict[Path, bytes] = field(default_factory=dict)
    """Every file of the scene (the main one first), by its resolved path, as bytes."""
    included_as: dict[Path, str] = field(default_factory=dict)
    """How each included file is named in its `<include file=...>` (MuJoCo looks it up by that name)."""
    bodies: list[TopBody] = field(default_factory=list)
    elements: dict[tuple[str, int], list[Path]] = field(default_factory=dict)
    """(tag, line) -> the files with an element of that tag starting on that line."""
    lines: Lines = field(default_factory=Lines)
    counts: dict[str, int] = field(default_factory=lambda: {"include": 0, "body": 0, "geom": 0})

    @classmethod
    def read(cls, main: Path, data: bytes | None = None) -> SceneFiles:
        """The scene whose main file is `main` (its bytes `data` when given: the file is not read)."""
        scene = cls(main)
        scene.add(main, read_limited(main, what="MJCF file") if data is None else data, depth=0)
        return scene

    def where(self, tag: str, line: int | None) -> Path:
        """The file of the `<tag>` element at `line` (MuJoCo's errors give no file): the only file with one
        there, else the main file."""
        found = self.elements.get((tag, line or 0), [])
        return found[0] if len(found) == 1 else self.main

    def first(self, tag: str) -> tuple[Path, int | None]:
        """The file and line of the first `<tag>` element (the main file, no line, when there is none)."""
        places = [(files[0], line) for (known, line), files in self.elements.items() if known == tag]
        return places[0] if places else (self.main, None)

    def add(self, path: Path, data: bytes, depth: int) -> None:
        source = str(path)
        root = parse_xml(data, source, self.lines)
        if local_name(root.tag) != "mujoco":
            raise WorldError(f"expected an MJCF file (its root element <mujoco>), got <{shown(root.tag)}>",
                             source=source, line=self.lines.of(root)[1], field=local_name(root.tag))
        self.files[path.resolve()] = data
        self.walk(root, path, depth)

    def walk(self, root: ET.Element, path: Path, depth: int) -> None:
        """Record the elements of one file and read the files it includes, in document order (MuJoCo splices an
        included file's content in place of its `<include>`, so the bodies come in that order)."""
        stack: list[tuple[ET.Element, int]] = [(root, 0)]  # (element, bodies around it)
        while stack:
            element, nesting = stack.pop()
            tag = local_name(element.tag)
            line = self.lines.of(element)[1] or 0
            self.elements.setdefault((tag, line), []).append(path)
            if tag in self.counts:
                self.counts[tag] += 1
                self.check_count(tag, path, line)
            if tag == "body":
                nesting += 1
                if nesting > MAX_NESTING:
                    raise WorldError(f"bodies nested more than {MAX_NESTING} deep; flatten the body tree",
                                     source=path, line=line, model=element.get("name"), field="body")
            if tag == "worldbody":
                for child in element:
                    if local_name(child.tag) == "body":
                        self.bodies.append(TopBody((child.get("name") or "").strip(), path,
                                                   self.lines.of(child)[1] or 0))
            if tag == "include":
                self.include(element, path, line, depth)
            stack.extend((child, nesting) for child in reversed(element))

    def check_count(self, tag: str, path: Path, line: int) -> None:
        limit = {"include": MAX_INCLUDES, "body": MAX_BODIES, "geom": MAX_GEOMS}[tag]
        if self.counts[tag] > limit:
            raise WorldError(f"more than {limit} <{tag}> elements in one scene; refusing to read it", source=path,
                             line=line, field=tag)

    def include(self, element: ET.Element, path: Path, line: int, depth: int) -> None:
        name = element.get("file") or ""
        if not name:
            raise WorldError("an <include> needs a file attribute", source=path, line=line, field="include/@file")
        if depth + 1 > MAX_INCLUDE_DEPTH:
            raise WorldError(f"includes nested more than {MAX_INCLUDE_DEPTH} deep (a cycle?) at {shown(name)}",
                             source=path, line=line, field="include/@file")
        target = Path(name) if Path(name).is_absolute() else self.main.parent / name
        target = target.resolve()
        if target in self.files:  # MuJoCo refuses a file included twice; so do we, with where
            raise WorldError(f"{shown(name)} is included more than once (or includes itself)", source=path,
                             line=line, field="include/@file")
        if not target.is_file():
            raise WorldError(f"included file not found: {shown(name)} (looked for {target}; MuJoCo resolves an "
                             "include relative to the main file's folder)", source=path, line=line,
                             field="include/@file")
        self.included_as[target] = name
        self.add(target, read_limited(target, what="MJCF file"), depth + 1)
