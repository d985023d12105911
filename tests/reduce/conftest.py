"""Synthetic worlds for the reduction engine: point elements, straight-line traces, set oracles.

Everything here is simulation-free, so the engine's properties can be checked by hypothesis in
milliseconds per reduction.
"""

from __future__ import annotations

import hashlib
import sys
from collections.abc import Callable, Collection, Sequence
from dataclasses import dataclass, field
from types import ModuleType

import numpy as np
import pytest

from pytest_ddenv.reduce import Outcome, ProbeObservation, Trace


@dataclass(frozen=True)
class PointGeometry:
    """Each element is a ball of `radius` around a point; distances are to its surface (0 inside)."""

    positions: dict[str, tuple[float, float, float]]
    radius: float = 0.0

    def centroids(self, names: Sequence[str]) -> np.ndarray:
        return np.array([self.positions[name] for name in names], dtype=float).reshape(len(names), 3)

    def distances(self, points: np.ndarray, names: Sequence[str]) -> np.ndarray:
        centres = self.centroids(names)
        gaps = np.linalg.norm(np.asarray(points, dtype=float)[:, None, :] - centres[None, :, :], axis=2)
        return np.maximum(gaps - self.radius, 0.0)


def names(count: int) -> tuple[str, ...]:
    return tuple(f"m{i:04d}" for i in range(count))


def line_geometry(elements: Sequence[str], *, coincident: bool = False) -> PointGeometry:
    """Elements spread along y = 1 (or all at one point when `coincident`)."""
    if coincident:
        return PointGeometry({name: (1.0, 1.0, 0.0) for name in elements})
    return PointGeometry({name: (float(i), 1.0 + (i % 3) * 0.5, 0.0) for i, name in enumerate(elements)})


def line_trace(length: float, samples: int = 50, *, sensed: dict[str, float] | None = None) -> Trace:
    """A robot driving along the x axis from 0 to `length`, turning in the middle (yaw-rate step)."""
    if samples == 0:
        return Trace.empty()
    times = np.linspace(0.0, 10.0, samples)
    positions = np.stack([np.linspace(0.0, length, samples), np.zeros(samples), np.zeros(samples)], axis=1)
    yaw_rates = np.where(times > 5.0, 0.8, 0.0)
    return Trace(
        times=times,
        positions=positions,
        yaw_rates=yaw_rates,
        failure_position=positions[-1],
        first_sensed=sensed or {},
    )


@dataclass
class SetOracle:
    """f iff every culprit is present (monotone; the unique 1-minimal answer is the culprit set).

    With `rate` < 1 a world with the culprits fails with that probability, decided by a hash of
    (candidate, attempt, salt), so the outcome is a deterministic function of the probe's arguments.
    """

    culprits: frozenset[str]
    rate: float = 1.0
    salt: int = 0
    trace: Trace | None = None
    calls: list[tuple[tuple[str, ...], int]] = field(default_factory=list)

    def __call__(self, candidate: tuple[str, ...], attempt: int) -> ProbeObservation:
        self.calls.append((candidate, attempt))
        if self.culprits <= set(candidate) and uniform(candidate, attempt, self.salt) < self.rate:
            return ProbeObservation(Outcome.FAIL, trace=self.trace, signature={"kind": "stuck"}, seed=attempt)
        return ProbeObservation(Outcome.PASS, seed=attempt)


@dataclass
class FunctionOracle:
    """f iff `fails(set(candidate))`."""

    fails: Callable[[frozenset[str]], bool]
    calls: list[tuple[tuple[str, ...], int]] = field(default_factory=list)

    def __call__(self, candidate: tuple[str, ...], attempt: int) -> ProbeObservation:
        self.calls.append((candidate, attempt))
        return ProbeObservation(Outcome.FAIL if self.fails(frozenset(candidate)) else Outcome.PASS, seed=attempt)


def uniform(candidate: Collection[str], attempt: int, salt: int) -> float:
    """A reproducible number in [0, 1) for (candidate, attempt, salt)."""
    text = "|".join(sorted(candidate)) + f"#{attempt}#{salt}"
    return int.from_bytes(hashlib.blake2b(text.encode(), digest_size=8).digest(), "big") / 2**64


@pytest.fixture(scope="session")
def synthetic() -> ModuleType:
    """This module: PointGeometry, SetOracle, FunctionOracle, names, line_geometry, line_trace, uniform."""
    return sys.modules[__name__]
