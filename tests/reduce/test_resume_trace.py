"""A resumed reduction takes the path of the run it resumes: the schemas of each round read the trace of the
last accepted world's first failing run, which is logged with the acceptance (`events.Accept.trace`), so a
world accepted from the log orders the next rounds as it did the first time. Synthetic probes, no physics."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from pytest_ddenv.reduce import Outcome, ProbeLog, ProbeObservation, Trace, events, reduce

from .conftest import line_geometry, names

ELEMENTS = names(16)
CULPRITS = frozenset({"m0002", "m0013"})


def trace_of(candidate: tuple[str, ...]) -> Trace:
    """A path whose end jumps with the candidate (a hash of its element indices): every accepted world moves
    the failure point, so the priority orders each round by a trace of its own."""
    end = float(sum(int(name[1:]) for name in candidate) * 7 % len(ELEMENTS))
    times = np.linspace(0.0, 5.0, 20)
    positions = np.stack([np.linspace(0.0, end, 20), np.ones(20), np.zeros(20)], axis=1)
    return Trace(times=times, positions=positions, yaw_rates=np.zeros(20), failure_position=positions[-1],
                 first_sensed={candidate[0]: 1.25}, touched=frozenset(candidate[-1:]))


def probe(calls: list[tuple[tuple[str, ...], int]], *,
          lucky: str | None = None) -> Callable[[tuple[str, ...], int], ProbeObservation]:
    """f with both culprits; with `lucky`, also with that culprit alone on attempt 0 (such a world drifts)."""

    def run(candidate: tuple[str, ...], attempt: int) -> ProbeObservation:
        calls.append((candidate, attempt))
        if CULPRITS <= set(candidate) or (lucky is not None and lucky in candidate and attempt == 0):
            return ProbeObservation(Outcome.FAIL, trace=trace_of(candidate), signature={"kind": "stuck"}, seed=attempt)
        return ProbeObservation(Outcome.PASS, signature=None, seed=attempt)

    return run


@pytest.mark.parametrize("priority", ["failure-proximal", "avg-trajectory-proximal"])
def test_a_resumed_reduction_simulates_nothing_and_takes_the_same_path(tmp_path: Path, priority: str) -> None:
    log = tmp_path / "runs.jsonl"
    first_calls: list[tuple[tuple[str, ...], int]] = []
    first = reduce(ELEMENTS, probe(first_calls), geometry=line_geometry(ELEMENTS), reference=trace_of(ELEMENTS),
                   partition="even", priority=priority, deflake=0, log=log)
    assert set(first.minimal) == CULPRITS and first_calls
    accepted = [event for event in ProbeLog.load(log).own_events() if isinstance(event, events.Accept)]
    assert accepted and all(event.trace is not None for event in accepted)
    assert accepted[0].trace is not None
    logged = Trace.from_json(accepted[0].trace)
    expected = trace_of(tuple(accepted[0].candidate))
    assert np.array_equal(logged.positions, expected.positions) and logged.touched == expected.touched
    assert logged.first_sensed == expected.first_sensed, "the trace reads back exactly"

    again_calls: list[tuple[tuple[str, ...], int]] = []
    again = reduce(ELEMENTS, probe(again_calls), geometry=line_geometry(ELEMENTS), reference=trace_of(ELEMENTS),
                   partition="even", priority=priority, deflake=0, log=log)
    assert again_calls == [], "every verdict on the path is in the log"
    assert again.minimal == first.minimal and again.probes == first.probes


def test_a_resumed_reduction_replays_a_drift_back_off_without_a_simulation(tmp_path: Path) -> None:
    """A world accepted on a lucky run, then backed off by the drift watch: the resumed reduction accepts it
    again from the log, with its logged trace, plays the same round after it and backs off at the same point."""
    log = tmp_path / "runs.jsonl"
    first_calls: list[tuple[tuple[str, ...], int]] = []
    first = reduce(ELEMENTS, probe(first_calls, lucky="m0013"), geometry=line_geometry(ELEMENTS),
                   reference=trace_of(ELEMENTS), partition="even", priority="failure-proximal", deflake=0, log=log)
    assert set(first.minimal) == CULPRITS and first.rate_backoffs >= 1
    again_calls: list[tuple[tuple[str, ...], int]] = []
    again = reduce(ELEMENTS, probe(again_calls, lucky="m0013"), geometry=line_geometry(ELEMENTS),
                   reference=trace_of(ELEMENTS), partition="even", priority="failure-proximal", deflake=0, log=log)
    assert again_calls == [], "every run on the path, the drift watch's included, is in the log"
    assert (again.minimal, again.probes, again.rate_backoffs) == (first.minimal, first.probes, first.rate_backoffs)
