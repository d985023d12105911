"""SDF pose frames: the named frames of one scope (the world or one model) and how they resolve.

As in libsdformat (SDF 1.7+ frame semantics; the `frame` attribute of 1.5/1.6 is read as `relative_to`):
a pose is relative to the frame its `relative_to` names, else to the entry's default frame: the scope's own
frame for links, nested models and models, the `attached_to` frame for `<frame>`s, the child link for joints.
Names may be scoped into nested models (`inner::link`, `inner::__model__`).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Collection
from dataclasses import dataclass

from pytest_ddenv.errors import shown
from pytest_ddenv.sdf import _poses
from pytest_ddenv.sdf._values import Values
from pytest_ddenv.world import Pose

MAX_CHAIN = 100
"""Longest chain of frames, each relative to the next, that is resolved (longer: an error, not a RecursionError)."""


@dataclass
class Frame:
    """One named frame: `pose` relative to `relative_to` (or to `default` when that is empty)."""

    pose: Pose
    relative_to: str
    element: ET.Element
    default: str = ""
    placement: str = ""  # a model's placement frame: its pose places that frame, not the model frame


class Frames:
    """The named frames of one scope, each resolvable to a pose in the scope's own frame."""

    def __init__(self, values: Values, model: str | None, roots: Collection[str]) -> None:
        self.values = values
        self.model = model
        self.roots = frozenset(roots) | {""}
        self.entries: dict[str, Frame] = {}
        self.scopes: dict[str, Frames] = {}
        self._cache: dict[str, Pose] = {}

    def add(self, name: str, frame: Frame, scope: Frames | None = None) -> None:
        if name in self.entries:
            what = f"model '{self.model}'" if self.model else "the world"
            raise self.values.error(f"two frames, links, joints or models named '{name}' in {what}", frame.element,
                                    model=self.model, field="name")
        self.entries[name] = frame
        if scope is not None:
            self.scopes[name] = scope

    def resolve(self, name: str, element: ET.Element, visiting: tuple[str, ...] = ()) -> Pose:
        """The pose of frame `name` in this scope's own frame."""
        if name in self._cache:
            return self._cache[name]
        if name in self.entries:
            result = self._entry(name, visiting)
        elif name in self.roots:
            result = _poses.IDENTITY
        elif "::" in name and name.split("::", 1)[0] in self.scopes:
            head, rest = name.split("::", 1)
            inner = _poses.IDENTITY if rest == "__model__" else self.scopes[head].resolve(rest, element)
            result = compose(self.resolve(head, element, visiting), inner)
        else:
            known = ", ".join(sorted(n for n in self.entries if n and not n.startswith("_merged__"))) or "none"
            raise self.values.error(f"unknown frame {shown(name)} in relative_to/frame (known frames: {known})",
                                    element,
                                    model=self.model, field="pose/@relative_to")
        self._cache[name] = result
        return result

    def _entry(self, name: str, visiting: tuple[str, ...]) -> Pose:
        if name in visiting:
            chain = " -> ".join((*visiting, name))
            raise self.values.error(f"pose frames form a cycle: {chain}", self.entries[name].element,
                                    model=self.model, field="pose/@relative_to")
        frame = self.entries[name]
        if len(visiting) >= MAX_CHAIN:
            raise self.values.error(f"pose frames chained more than {MAX_CHAIN} deep (each relative to the next)",
                                    frame.element, model=self.model, field="pose/@relative_to")
        parent_name = frame.relative_to or frame.default
        parent = self.resolve(parent_name, frame.element, (*visiting, name)) if parent_name else _poses.IDENTITY
        result = compose(parent, frame.pose)
        if frame.placement:
            scope = self.scopes.get(name)
            if scope is None:  # pragma: no cover - placement frames are only set on models
                raise self.values.error(f"placement frame {shown(frame.placement)} of a frame that is not a model",
                                        frame.element, model=self.model, field="placement_frame")
            placed = scope.resolve(frame.placement, frame.element)
            result = compose(result, _poses.inverse(placed))
        return result


def compose(parent: Pose, child: Pose) -> Pose:
    """parent ∘ child, exact when either is the identity."""
    if parent == _poses.IDENTITY:
        return child
    return parent.compose(child)
