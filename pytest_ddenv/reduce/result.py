"""What a reduction reports: its `Reduction` result (with its notes) and the "start" and "end" records of its
run log. The engine (`engine.py`) hands over its state at the end; these say how it is spelt."""

from __future__ import annotations

from collections.abc import Sequence

from pytest_ddenv.reduce import events
from pytest_ddenv.reduce.counters import Counters
from pytest_ddenv.reduce.rates import RateComparison
from pytest_ddenv.reduce.settings import Settings
from pytest_ddenv.reduce.types import Candidate, FirstCutResult, Reduction


def plural(count: int, noun: str) -> str:
    return f"{count} {noun}{'' if count == 1 else 's'}"


def notes_of(log_notes: Sequence[str], backoff_notes: Sequence[str], unverified: int) -> tuple[str, ...]:
    """The result's notes: the run log's, the back-offs', and the single removals left `unverified`."""
    notes = [*log_notes, *backoff_notes]
    if unverified:
        notes.append(
            f"not verified: {plural(unverified, 'single removal')} of the minimal world rejected only "
            "because the runs errored (a worker died or a probe hung), also when tried again; a resumed "
            "reduction tries again"
        )
    return tuple(notes)


def build_reduction(
    settings: Settings,
    counters: Counters,
    *,
    minimal: Candidate,
    probes: int,
    steps: Sequence[tuple[int, int]],
    one_minimal: bool,
    incomplete: str | None,
    failure_rate: tuple[int, int],
    wall_time: float,
    deflake: int | str,
    calibration: tuple[int, int] | None,
    resumed_probes: int,
    notes: tuple[str, ...],
    rate_check: RateComparison | None,
    rate_backoffs: int,
    precondition_kept: tuple[tuple[str, str], ...],
    without_precondition_kept: tuple[int, int] | None,
    independent: bool,
    first_cut: FirstCutResult | None,
) -> Reduction:
    """The `Reduction` of a reduction with `settings` whose probes `counters` counted."""
    return Reduction(
        original=settings.elements,
        minimal=minimal,
        kept=tuple(name for name in settings.elements if name in settings.keep),
        probes=probes,
        cache_hits=counters.cache_hits,
        skipped=len(counters.skipped),
        errors=counters.errors,
        steps=tuple(steps),
        one_minimal=one_minimal,
        incomplete_reason=incomplete,
        failure_rate=failure_rate,
        wall_time=wall_time,
        partition=settings.partitioner.name,
        priority=settings.prioritizer.name,
        granularity=settings.granularity,
        deflake=deflake,
        seed=settings.seed,
        calibration=calibration,
        simulations=counters.simulations,
        resumed_probes=resumed_probes,
        errored=len(counters.errored),
        notes=notes,
        rate_check=rate_check,
        rate_backoffs=rate_backoffs,
        precondition_kept=precondition_kept,
        without_precondition_kept=without_precondition_kept,
        independent=independent,
        first_cut=first_cut,
    )


def start_event(settings: Settings, *, resumed: bool) -> events.Start:
    """The run log's "start" record of a reduction with `settings` (`resumed`: from an earlier log)."""
    return events.Start(
        resumed=resumed, elements=tuple(settings.elements),
        keep=tuple(name for name in settings.elements if name in settings.keep),
        partition=settings.partitioner.name, priority=settings.prioritizer.name,
        n_partitions=settings.n_partitions, granularity=settings.granularity,
        complement_order=settings.complement_order, deflake=settings.policy.label, seed=settings.seed,
        max_probes=settings.max_probes, max_seconds=settings.max_seconds,
        failure_rate_runs=settings.failure_rate_runs, reference=settings.reference is not None)


def end_event(reduction: Reduction) -> events.End:
    """The run log's "end" record of `reduction`."""
    return events.End(
        minimal=tuple(reduction.minimal), size=len(reduction.minimal), original_size=len(reduction.original),
        probes=reduction.probes, simulations=reduction.simulations, resumed_probes=reduction.resumed_probes,
        cache_hits=reduction.cache_hits, skipped=reduction.skipped, errors=reduction.errors,
        errored=reduction.errored, steps=[list(step) for step in reduction.steps],
        one_minimal=reduction.one_minimal, incomplete_reason=reduction.incomplete_reason,
        failure_rate=list(reduction.failure_rate),
        rate_check=None if reduction.rate_check is None else reduction.rate_check.decision,
        rate_backoffs=reduction.rate_backoffs, wall_time=reduction.wall_time)
