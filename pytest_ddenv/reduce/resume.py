"""What a reduction takes from its run log before it starts: the log opened (and refused when it belongs to
another world), and, when it resumes an earlier run, the verdicts to reuse, the runs of undecided candidates
and how many probes the earlier runs decided. See docs/algorithm.md (memoization, the log and resuming)."""

from __future__ import annotations

from collections.abc import MutableMapping
from dataclasses import dataclass
from typing import Any

from pytest_ddenv.errors import ReductionError
from pytest_ddenv.reduce import events
from pytest_ddenv.reduce.log import ProbeLog, accepted_trace
from pytest_ddenv.reduce.settings import Settings
from pytest_ddenv.reduce.types import Decision, Outcome


def open_log(settings: Settings) -> ProbeLog | None:
    """The run log of `settings` (a path is opened to resume), refused when it started another world."""
    if settings.log is None:
        return None
    log = settings.log if isinstance(settings.log, ProbeLog) else ProbeLog(settings.log, resume=True)
    started = log.started_with()
    if started is not None and (started[0] != settings.elements or set(started[1]) != settings.keep):
        raise ReductionError(
            f"the probe log {log.path or '(in memory)'} belongs to a reduction of a different world "
            f"({len(started[0])} elements, keep={list(started[1])}); pass another log path, or move this one away"
        )
    return log


@dataclass(frozen=True)
class Resumed:
    """What a run log gives a reduction that starts with it."""

    resumed: bool
    """The log holds an earlier start of this reduction."""
    history: int
    """Probes decided by earlier runs of the log (reported as part of the whole history)."""
    preloaded: dict[frozenset[str], list[Outcome]]
    """The logged runs of candidates not yet decided (`ProbeLog.partial_runs`)."""


def resume(log: ProbeLog | None, cache: MutableMapping[Any, Any]) -> Resumed:
    """Read `log`: its verdicts go into `cache` (not over the cache's own), the acceptances a rate comparison
    undid included (`accepted_before_rate_below`)."""
    if log is None:
        return Resumed(resumed=False, history=0, preloaded={})
    resumed = log.started_with() is not None
    history = log.decided_probes()
    for key, decision in {**log.decisions(), **accepted_before_rate_below(log)}.items():
        cache.setdefault(key, decision)
    return Resumed(resumed=resumed, history=history, preloaded=log.partial_runs())


def accepted_before_rate_below(log: ProbeLog) -> dict[frozenset[str], Decision]:
    """The acceptances a rate comparison undid later in `log`: a resumed reduction accepts them again and
    undoes them at the same point, from the logged runs (the drift watch's or the end's comparison), so it
    takes the same path without a new simulation."""
    accepted: dict[frozenset[str], Decision] = {}
    undone: dict[frozenset[str], Decision] = {}
    for event in log.own_events():
        key = frozenset(event.candidate) if isinstance(event, (events.Accept, events.RateBelow)) else None
        if isinstance(event, events.Accept) and key is not None:
            accepted[key] = Decision(reproduces=True, fails=event.fails, runs=event.runs, errors=event.errors or 0,
                                     trace=accepted_trace(event))
        elif isinstance(event, events.RateBelow) and key in accepted:
            undone[key] = accepted[key]
    return undone
