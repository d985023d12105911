"""What the schemas may look at: the geometry, the latest failing trace, and the verdicts so far.

One `Context` lives for one reduction. It caches the geometry queries: an element's centroid once, and the
distance from every trace point to an element once per trace, when a schema first asks for it (the trace
changes only when a smaller failing world is adopted, and then only the current elements are asked for).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from pytest_ddenv.errors import ReductionError
from pytest_ddenv.reduce.types import FloatArray, Geometry, Trace

MAX_TRACE_POINTS = 2000
"""Longer traces are subsampled evenly (first and last point kept) before distances are computed."""


@dataclass(frozen=True)
class Verdict:
    """One decided candidate, as the learner sees it: which reducible elements it had, did it give f."""

    members: frozenset[str]
    reproduces: bool
    errored: bool = False
    """A rejection that rests on ERROR runs (`Decision.errored`): no evidence about the world."""


@dataclass
class Context:
    """Geometry + latest failing trace + history, for the partition and priority schemas."""

    elements: tuple[str, ...]
    """All reducible elements of the original world, original order."""
    geometry: Geometry | None = None
    trace: Trace | None = None
    seed: int = 0
    history: list[Verdict] = field(default_factory=list)
    """Verdicts in the order the serial algorithm consults them (identical with and without an executor)."""
    _index: dict[str, int] = field(default_factory=dict, init=False, repr=False)
    _centroids: dict[str, FloatArray] = field(default_factory=dict, init=False, repr=False)
    _distance_trace: Trace | None = field(default=None, init=False, repr=False)
    _distances: dict[str, FloatArray] = field(default_factory=dict, init=False, repr=False)
    _points: FloatArray | None = field(default=None, init=False, repr=False)
    _point_times: FloatArray | None = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:
        self._index = {name: i for i, name in enumerate(self.elements)}

    def order(self, name: str) -> int:
        """Position of an element in the original world."""
        return self._index[name]

    def sort(self, names: Sequence[str]) -> tuple[str, ...]:
        """Names in original order."""
        return tuple(sorted(names, key=self._index.__getitem__))

    # -- geometry -----------------------------------------------------------------------------------------

    def centroids(self, names: Sequence[str]) -> FloatArray | None:
        """(E, 3) centroids of the named elements, or None without geometry."""
        if self.geometry is None:
            return None
        missing = [name for name in dict.fromkeys(names) if name not in self._centroids]
        if missing:
            centroids = np.asarray(self.geometry.centroids(missing), dtype=np.float64)
            if centroids.shape != (len(missing), 3) or not np.all(np.isfinite(centroids)):
                raise ReductionError(
                    f"geometry.centroids() must return finite values of shape ({len(missing)}, 3), "
                    f"got shape {centroids.shape}"
                )
            self._centroids.update(zip(missing, centroids, strict=True))
        if not names:
            return np.zeros((0, 3))
        return np.stack([self._centroids[name] for name in names])

    def trace_points(self) -> tuple[FloatArray, FloatArray] | None:
        """(points (N, 3), times (N,)) of the current trace, subsampled (the carried path's points after the
        robot's, with the same times), or None if there are none."""
        self._refresh_trace_cache()
        if self._points is None or self._point_times is None:
            return None
        return self._points, self._point_times

    def trace_distances(self, names: Sequence[str]) -> FloatArray | None:
        """(N, E) distance from each (subsampled) trace point to each named element, or None."""
        if self.geometry is None:
            return None
        self._refresh_trace_cache()
        if self._points is None:
            return None
        missing = [name for name in dict.fromkeys(names) if name not in self._distances]
        if missing:
            self._distances.update(zip(missing, self._measure(self._points, missing).T, strict=True))
        if not names:
            return np.zeros((len(self._points), 0))
        return np.stack([self._distances[name] for name in names], axis=1)

    def point_distances(self, point: FloatArray, names: Sequence[str]) -> FloatArray | None:
        """(E,) distance from one point to each named element, or None without geometry."""
        if self.geometry is None:
            return None
        row: FloatArray = self._measure(np.asarray(point, dtype=np.float64).reshape(1, 3), list(names))[0]
        return row

    def failure_point(self) -> FloatArray | None:
        """Where the latest failure happened: the failure position, else the last trace point, else None."""
        if self.trace is None:
            return None
        if self.trace.failure_position is not None:
            return self.trace.failure_position
        if len(self.trace) > 0:
            last: FloatArray = self.trace.positions[-1]
            return last
        return None

    def _measure(self, points: FloatArray, names: list[str]) -> FloatArray:
        assert self.geometry is not None
        distances = np.asarray(self.geometry.distances(points, names), dtype=np.float64)
        expected = (points.shape[0], len(names))
        if distances.shape != expected or not np.all(np.isfinite(distances)):
            raise ReductionError(
                f"geometry.distances() must return finite values of shape {expected}, got shape {distances.shape}"
            )
        return distances

    def _refresh_trace_cache(self) -> None:
        if self._distance_trace is self.trace:
            return
        self._distance_trace = self.trace
        self._distances = {}
        self._points = None
        self._point_times = None
        if self.trace is None or len(self.trace) == 0:
            return
        count = len(self.trace)
        if count > MAX_TRACE_POINTS:
            chosen = np.unique(np.linspace(0, count - 1, MAX_TRACE_POINTS).round().astype(int))
        else:
            chosen = np.arange(count)
        self._points = self.trace.positions[chosen]
        self._point_times = self.trace.times[chosen]
        if self.trace.carried is not None:  # what the robot carries passes by objects too
            self._points = np.concatenate([self._points, self.trace.carried[chosen]])
            self._point_times = np.concatenate([self._point_times, self._point_times])
