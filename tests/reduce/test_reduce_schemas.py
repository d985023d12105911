"""Every partition and priority schema on worlds of 1..200 elements, coincident positions, empty traces."""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pytest_ddenv.errors import ReductionError
from pytest_ddenv.reduce import PARTITIONS, PRIORITIES, Context, Trace, reduce
from pytest_ddenv.reduce.context import Verdict
from pytest_ddenv.reduce.partition import (
    LearnerPartition,
    ModelToModelPartition,
    TimeSegmentPartition,
    TrajectorySegmentPartition,
    make_partitioner,
)
from pytest_ddenv.reduce.priority import make_prioritizer

from .conftest import PointGeometry, SetOracle, line_geometry, line_trace, names

LAYOUTS = ["spread", "coincident", "two-spots", "none"]
TRACES = ["line", "empty", "none", "single-sample"]


def layout_geometry(elements: tuple[str, ...], layout: str) -> PointGeometry | None:
    if layout == "none":
        return None
    if layout == "two-spots":
        return PointGeometry({name: (float(i % 2) * 5.0, 0.0, 0.0) for i, name in enumerate(elements)})
    return line_geometry(elements, coincident=layout == "coincident")


def trace_of(kind: str, size: int) -> Trace | None:
    if kind == "none":
        return None
    if kind == "empty":
        return Trace.empty()
    if kind == "single-sample":
        return Trace(times=[0.0], positions=[[0.0, 0.0, 0.0]], yaw_rates=[0.0])
    return line_trace(float(size), sensed={"m0003": 2.0, "m0001": 4.0})


@pytest.mark.parametrize("partition", PARTITIONS)
@given(
    size=st.integers(1, 200),
    layout=st.sampled_from(LAYOUTS),
    trace=st.sampled_from(TRACES),
    priority=st.sampled_from(PRIORITIES),
    data=st.data(),
)
@settings(max_examples=12, deadline=None)
def test_every_schema_works_on_any_world(
    partition: str, size: int, layout: str, trace: str, priority: str, data: st.DataObject
) -> None:
    elements = names(size)
    culprits = frozenset(data.draw(st.sets(st.sampled_from(elements), min_size=1, max_size=3)))
    reference = trace_of(trace, size)
    result = reduce(
        elements,
        SetOracle(culprits, trace=reference),
        geometry=layout_geometry(elements, layout),
        reference=reference,
        partition=partition,
        priority=priority,
        deflake=0,
        failure_rate_runs=1,
    )
    assert set(result.minimal) == culprits
    assert result.one_minimal


@pytest.mark.parametrize("partition", PARTITIONS)
@pytest.mark.parametrize("layout", LAYOUTS)
@pytest.mark.parametrize("trace", TRACES)
@pytest.mark.parametrize("size", [1, 2, 3, 7, 40, 200])
def test_partitions_are_exact(partition: str, layout: str, trace: str, size: int) -> None:
    elements = names(size)
    context = Context(elements, geometry=layout_geometry(elements, layout), trace=trace_of(trace, size))
    context.history.extend([Verdict(frozenset(elements), True), Verdict(frozenset(elements[:1]), False)])
    schema = make_partitioner(partition)
    for n in sorted({1, 2, 3, 5, size, size + 3}):
        parts = schema(elements, n, context)
        assert len(parts) == min(n, size)
        assert all(parts)
        assert sorted(itertools.chain.from_iterable(parts)) == list(elements)
        assert all(part == tuple(sorted(part)) for part in parts), "parts keep the original order"


@pytest.mark.parametrize("priority", PRIORITIES)
@pytest.mark.parametrize("layout", LAYOUTS)
@pytest.mark.parametrize("trace", TRACES)
def test_priorities_are_permutations(priority: str, layout: str, trace: str) -> None:
    elements = names(9)
    context = Context(elements, geometry=layout_geometry(elements, layout), trace=trace_of(trace, 9), seed=3)
    parts = [elements[0:2], elements[2:5], elements[5:6], elements[6:9]]
    ordered = make_prioritizer(priority)(parts, context, 0)
    assert sorted(ordered) == sorted(parts)
    assert ordered == make_prioritizer(priority)(parts, context, 0), "same inputs, same order"


def test_model2model_clusters_by_position() -> None:
    elements = names(6)
    geometry = PointGeometry({name: ((0.0 if i < 3 else 50.0) + i * 0.1, 0.0, 0.0) for i, name in enumerate(elements)})
    parts = ModelToModelPartition()(elements, 2, Context(elements, geometry=geometry))
    assert parts == [elements[:3], elements[3:]]


def test_model2model_with_fewer_distinct_positions_than_parts() -> None:
    elements = names(6)
    geometry = PointGeometry({name: (0.0 if i % 2 else 9.0, 0.0, 0.0) for i, name in enumerate(elements)})
    parts = ModelToModelPartition()(elements, 4, Context(elements, geometry=geometry))
    assert len(parts) == 4
    # coincident elements were split only after the two distinct spots were separated
    assert all(len({i % 2 for i, name in enumerate(elements) if name in part}) == 1 for part in parts)


def test_timeseg_assigns_each_element_to_its_closest_segment() -> None:
    elements = ("late", "early")
    geometry = PointGeometry({"early": (1.0, 1.0, 0.0), "late": (9.0, 1.0, 0.0)})
    context = Context(elements, geometry=geometry, trace=line_trace(10.0))
    assert TimeSegmentPartition()(elements, 2, context) == [("late",), ("early",)]
    # the first part in time comes first once ordered by the robot's path
    ordered = make_prioritizer("min-trajectory-proximal")([("late",), ("early",)], context, 0)
    assert len(ordered) == 2


def test_trajectoryseg_cuts_where_the_yaw_rate_changes() -> None:
    times = np.linspace(0.0, 10.0, 101)
    yaw = np.where(times >= 7.0, 1.0, 0.0)
    cuts = TrajectorySegmentPartition().cuts(times, yaw, 2)
    assert cuts.tolist() == [7.0]
    straight = TrajectorySegmentPartition().cuts(times, np.zeros_like(times), 3)
    assert np.allclose(straight, [10 / 3, 20 / 3]), "a straight run is cut in equal time"
    many = TrajectorySegmentPartition().cuts(times, yaw, 4)
    assert 7.0 in many.tolist() and len(many) == 3


def test_learner_groups_the_elements_the_failure_needs() -> None:
    elements = names(8)
    context = Context(elements)
    culprits = {"m0002", "m0005"}
    rng = np.random.default_rng(0)
    for _ in range(30):
        members = frozenset(name for name in elements if rng.random() < 0.5)
        context.history.append(Verdict(members, culprits <= members))
    context.history.append(Verdict(frozenset(elements), True))
    parts = LearnerPartition()(elements, 4, context)
    assert any(culprits <= set(part) for part in parts)


def test_learner_falls_back_to_model2model_without_both_labels() -> None:
    elements = names(6)
    geometry = PointGeometry({name: ((0.0 if i < 3 else 50.0) + i * 0.1, 0.0, 0.0) for i, name in enumerate(elements)})
    context = Context(elements, geometry=geometry)
    context.history.append(Verdict(frozenset(elements), True))
    assert LearnerPartition()(elements, 2, context) == ModelToModelPartition()(elements, 2, context)


def test_proximity_priorities_use_surfaces_not_centroids() -> None:
    elements = ("big", "small")

    # "big" is a huge ball whose centre is far from the failure but whose surface touches it
    class Balls(PointGeometry):
        def distances(self, points: np.ndarray, names: Any) -> np.ndarray:
            centres = self.centroids(names)
            radii = np.array([10.0 if name == "big" else 0.1 for name in names])
            gaps = np.linalg.norm(points[:, None, :] - centres[None], axis=2)
            return np.maximum(gaps - radii, 0.0)

    geometry = Balls({"big": (11.0, 0.0, 0.0), "small": (3.0, 0.0, 0.0)})
    trace = Trace(
        times=[0.0, 1.0],
        positions=[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]],
        yaw_rates=[0.0, 0.0],
        failure_position=[1.0, 0.0, 0.0],
    )
    context = Context(elements, geometry=geometry, trace=trace)
    for priority in ("failure-proximal", "min-trajectory-proximal", "avg-trajectory-proximal"):
        assert make_prioritizer(priority)([("small",), ("big",)], context, 0)[0] == ("big",), priority


def test_timestep_priority_orders_by_first_sensed() -> None:
    elements = names(4)
    trace = line_trace(4.0, sensed={"m0003": 1.0, "m0001": 2.0})
    context = Context(elements, trace=trace)
    parts = [("m0000",), ("m0001",), ("m0002",), ("m0003",)]
    assert make_prioritizer("timestep")(parts, context, 0) == [("m0003",), ("m0001",), ("m0000",), ("m0002",)]


def test_random_priority_is_seeded() -> None:
    elements = names(12)
    parts = [elements[i : i + 2] for i in range(0, 12, 2)]
    first = make_prioritizer("random")(parts, Context(elements, seed=1), 0)
    assert first == make_prioritizer("random")(parts, Context(elements, seed=1), 0)
    others = {tuple(make_prioritizer("random")(parts, Context(elements, seed=s), 0)) for s in range(8)}
    assert len(others) > 1


def test_paper_aliases_are_accepted() -> None:
    assert make_prioritizer("avg-trajectory").name == "avg-trajectory-proximal"
    assert make_prioritizer("crash-proximal").name == "failure-proximal"
    with pytest.raises(ReductionError, match="valid choices: random, sequential"):
        make_prioritizer("closest")
    with pytest.raises(ReductionError, match="valid choices: model2model, timeseg"):
        make_partitioner("kmeans")


def test_bad_geometry_is_reported() -> None:
    class Broken:
        def centroids(self, names: Any) -> np.ndarray:
            return np.zeros((1, 2))

        def distances(self, points: np.ndarray, names: Any) -> np.ndarray:
            return np.zeros((len(points), len(names)))

    with pytest.raises(ReductionError, match=r"centroids\(\) must return"):
        reduce(names(3), SetOracle(frozenset({"m0001"})), geometry=Broken(), deflake=0)
