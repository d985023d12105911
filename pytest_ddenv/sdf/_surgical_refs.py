"""What the kept part of a cut world still says about the cut models and about where its files are.

A world-level `<frame attached_to>`, a `<pose relative_to>` of a world-level element, or a world-level joint's
`<parent>`/`<child>` that names a removed model (or a frame inside it, `rack::link`) makes the cut file one
libsdformat refuses; relative file paths make it a file that opens only beside the original.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Collection, Iterable
from urllib.parse import urlparse

from pytest_ddenv.sdf._ddenv import DDENV_NS

PATH_TAGS = ("uri",)
"""Elements whose text is a file path or URI (meshes, heightmaps, material scripts, includes)."""


def removed_reference(kept: Iterable[ET.Element], removed: Collection[str]) -> str | None:
    """How one of the `kept` world-level elements refers to a removed model, or None when none does."""
    for element in kept:
        label = f"<{element.tag} name=\"{(element.get('name') or '').strip()}\">" if element.get("name") else (
            f"<{element.tag}>")
        attached = (element.get("attached_to") or "").strip()
        if _names_removed(attached, removed):
            return f"the world's {label} is attached_to the removed model {_top(attached)}"
        for pose in element.findall("pose"):
            relative = (pose.get("relative_to") or "").strip()
            if _names_removed(relative, removed):
                return f"the pose of the world's {label} is relative_to the removed model {_top(relative)}"
        if element.tag == "joint":
            for end in ("parent", "child"):
                frame = (element.findtext(end) or "").strip()
                if _names_removed(frame, removed):
                    return f"the world's {label} has the removed model {_top(frame)} as its <{end}>"
    return None


def _names_removed(frame: str, removed: Collection[str]) -> bool:
    return bool(frame) and _top(frame) in removed


def _top(frame: str) -> str:
    return frame.split("::", 1)[0]


def relative_paths(kept: Iterable[ET.Element]) -> list[str]:
    """The relative file paths in the `kept` elements (resolved by Gazebo and by us against the file's folder)."""
    found = []
    for element in kept:
        for inner in element.iter():
            texts = [inner.text or ""] if inner.tag in PATH_TAGS else []
            if inner.tag == f"{{{DDENV_NS}}}robot_description":
                texts.append(inner.get("urdf") or "")
            found += [text.strip() for text in texts if _is_relative(text.strip())]
    return found


def _is_relative(text: str) -> bool:
    if not text or text.startswith(("/", "~", "\\")):
        return False
    return not urlparse(text).scheme  # a Windows drive letter parses as a scheme: absolute too
