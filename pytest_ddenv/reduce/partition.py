"""Partition schemas: split the current world into n parts (Table I of the paper, plus `even`).

Every schema returns exactly ``min(n, len(current))`` non-empty, disjoint parts that cover `current`, each
part in original order, the parts sorted by their first element's original position. A schema that
cannot use its information (no geometry, no trace, T = 0, too few distinct positions, not enough data)
degrades as documented on each class and in docs/algorithm.md, never fails.
"""

from __future__ import annotations

import functools
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from pytest_ddenv.errors import ReductionError
from pytest_ddenv.reduce.context import Context
from pytest_ddenv.reduce.types import FloatArray

Part = tuple[str, ...]

KMEANS_N_INIT = 4
"""Fixed number of k-means restarts (seeded), so that partitions are reproducible."""
YAW_RATE_DELTA = 0.2
"""Default change of yaw rate (rad/s) between consecutive samples that starts a new trajectory segment."""


class Partitioner(Protocol):
    """A partition schema."""

    @property
    def name(self) -> str: ...

    def __call__(self, current: Part, n: int, context: Context) -> list[Part]: ...


@functools.cache
def _thread_controller() -> Any:
    from threadpoolctl import ThreadpoolController  # a dependency of scikit-learn

    return ThreadpoolController()


def fit_quietly(model: Any, *args: Any, **kwargs: Any) -> Any:
    """Fit a small scikit-learn model single-threaded (BLAS threads cost more than they save on tiny
    problems, and probes run in parallel anyway) and without convergence warnings."""
    with warnings.catch_warnings(), _thread_controller().limit(limits=1):
        warnings.simplefilter("ignore")
        return model.fit(*args, **kwargs)


def even_split(names: Sequence[str], n: int) -> list[Part]:
    """Contiguous parts whose sizes differ by at most one (plain ddmin split)."""
    names = tuple(names)
    n = max(1, min(n, len(names)))
    bounds = np.linspace(0, len(names), n + 1).round().astype(int)
    return [names[bounds[i] : bounds[i + 1]] for i in range(n) if bounds[i + 1] > bounds[i]]


def finish_parts(groups: Sequence[Sequence[str]], n: int, context: Context) -> list[Part]:
    """Drop empty groups, split the largest group in halves until there are min(n, size) parts, sort.

    Splitting keeps the group's own order (a cluster split in original order, a ranked group by rank), so
    n parts exist even when clustering found fewer (coincident positions, n larger than distinct points).
    """
    parts: list[Part] = [tuple(group) for group in groups if len(group) > 0]
    total = sum(len(part) for part in parts)
    target = min(n, total)
    while len(parts) < target:
        largest = max(range(len(parts)), key=lambda i: (len(parts[i]), -i))
        group = parts.pop(largest)
        half = (len(group) + 1) // 2
        parts[largest:largest] = [group[:half], group[half:]]
    canonical = [context.sort(part) for part in parts]
    canonical.sort(key=lambda part: context.order(part[0]))
    return canonical


@dataclass(frozen=True)
class EvenPartition:
    """`even`: ddmin's split in file order. The baseline; needs nothing."""

    name: str = "even"

    def __call__(self, current: Part, n: int, context: Context) -> list[Part]:
        return finish_parts(even_split(current, n), n, context)


@dataclass(frozen=True)
class ModelToModelPartition:
    """`model2model`: k-means (scikit-learn, seeded, fixed n_init) over the elements' centroids.

    Coincident positions are clustered once (weighted by multiplicity) so they always share a part; if
    there are fewer distinct positions than n, or a cluster comes out empty, the largest parts are split in
    file order until there are n. Without geometry this is `even`.
    """

    name: str = "model2model"
    n_init: int = KMEANS_N_INIT

    def __call__(self, current: Part, n: int, context: Context) -> list[Part]:
        points = context.centroids(current)
        if points is None or len(current) <= 1 or n <= 1:
            return finish_parts(even_split(current, n), n, context)
        distinct, inverse, counts = np.unique(points, axis=0, return_inverse=True, return_counts=True)
        inverse = np.asarray(inverse).reshape(-1)
        clusters = min(n, distinct.shape[0])
        if clusters == distinct.shape[0]:
            labels = inverse
        elif clusters == 1:
            labels = np.zeros(len(current), dtype=int)
        else:
            labels = self._kmeans(distinct, counts, clusters, context.seed)[inverse]
        groups: dict[int, list[str]] = {}
        for name, label in zip(current, labels, strict=True):
            groups.setdefault(int(label), []).append(name)
        return finish_parts(list(groups.values()), n, context)

    def _kmeans(self, points: FloatArray, weights: np.ndarray, clusters: int, seed: int) -> np.ndarray:
        from sklearn.cluster import KMeans

        model = KMeans(n_clusters=clusters, random_state=seed % 2**32, n_init=self.n_init)
        fit_quietly(model, points, sample_weight=weights.astype(np.float64))
        return np.asarray(model.labels_, dtype=int)


def _segment_assignment(current: Part, n: int, context: Context, boundaries: FloatArray) -> list[list[str]] | None:
    """Assign each element to the time segment whose trace points come closest to its surface.

    `boundaries` are the n-1 inner cut times. Returns None when there are no distances to use.
    """
    sampled = context.trace_points()
    distances = context.trace_distances(current)
    if sampled is None or distances is None:
        return None
    _, times = sampled
    segment_of_point = np.searchsorted(np.sort(boundaries), times, side="right")
    closest = np.full((n, len(current)), np.inf)
    for segment in range(n):
        rows = distances[segment_of_point == segment]
        if rows.shape[0] > 0:
            closest[segment] = rows.min(axis=0)
    assignment = np.argmin(closest, axis=0)  # ties: earliest segment
    groups: list[list[str]] = [[] for _ in range(n)]
    for name, segment in zip(current, assignment, strict=True):
        groups[int(segment)].append(name)
    return groups


def _equal_time_cuts(start: float, end: float, n: int) -> FloatArray:
    return np.linspace(start, end, n + 1)[1:-1]


@dataclass(frozen=True)
class TimeSegmentPartition:
    """`timeseg`: the trace cut into n equal-time segments; each element goes to its closest segment.

    Without geometry, without a trace or with an empty trace this is `even`.
    """

    name: str = "timeseg"

    def __call__(self, current: Part, n: int, context: Context) -> list[Part]:
        n = min(n, len(current))
        if context.trace is None or len(context.trace) == 0 or n <= 1:
            return finish_parts(even_split(current, n), n, context)
        times = context.trace.times
        groups = _segment_assignment(current, n, context, _equal_time_cuts(times[0], times[-1], n))
        if groups is None:
            return finish_parts(even_split(current, n), n, context)
        return finish_parts(groups, n, context)


@dataclass(frozen=True)
class TrajectorySegmentPartition:
    """`trajectoryseg`: the trace cut where the yaw rate changes by more than `yaw_rate_delta`.

    Of the changes above the threshold, the n-1 largest become cuts; if there are fewer, the longest
    segments are halved in time until there are n (a straight run is cut like `timeseg`). Elements go to
    their closest segment. Without geometry or trace (or T = 0) this is `even`.
    """

    name: str = "trajectoryseg"
    yaw_rate_delta: float = YAW_RATE_DELTA

    def __call__(self, current: Part, n: int, context: Context) -> list[Part]:
        n = min(n, len(current))
        trace = context.trace
        if trace is None or len(trace) == 0 or n <= 1:
            return finish_parts(even_split(current, n), n, context)
        groups = _segment_assignment(current, n, context, self.cuts(trace.times, trace.yaw_rates, n))
        if groups is None:
            return finish_parts(even_split(current, n), n, context)
        return finish_parts(groups, n, context)

    def cuts(self, times: FloatArray, yaw_rates: FloatArray, n: int) -> FloatArray:
        """The n-1 inner cut times."""
        changes = np.abs(np.diff(yaw_rates))
        above = np.flatnonzero(changes > self.yaw_rate_delta)
        strongest = sorted(above.tolist(), key=lambda i: (-changes[i], i))[: n - 1]
        cuts = sorted({float(times[i + 1]) for i in strongest})
        edges = [float(times[0]), *cuts, float(times[-1])]
        return np.asarray(_subdivide(edges, n)[1:-1], dtype=np.float64)


def _subdivide(edges: list[float], n: int) -> list[float]:
    """Split the intervals between `edges` into n intervals in total, each into equal pieces, the number
    of pieces proportional to its length (largest remainder; every interval keeps at least one)."""
    widths = np.diff(edges)
    total = float(widths.sum())
    if len(widths) >= n or total <= 0.0:
        return edges
    ideal = n * widths / total
    pieces = np.maximum(1, np.floor(ideal)).astype(int)
    while pieces.sum() < n:
        pieces[int(np.argmax(ideal - pieces))] += 1
    while pieces.sum() > n:
        shrinkable = np.where(pieces > 1, ideal - pieces, np.inf)
        pieces[int(np.argmin(shrinkable))] -= 1
    result = [edges[0]]
    for start, width, count in zip(edges[:-1], widths, pieces, strict=True):
        result.extend(start + width * (k + 1) / count for k in range(int(count)))
    return result


@dataclass(frozen=True)
class LearnerPartition:
    """`learner`: logistic regression on the verdicts so far predicts which elements f needs.

    Each decided candidate is a membership vector over the reducible elements, labelled 1 if it reproduced
    f. Elements are ranked by their coefficient (estimated necessity, ties in file order) and the ranking
    is cut into n contiguous groups, so that likely-necessary elements share a part and likely-irrelevant
    ones can be removed together. Until both labels have been seen it is `model2model`.
    """

    name: str = "learner"
    regularization: float = 1.0

    def __call__(self, current: Part, n: int, context: Context) -> list[Part]:
        labels = [verdict.reproduces for verdict in context.history]
        if len(current) <= 1 or n <= 1 or all(labels) or not any(labels):
            return ModelToModelPartition()(current, n, context)
        scores = self.necessity(current, context)
        ranked = sorted(current, key=lambda name: (-scores[name], context.order(name)))
        return finish_parts(even_split(ranked, n), n, context)

    def necessity(self, current: Part, context: Context) -> dict[str, float]:
        """Estimated necessity (logistic-regression coefficient) of each current element."""
        from sklearn.linear_model import LogisticRegression

        columns = {name: i for i, name in enumerate(context.elements)}
        features = np.zeros((len(context.history), len(context.elements)))
        for row, verdict in enumerate(context.history):
            features[row, [columns[name] for name in verdict.members]] = 1.0
        targets = np.array([int(verdict.reproduces) for verdict in context.history])
        model = LogisticRegression(C=self.regularization, max_iter=1000)
        fit_quietly(model, features, targets)
        coefficients = model.coef_[0]
        return {name: float(np.round(coefficients[columns[name]], 9)) for name in current}


PARTITION_SCHEMAS: dict[str, Callable[[], Partitioner]] = {
    "model2model": ModelToModelPartition,
    "timeseg": TimeSegmentPartition,
    "trajectoryseg": TrajectorySegmentPartition,
    "learner": LearnerPartition,
    "even": EvenPartition,
}
PARTITIONS: tuple[str, ...] = tuple(PARTITION_SCHEMAS)
PARTITION_ALIASES = {"m2m": "model2model"}


def make_partitioner(partition: str | Partitioner) -> Partitioner:
    """The schema for a name (or a ready Partitioner object, returned as is)."""
    if not isinstance(partition, str):
        if callable(partition) and isinstance(getattr(partition, "name", None), str):
            return partition
        raise ReductionError(
            f"partition must be one of {', '.join(PARTITIONS)} or a Partitioner object, got {partition!r}"
        )
    name = PARTITION_ALIASES.get(partition, partition)
    if name not in PARTITION_SCHEMAS:
        raise ReductionError(f"unknown partition schema {partition!r}; valid choices: {', '.join(PARTITIONS)}")
    return PARTITION_SCHEMAS[name]()
