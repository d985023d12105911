"""Bodies to place: drawn primitives and users' templates at the origin, with their physics and their names."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass

from hypothesis import strategies as st

from pytest_ddenv.errors import shown
from pytest_ddenv.strategies._arguments import (
    _checked_flag,
    _checked_kinds,
    _checked_range,
    _checked_static,
    _fail,
    _milli,
)
from pytest_ddenv.strategies._defaults import MILLI, PrimitiveKind
from pytest_ddenv.world.files import resolve_relative
from pytest_ddenv.world.limits import MAX_NAME_LENGTH, name_problem
from pytest_ddenv.world.model import Model, Pose, Shape, World


@dataclass(frozen=True)
class _Primitives:
    """How primitive models are drawn (checked arguments, lengths and masses in thousandths)."""

    kinds: tuple[PrimitiveKind, ...]
    size: tuple[int, int]
    mass: tuple[int, int]
    friction: tuple[int, int]
    static: bool | None
    yaw: bool

    @classmethod
    def checked(cls, function: str, kinds: object, size: object, mass: object, friction: object, static: object,
                yaw: object) -> _Primitives:
        turns = _checked_flag(function, "yaw", yaw)
        return cls(
            kinds=_checked_kinds(function, kinds),
            size=_milli(function, "size", _checked_range(function, "size", size)),
            mass=_milli(function, "mass", _checked_range(function, "mass", mass)),
            friction=_milli(function, "friction", _checked_range(function, "friction", friction,
                                                                 low_included=True)),
            static=_checked_static(function, static),
            yaw=turns,
        )

    def widest(self) -> float:
        """The widest footprint (m, along x or y) a drawn primitive can have."""
        if not self.kinds:
            return 0.0
        largest = self.size[1] / MILLI
        return largest * math.sqrt(2.0) if "box" in self.kinds and self.yaw else largest


@dataclass(frozen=True)
class _Body:
    """A model at the origin: its footprint centred on (0, 0), its lowest point at z = 0, heading 0.

    `half` is its footprint's half extents (x, y) at heading 0; `top` the radius of the largest disc on its
    flat top (0 when it has none: a sphere or a template); `height` its height.
    """

    model: Model
    half: tuple[float, float]
    height: float
    top: float = 0.0

    def widest(self, turns: bool) -> float:
        """The widest its footprint gets along x or y (m): at any heading when it `turns`."""
        return 2.0 * (math.hypot(*self.half) if turns else max(self.half))

    def half_at(self, yaw: float) -> tuple[float, float]:
        """Half extents of the footprint's axis-aligned bounds at heading `yaw` (exact for boxes, and for
        any body an outer bound: the bounds of its turned bounds)."""
        c, s = abs(math.cos(yaw)), abs(math.sin(yaw))
        hx, hy = self.half
        return hx * c + hy * s, hx * s + hy * c

    def placed(self, name: str, x: float, y: float, z: float, yaw: float) -> Model:
        """The model named `name` turned by `yaw`, its footprint centred on (x, y), its lowest point at z."""
        pose = self.model.pose
        if pose.roll == 0.0 and pose.pitch == 0.0 and pose.x == 0.0 and pose.y == 0.0:
            moved = Pose(x, y, round(z + pose.z, 9), 0.0, 0.0, pose.yaw + yaw)  # 0.3, not 0.30000000000000004
        else:
            moved = Pose(x, y, z, 0.0, 0.0, yaw).compose(pose)
        return dataclasses.replace(self.model, name=name, pose=moved)


def _template_body(template: Model, source: str | None) -> _Body:
    """A user's model as a body: centred on its footprint, resting on z = 0 (mesh paths made absolute)."""
    shapes = tuple(
        dataclasses.replace(shape, mesh=str(resolve_relative(shape.mesh, source).resolve()))
        if shape.mesh is not None and source is not None else shape
        for shape in template.shapes
    )
    model = dataclasses.replace(template, shapes=shapes)
    low, high = (tuple(float(v) for v in corner) for corner in World(models=(model,)).bounds(model.name))
    centre_x, centre_y = (low[0] + high[0]) / 2.0, (low[1] + high[1]) / 2.0
    pose = template.pose
    model = dataclasses.replace(model, pose=Pose(pose.x - centre_x, pose.y - centre_y, pose.z - low[2],
                                                 pose.roll, pose.pitch, pose.yaw))
    return _Body(model, half=((high[0] - low[0]) / 2.0, (high[1] - low[1]) / 2.0), height=high[2] - low[2])


def _checked_templates(function: str, templates: object, argument: str = "templates") -> tuple[_Body, ...]:
    """The templates (Models, or a World's models with their mesh paths made absolute) as bodies."""
    if templates is None:
        return ()
    source = None
    if isinstance(templates, World):
        source, templates = templates.source, templates.models
    if isinstance(templates, Model):
        templates = (templates,)
    if not isinstance(templates, (tuple, list)) or not all(isinstance(t, Model) for t in templates):
        raise _fail(function, argument, f"expected a World or a sequence of Models, got {shown(templates)}")
    bodies = []
    for template in templates:
        problem = name_problem(template.name)
        if problem is not None:
            raise _fail(function, argument, f"model {shown(template.name)}: {problem}")
        bodies.append(_template_body(template, source))
    return tuple(bodies)


def _primitive(kind: PrimitiveKind, sizes: Sequence[int]) -> _Body:
    """A primitive body from its sizes in millimetres: box (x, y, z), cylinder (diameter, length), sphere
    (diameter)."""
    if kind == "box":
        sx, sy, sz = (size / MILLI for size in sizes)
        model = Model(kind, (Shape("box", size=(sx, sy, sz)),), pose=Pose(0.0, 0.0, sz / 2.0))
        return _Body(model, half=(sx / 2.0, sy / 2.0), height=sz, top=min(sx, sy) / 2.0)
    diameter = sizes[0] / MILLI
    if kind == "cylinder":
        length = sizes[1] / MILLI
        model = Model(kind, (Shape("cylinder", radius=diameter / 2.0, length=length),),
                      pose=Pose(0.0, 0.0, length / 2.0))
        return _Body(model, half=(diameter / 2.0, diameter / 2.0), height=length, top=diameter / 2.0)
    model = Model(kind, (Shape("sphere", radius=diameter / 2.0),), pose=Pose(0.0, 0.0, diameter / 2.0))
    return _Body(model, half=(diameter / 2.0, diameter / 2.0), height=diameter)


SIZES = {"box": 3, "cylinder": 2, "sphere": 1}
"""How many sizes each primitive kind has."""


ACROSS = {"box": 2, "cylinder": 1, "sphere": 1}
"""How many of them are across its footprint (the first ones)."""


def _draw_sizes(draw: st.DrawFn, spec: _Primitives, kind: PrimitiveKind) -> tuple[int, ...]:
    return tuple(draw(st.integers(*spec.size)) for _ in range(SIZES[kind]))


@dataclass(frozen=True)
class _Physics:
    """Static, or dynamic with a mass (kg); the friction coefficient (mu = mu2)."""

    dynamic: bool
    mass: float | None
    mu: float

    def of(self, body: _Body) -> _Body:
        model = dataclasses.replace(body.model, static=not self.dynamic, mass=self.mass, mu=self.mu, mu2=self.mu)
        return dataclasses.replace(body, model=model)


def _draw_physics(draw: st.DrawFn, spec: _Primitives) -> _Physics:
    """Static or dynamic (shrinks to static), a mass when dynamic, a friction coefficient. The mass is drawn
    even for a static model unless all are static, so that turning one dynamic moves no other value."""
    dynamic = (not spec.static) if spec.static is not None else draw(st.booleans())
    mass = draw(st.integers(*spec.mass)) / MILLI if spec.static is not True else None
    return _Physics(dynamic, mass if dynamic else None, draw(st.integers(*spec.friction)) / MILLI)


def _name(base: str, index: int) -> str:
    """`base_index`, unique since the index is (the part after the last underscore is the index)."""
    suffix = f"_{index}"
    return base[:MAX_NAME_LENGTH - len(suffix)] + suffix
