"""What a stage may not change: the structure of the world it simplifies.

A simplification that moves or resizes a model must keep how each pair of models stands to each other: two
models that share space still do, two that touch still touch, and two that are apart stay apart, with a gap
between them that stays narrower (or wider) than the robot. Two posts that form a 0.6 m gap, rounded to the
same place, are one pole; rounded to touching places, a wall; made thinner, a gap the robot fits through:
each a different world, whatever the failure does. Nor may the robot fail touching a model that the failing
runs of the world the stage started from never touched. The first rule is checked before simulating
(`keeps_structure`, a precondition: the candidate is refused and the reason logged), the second on each run
(`touching_only`: such a run is another failure, not the same one).

Pairs are compared on each shape's outline seen from above (the convex hull of its corners, rims or
vertices) where their height ranges meet: exact for boxes, upright cylinders and spheres, a little generous
for tilted or concave shapes.
"""

from __future__ import annotations

import functools
import itertools
import math
from collections.abc import Callable, Collection, Iterable, Mapping
from typing import Any

import numpy as np
import shapely

from pytest_ddenv.outcome import Outcome
from pytest_ddenv.reduce import ProbeObservation, events
from pytest_ddenv.reduce.types import Candidate, Precondition, Probe
from pytest_ddenv.world.files import resolve_mesh_path
from pytest_ddenv.world.geometry import FloatArray, box_corners, cylinder_extent_points
from pytest_ddenv.world.meshes import load_mesh
from pytest_ddenv.world.model import Model, Shape, World

AREA = 1e-4
"""Square metres two outlines must share (1 cm²) to overlap: models that only touch do not."""
HEIGHT = 1e-3
"""Metres two height ranges must share to overlap: a box resting on a slab does not."""
TOUCH = 0.02
"""Metres between two models below which they touch (no gap between them)."""

Outline = tuple[shapely.Polygon, float, float]
"""A shape seen from above (its convex outline) and its height range (low, high)."""


def _local_points(shape: Shape, source: str | None) -> FloatArray:
    """Points of `shape` in its own frame whose convex hull contains it."""
    if shape.kind == "box" and shape.size is not None:
        return box_corners(np.array(shape.size, dtype=float))
    if shape.kind in ("cylinder", "capsule") and shape.radius is not None and shape.length is not None:
        rims = cylinder_extent_points(shape.radius, shape.length)
        if shape.kind == "cylinder":
            return rims
        ends = cylinder_extent_points(shape.radius, shape.length + 2 * shape.radius)
        return np.vstack([rims, ends])
    if shape.kind == "sphere" and shape.radius is not None:
        return cylinder_extent_points(shape.radius, 2 * shape.radius)
    if shape.kind == "cone" and shape.radius is not None and shape.length is not None:  # its base rim and tip
        rim = cylinder_extent_points(shape.radius, shape.length)
        return np.vstack([rim[len(rim) // 2:], [[0.0, 0.0, shape.length / 2.0]]])
    if shape.kind == "polyline" and shape.points is not None and shape.height is not None:
        ring = np.asarray(shape.points, dtype=float)
        return np.vstack([np.column_stack([ring, np.zeros(len(ring))]),
                          np.column_stack([ring, np.full(len(ring), shape.height)])])
    if shape.kind == "heightmap" and shape.size is not None:
        size = np.array(shape.size, dtype=float)
        corners: FloatArray = box_corners(size) + np.array([0.0, 0.0, size[2] / 2.0])
        return corners
    mesh: Any = load_mesh(resolve_mesh_path(shape.mesh, source), shape.scale)
    return np.asarray(mesh.vertices, dtype=float)


@functools.lru_cache(maxsize=1024)
def outlines(model: Model, source: str | None) -> tuple[Outline, ...]:
    """Each shape of `model` in the world frame: its convex outline from above and its height range."""
    found: list[Outline] = []
    for shape in model.shapes:
        pose = model.pose.compose(shape.pose)
        points = pose.position + _local_points(shape, source) @ pose.rotation.T
        hull = shapely.MultiPoint([tuple(point) for point in points[:, :2]]).convex_hull
        polygon = hull if isinstance(hull, shapely.Polygon) else hull.buffer(1e-6)
        found.append((polygon, float(points[:, 2].min()), float(points[:, 2].max())))
    return tuple(found)


def clearance(first: Model, second: Model, source: str | None) -> float:
    """The gap (m) between two models seen from above, where their height ranges meet (inf: they never do);
    negative when they share space (more than `AREA`)."""
    gap = math.inf
    for (shape_a, low_a, high_a), (shape_b, low_b, high_b) in itertools.product(outlines(first, source),
                                                                               outlines(second, source)):
        if min(high_a, high_b) - max(low_a, low_b) <= HEIGHT:
            continue
        if shape_a.intersects(shape_b) and shape_a.intersection(shape_b).area > AREA:
            return -1.0
        gap = min(gap, float(shape_a.distance(shape_b)))
    return gap


def relation(gap: float, robot_width: float | None) -> str:
    """How two models `gap` apart stand to each other: "overlap", "touch", "apart" (no common height, or no
    robot width to compare with), "narrow" or "wide" (a gap narrower or wider than the robot)."""
    if gap < 0:
        return "overlap"
    if gap < TOUCH:
        return "touch"
    if robot_width is None or gap == math.inf:
        return "apart"
    return "narrow" if gap < robot_width else "wide"


def _described(kind: str, gap: float, robot_width: float | None, robot: str) -> str:
    if kind in ("narrow", "wide"):
        comparison = "narrower" if kind == "narrow" else "wider"
        return f"a {gap:.2f} m gap, {comparison} than {robot} ({robot_width or 0.0:.2f} m)"
    return {"overlap": "sharing space", "touch": "touching"}.get(kind, "apart")


def relations(world: World, robot_width: float | None, among: Collection[str] | None = None
              ) -> dict[tuple[str, str], tuple[str, float]]:
    """(relation, gap) of each pair of models of `world` (in world order); with `among`, only the pairs with
    at least one of those."""
    found: dict[tuple[str, str], tuple[str, float]] = {}
    models = world.models
    for index, first in enumerate(models):
        for second in models[index + 1:]:
            if among is not None and first.name not in among and second.name not in among:
                continue
            gap = clearance(first, second, world.source)
            found[(first.name, second.name)] = (relation(gap, robot_width), gap)
    return found


def nearest_gaps(world: World) -> dict[str, float]:
    """Each model's gap (m) to the nearest model it does not touch (inf: none): the coarsest grid its position
    or size may be rounded on without changing the gaps around it beyond recognition."""
    gaps = {name: math.inf for name in world.names}
    for (first, second), (_, gap) in relations(world, None).items():
        if TOUCH <= gap < math.inf:
            gaps[first], gaps[second] = min(gaps[first], gap), min(gaps[second], gap)
    return gaps


def keeps_structure(base: World, build: Callable[[Candidate], World], robot_width: float | None,
                    robot: str = "the robot") -> Precondition:
    """A precondition: refuse a candidate whose world (`build(candidate)`) changes how two models stand to each
    other (`relation`) from `base` (a different structure), saying which and how."""
    before_models = {model.name: model for model in base.models}
    before = relations(base, robot_width)

    def precondition(candidate: Candidate) -> str | None:
        world = build(candidate)
        changed = [model.name for model in world.models if before_models.get(model.name) != model]
        if not changed:
            return None
        for pair, (now, gap) in relations(world, robot_width, changed).items():
            was, old_gap = before.get(pair, (now, gap))
            if now != was:
                return (f"changes {pair[0]} and {pair[1]} from {_described(was, old_gap, robot_width, robot)} to "
                        f"{_described(now, gap, robot_width, robot)}: a different structure, not a simpler one")
        return None

    return precondition


def touched_at_failure(probes: Iterable[events.Probe], names: Collection[str]) -> frozenset[str]:
    """The models the robot touched when `names` (a world's models) failed the same way, by its probes in a
    run log."""
    key = frozenset(names)
    touched: set[str] = set()
    for probe in probes:
        if probe.result is Outcome.FAIL and frozenset(probe.candidate) == key and probe.signature is not None:
            touched.update(str(name) for name in probe.signature.get("touched", ()))
    return frozenset(touched)


def touching_only_wrap(wrap: Callable[[Probe], Probe], allowed: frozenset[str]) -> Callable[[Probe], Probe]:
    """A stage context's `wrap` that applies `touching_only` first."""
    return lambda probe: wrap(touching_only(probe, allowed))


def touching_only(probe: Probe, allowed: frozenset[str]) -> Probe:
    """`probe`, where a run that fails the same way touching a model outside `allowed` (the models the runs
    of the world the stage started from touched when they failed) is another failure: the robot is caught by
    something else. Nothing changes when `allowed` is empty (those runs touched no model)."""
    if not allowed:
        return probe

    def checked(candidate: Candidate, attempt: int) -> ProbeObservation:
        observed = probe(candidate, attempt)
        signature = observed.signature
        if observed.outcome is not Outcome.FAIL or not isinstance(signature, Mapping):
            return observed
        others = sorted(set(map(str, signature.get("touched", ()))) - allowed)
        if not others:
            return observed
        return ProbeObservation(Outcome.OTHER, trace=None, signature=signature, seed=observed.seed,
                           sim_time=observed.sim_time, wall_time=observed.wall_time,
                           detail=f"a different structure: the robot failed touching {', '.join(others)}, which "
                                  f"the failing runs it started from never touched ({', '.join(sorted(allowed))})")

    return checked
