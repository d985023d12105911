"""Reading SDF values (numbers, booleans, poses) with errors that name the file, line, model and field."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Sequence

from pytest_ddenv.errors import WorldError, shown
from pytest_ddenv.sdf import _poses
from pytest_ddenv.sdf._xml import Lines
from pytest_ddenv.world.model import Pose

SKIP_HINT = (
    "to load the world without the models that hold it, pass --skip-unsupported (ddenv) or "
    "skip_unsupported=True (the ddenv marker, World.load or load_sdf)"
)


class UnsupportedSdfError(WorldError):
    """An SDF element pytest-ddenv cannot simulate. `skip_unsupported=True` drops the model that holds it.

    `element` is the element's tag (e.g. "actor", "submesh") and `detail` says why, without the hint.
    """

    def __init__(
        self, element: str, detail: str, *, source: str | None = None, model: str | None = None,
        field: str | None = None, line: int | None = None,
    ) -> None:
        self.element = element
        self.detail = detail
        super().__init__(f"{self.summary}; {SKIP_HINT}", source=source, model=model, field=field, line=line)

    @property
    def summary(self) -> str:
        """What is wrong, without the hint (the line of a dropped model in `World.notes`)."""
        return f"unsupported <{self.element}>: {self.detail}"

    @property
    def where(self) -> str:
        """file:line of the element (or the file alone)."""
        if self.source is None:
            return f"line {self.line}" if self.line is not None else ""
        return self.source if self.line is None else f"{self.source}:{self.line}"


class UnavailableSdfError(UnsupportedSdfError):
    """What a model needs cannot be had here: a Gazebo Fuel model not downloaded, a mesh or heightmap file missing
    or unreadable. Skipped as an unsupported element is (`skip_unsupported=True` drops the model)."""

    @property
    def summary(self) -> str:
        return self.detail


class Values:
    """Typed reading of element text; every error names the file and line of the element it is about."""

    def __init__(self, lines: Lines, source: str | None) -> None:
        self.lines = lines
        self.source = source

    def error(
        self, message: str, element: ET.Element | None = None, *, model: str | None = None, field: str | None = None,
        kind: type[WorldError] = WorldError,
    ) -> WorldError:
        source, line = self.lines.of(element) if element is not None else (None, None)
        return kind(message, source=source or self.source, model=model, field=field, line=line)

    def unsupported(
        self, tag: str, detail: str, element: ET.Element | None, *, model: str | None = None, field: str | None = None
    ) -> UnsupportedSdfError:
        source, line = self.lines.of(element) if element is not None else (None, None)
        return UnsupportedSdfError(tag, detail, source=source or self.source, model=model, field=field, line=line)

    def unavailable(
        self, tag: str, detail: str, element: ET.Element | None, *, model: str | None = None, field: str | None = None
    ) -> UnavailableSdfError:
        source, line = self.lines.of(element) if element is not None else (None, None)
        return UnavailableSdfError(tag, detail, source=source or self.source, model=model, field=field, line=line)

    def floats(self, element: ET.Element, count: Sequence[int], where: str, model: str | None) -> list[float]:
        text = (element.text or "").split()
        try:
            values = [float(item) for item in text]
        except ValueError:
            raise self.error(f"expected numbers, got {shown(element.text)}", element, model=model,
                             field=where) from None
        if len(values) not in count:
            expected = " or ".join(str(c) for c in count)
            raise self.error(f"expected {expected} numbers, got {len(values)}", element, model=model, field=where)
        if not all(math.isfinite(v) for v in values):
            raise self.error(f"expected finite numbers, got {shown(element.text)}", element, model=model,
                             field=where)
        return values

    def number(self, element: ET.Element, where: str, model: str | None, *, positive: bool = False) -> float:
        value = self.floats(element, (1,), where, model)[0]
        if positive and value <= 0:
            raise self.error(f"expected a positive number, got {value}", element, model=model, field=where)
        return value

    def child_number(
        self, parent: ET.Element, tag: str, where: str, model: str | None, *, positive: bool = False,
        default: float | None = None,
    ) -> float | None:
        """The number in `parent`'s child `tag`, or `default` when there is no such child (as libsdformat fills
        a missing element with its default from the SDF specification)."""
        child = parent.find(tag)
        return default if child is None else self.number(child, f"{where}/{tag}", model, positive=positive)

    def child_floats(
        self, parent: ET.Element, tag: str, count: int, where: str, model: str | None, default: Sequence[float]
    ) -> list[float]:
        child = parent.find(tag)
        return list(default) if child is None else self.floats(child, (count,), f"{where}/{tag}", model)

    def boolean(self, element: ET.Element, where: str, model: str | None) -> bool:
        text = (element.text or "").strip().lower()
        if text in ("1", "true"):
            return True
        if text in ("0", "false"):
            return False
        raise self.error(f"expected true/false or 1/0, got {shown(element.text)}", element, model=model, field=where)

    def child_boolean(self, parent: ET.Element, tag: str, where: str, model: str | None) -> bool | None:
        child = parent.find(tag)
        return None if child is None else self.boolean(child, f"{where}/{tag}" if where else tag, model)

    def pose(self, parent: ET.Element, where: str, model: str | None) -> tuple[Pose, str]:
        """The `<pose>` child of `parent` and the frame it is relative to ('' = the default frame).

        `relative_to` (SDF 1.7+) or `frame` (SDF 1.5/1.6, which libsdformat converts to `relative_to`).
        """
        element = parent.find("pose")
        if element is None:
            return _poses.IDENTITY, ""
        relative_to = (element.get("relative_to") or element.get("frame") or "").strip()
        field_name = f"{where}/pose" if where else "pose"
        if not (element.text or "").strip():
            return _poses.IDENTITY, relative_to
        if element.get("rotation_format", "euler_rpy").strip() == "quat_xyzw":
            values = self.floats(element, (7,), field_name, model)
            try:
                return _poses.from_quaternion(*values), relative_to
            except ValueError as error:
                raise self.error(str(error), element, model=model, field=field_name) from None
        values = self.floats(element, (6,), field_name, model)
        if element.get("degrees", "false").strip().lower() in ("true", "1"):
            values[3:] = [math.radians(v) for v in values[3:]]
        return Pose(*values), relative_to
