"""SDF pose frames: the named frames of one scope (the world or one model) and how they resolve.

As in libsdformat (SDF 1.7+ frame semantics; the `frame` attribute of 1.5/1.6 is read as `relative_to`):
a pose is relative to the frame its `relative_to` names, else to the entry's default frame: the scope's own
frame for links, nested models and models, the `attached_to` frame for `<frame>`s, the child link for joints.
Names may be scoped into nested models (`inner::link`, `inner::__model__`).

As libsdformat does, every name a scope's entries give (a pose's `relative_to`, a frame's `attached_to`, a
joint's `<parent>` and `<child>`) must name a frame of the scope, whether or not a pose is resolved through it
(`Frames.check`). Before SDF 1.7 a link, joint or frame may share its name with another kind of entry: as
libsdformat does, the later kind is renamed (`NAME_link`, `NAME_joint`, `NAME_frame`, then `NAME_joint0`, ...)
when the entries are added in libsdformat's order (models, links, joints, frames).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Collection
from dataclasses import dataclass

from pytest_ddenv.errors import shown
from pytest_ddenv.sdf import _poses
from pytest_ddenv.sdf._values import Values
from pytest_ddenv.world.model import Pose

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
    kind: str = ""  # "link", "frame", "joint", "model": what `check` checks
    parent: str = ""  # a joint's <parent>


class Frames:
    """The named frames of one scope, each resolvable to a pose in the scope's own frame."""

    def __init__(self, values: Values, model: str | None, roots: Collection[str], *, legacy: bool = False) -> None:
        self.values = values
        self.model = model
        self.legacy = legacy  # SDF before 1.7: a name shared by two kinds of entry renames the later one
        self.roots = frozenset(roots) | {""}
        self.entries: dict[str, Frame] = {}
        self.scopes: dict[str, Frames] = {}
        self._cache: dict[str, Pose] = {}

    def add(self, name: str, frame: Frame, scope: Frames | None = None) -> str:
        """Add the frame `name`; returns the name it has (renamed as libsdformat renames before SDF 1.7)."""
        if name in self.entries:
            if self.legacy and frame.kind in ("link", "joint", "frame") and self.entries[name].kind != frame.kind:
                renamed, number = f"{name}_{frame.kind}", 0
                while renamed in self.entries:
                    renamed, number = f"{name}_{frame.kind}{number}", number + 1
                name = renamed
            else:
                what = f"model '{self.model}'" if self.model else "the world"
                raise self.values.error(f"two frames, links, joints or models named '{name}' in {what}",
                                        frame.element, model=self.model, field="name")
        self.entries[name] = frame
        if scope is not None:
            self.scopes[name] = scope
        return name

    def exists(self, name: str, *, roots: bool = True) -> bool:
        """Whether `name` is a frame of this scope (`roots`: its own frame names, `__model__` or `world`, too)."""
        if name in self.entries or (roots and name in self.roots):
            return True
        head, scoped, rest = name.partition("::")
        return bool(scoped) and head in self.scopes and (rest == "__model__" or self.scopes[head].exists(rest))

    def known(self, name: str = "") -> str:
        """The frame names of this scope, or of the nested scope a scoped `name` reaches (`a::b::x`: a::b's)."""
        scope, prefix = self, ""
        head, scoped, rest = name.partition("::")
        while scoped and head in scope.scopes:
            scope, prefix = scope.scopes[head], f"{prefix}{head}::"
            head, scoped, rest = rest.partition("::")
        names = sorted(f"{prefix}{n}" for n in scope.entries if n and not n.startswith("_merged__"))
        return ", ".join(names) or "none"

    def check(self) -> None:
        """Refuse, as libsdformat does, a `relative_to`, `attached_to`, joint `<parent>` or `<child>` naming no
        frame of this scope (in file order)."""
        scope = f"model '{self.model}'" if self.model else "the world"
        kinds = "link, frame, joint or nested model" if self.model else "model or frame"
        for name, frame in self.entries.items():
            owner = f"{frame.kind or 'element'} {shown(name)}"
            pose = frame.element.find("pose")
            if frame.relative_to and not self.exists(frame.relative_to):
                self.missing(frame.relative_to, f"the relative_to of {owner}", pose if pose is not None else
                             frame.element, f"{frame.kind}/pose/@relative_to", scope, kinds)
            if frame.kind == "frame" and frame.default and not self.exists(frame.default):
                self.missing(frame.default, f"the attached_to of {owner}", frame.element, "frame/@attached_to",
                             scope, kinds)
            if frame.kind == "joint":
                self.joint(name, frame, scope, kinds)

    def joint(self, name: str, frame: Frame, scope: str, kinds: str) -> None:
        for tag, value in (("parent", frame.parent), ("child", frame.default)):
            element = frame.element.find(tag)
            if element is None or not value:
                raise self.values.error(f"joint {shown(name)} needs a <{tag}> naming a {kinds}",
                                        frame.element if element is None else element, model=self.model,
                                        field=f"joint/{tag}")
            if not (self.exists(value, roots=False) or (tag == "parent" and value == "world")):
                self.missing(value, f"the <{tag}> of joint {shown(name)}", element, f"joint/{tag}", scope, kinds)
        if frame.parent == frame.default:
            raise self.values.error(f"joint {shown(name)} has the same <parent> and <child> ({shown(frame.parent)}); "
                                    "they must be different frames", frame.element.find("child"), model=self.model,
                                    field="joint/child")

    def missing(self, name: str, what: str, element: ET.Element | None, field: str, scope: str, kinds: str) -> None:
        raise self.values.error(f"unknown frame {shown(name)} in {what}: not a {kinds} of {scope} (there are: "
                                f"{self.known(name)})", element, model=self.model, field=field)

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
            raise self.values.error(f"unknown frame {shown(name)} in relative_to/frame (known frames: {self.known()})",
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
