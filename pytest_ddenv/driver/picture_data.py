"""What the pictures read from an artifacts folder: the last reduction's probes and steps in its run log
(runs.jsonl) and the reference failure in summary.json. Read-only; a missing or damaged file gives nothing."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeGuard

if TYPE_CHECKING:
    from pytest_ddenv.reduce.events import Event, Probe


def _last_reduction(log: Path) -> list[Event]:
    """The model-level events of the last reduction in a run log (from its last ``start`` that is not a
    resumed one: a resumed reduction goes on with the probes of the runs before it)."""
    from pytest_ddenv.reduce import events  # lazily: importing the pictures stays cheap
    from pytest_ddenv.reduce.log import read_events

    found: list[Event] = []
    for event in read_events(log):
        if event.stage is None:  # the stages after the models are not drawn here
            if isinstance(event, events.Start) and not event.resumed:
                found = []
            found.append(event)
    return found


def _is_reduction_probe(event: Event) -> TypeGuard[Probe]:
    """A probe whose result the reduction used: its runs of candidates and its calibration runs of the
    original world (what `Reduction.probes` counts)."""
    from pytest_ddenv.reduce import events

    return isinstance(event, events.Probe) and event.purpose in ("reduce", "calibration")


def _reduction_probes(logged: list[Event]) -> list[Probe]:
    return [event for event in logged if _is_reduction_probe(event)]


def probe_sizes_from_log(log: Path) -> list[tuple[int, int, str]]:
    """(probe number, candidate size, outcome) of the probes of the last reduction in a run log: its runs of
    candidates and its calibration runs, numbered in the order they were logged."""
    probes = _reduction_probes(_last_reduction(log))
    return [(number, len(probe.candidate) if probe.size is None else probe.size, probe.outcome)
            for number, probe in enumerate(probes, start=1)]


def steps_from_log(log: Path) -> list[tuple[int, int]]:
    """(probe number, size) of the start and of every adopted world (``step``, ``back-off``) of the last
    reduction in a run log, on the same numbering as `probe_sizes_from_log`. A step is drawn at the probe that
    justified it, the last run of its candidate that failed the same way (with parallel probes, other
    candidates' runs are often logged between that run and the step); a back-off, which no probe justifies,
    where it happened. A step a resumed reduction adopts again from the log is drawn once. Empty when the
    log has no start."""
    from pytest_ddenv.reduce import events

    steps: list[tuple[int, int]] = []
    adopted: set[tuple[frozenset[str], int]] = set()
    last_fail: dict[frozenset[str], int] = {}
    probes = 0
    for event in _last_reduction(log):
        if isinstance(event, events.Start) and not steps:
            steps.append((0, len(event.elements) + len(event.keep)))
        elif _is_reduction_probe(event):
            probes += 1
            if event.outcome == "fail":
                last_fail[frozenset(event.candidate)] = probes
        elif isinstance(event, events.Adopted):
            key = frozenset(event.candidate)
            number = last_fail.get(key, probes) if isinstance(event, events.Step) else probes
            if (key, number) in adopted:
                continue
            adopted.add((key, number))
            steps.append((max(number, steps[-1][0] if steps else 0), len(event.candidate)))
    return steps


def accepted_probes_from_log(log: Path) -> set[int]:
    """The numbers (as in `probe_sizes_from_log`) of the probes that failed the same way on a world the
    reduction adopted (a step, or the original world's calibration runs); the other same-failure probes
    were not accepted (the deflake rule rejected their candidate, or another candidate was adopted first)."""
    from pytest_ddenv.reduce import events

    logged = _last_reduction(log)
    adopted = {frozenset(event.candidate) for event in logged if isinstance(event, events.Adopted)}
    return {number for number, probe in enumerate(_reduction_probes(logged), start=1) if probe.outcome == "fail"
            and (probe.purpose == "calibration" or frozenset(probe.candidate) in adopted)}


def _reference_failure(summary: Path) -> dict[str, Any] | None:
    """The ``reference_failure`` object of a summary.json (None: no such file, key or object)."""
    from pytest_ddenv.driver.artifacts import read_summary

    data = read_summary(summary)
    reference = None if data is None else data.get("reference_failure")
    return reference if isinstance(reference, dict) else None


def reference_text(summary: Path) -> str | None:
    """The reduced failure in its own words when no predicate found it ("AssertionError at test_x.py:12")."""
    reference = _reference_failure(summary)
    if reference is None or reference.get("signature") is not None:
        return None
    return f"{reference.get('exception_type', 'an exception')} at {reference.get('location', '?')}"


def reference_pose(summary: Path) -> list[float] | None:
    """The pose (x, y, z, roll, pitch, yaw) of the reference failure a predicate found, else None."""
    reference = _reference_failure(summary)
    if reference is None:
        return None
    try:
        return [float(v) for v in reference["signature"]["pose"]]
    except (KeyError, TypeError, ValueError):
        return None
