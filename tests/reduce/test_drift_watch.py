"""The drift watch (issue 33): an accepted world that may fail less often than the original is compared during
the reduction, not only at its end (reduce/rate_check.py `DriftWatch`). Synthetic outcomes, no physics."""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from pathlib import Path

from pytest_ddenv.reduce import Outcome, ProbeLog, ProbeObservation, Reduction, events, reduce

ELEMENTS = ("a", "b", "c", "d", "e", "f", "g", "h")
Probe = Callable[[tuple[str, ...], int], ProbeObservation]


def observation(fails: bool, attempt: int) -> ProbeObservation:
    return ProbeObservation(Outcome.FAIL if fails else Outcome.PASS, signature={"kind": "stuck"}, seed=attempt)


def needs_a_and_b(candidate: tuple[str, ...], attempt: int) -> ProbeObservation:
    """f exactly when 'a' and 'b' are both there: every accepted world fails every run."""
    return observation({"a", "b"} <= set(candidate), attempt)


def needs_a_and_h(candidate: tuple[str, ...], attempt: int) -> ProbeObservation:
    """f exactly when 'a' and 'h' are both there (rejections between the accepted worlds)."""
    return observation({"a", "h"} <= set(candidate), attempt)


def lucky_without_b(*lucky: int) -> Probe:
    """f always with 'a' and 'b'; with 'a' alone only on the attempts `lucky` (a world that drifted)."""

    def probe(candidate: tuple[str, ...], attempt: int) -> ProbeObservation:
        present = set(candidate)
        return observation({"a", "b"} <= present or ("a" in present and attempt in lucky), attempt)

    return probe


def recording(probe: Probe) -> tuple[Probe, list[tuple[tuple[str, ...], int]]]:
    calls: list[tuple[tuple[str, ...], int]] = []

    def recorded(candidate: tuple[str, ...], attempt: int) -> ProbeObservation:
        calls.append((candidate, attempt))
        return probe(candidate, attempt)

    return recorded, calls


def run(probe: Probe, log: Path, deflake: int | str = 0) -> tuple[Reduction, list[tuple[tuple[str, ...], int]]]:
    recorded, calls = recording(probe)
    result = reduce(ELEMENTS, recorded, deflake=deflake, partition="even", priority="sequential", log=log)
    return result, calls


def fresh_runs(log: Path) -> dict[tuple[str, ...], list[int]]:
    """world -> attempts of its failure-rate runs, in log order."""
    runs: dict[tuple[str, ...], list[int]] = {}
    for probe in ProbeLog.load(log).probes("failure-rate"):
        runs.setdefault(tuple(probe.candidate), []).append(probe.attempt)
    return runs


def assert_evidence_is_fresh(log: Path, calls: list[tuple[tuple[str, ...], int]]) -> None:
    """No run is made twice, and no run that decided a world (the accepting one above all) is one of its fresh
    runs: they start after the attempts its verdict rests on."""
    assert not [call for call, count in Counter(calls).items() if count > 1], "a run simulated twice"
    decided = {frozenset(verdict.candidate): verdict.runs for verdict in ProbeLog.load(log).own_events()
               if isinstance(verdict, events.Accept)}
    for world, attempts in fresh_runs(log).items():
        if frozenset(world) != frozenset(ELEMENTS):
            assert min(attempts) >= decided[frozenset(world)], (world, attempts, decided[frozenset(world)])


def test_confirming_runs_that_fail_start_no_comparison_and_is_the_minimal_worlds_first_fresh_run(
        tmp_path: Path) -> None:
    log = tmp_path / "runs.jsonl"
    result, calls = run(needs_a_and_h, log)
    assert result.minimal == ("a", "h") and result.one_minimal and result.rate_backoffs == 0
    runs = fresh_runs(log)
    intermediate = {world: attempts for world, attempts in runs.items() if world not in (("a", "h"), ELEMENTS)}
    assert intermediate and all(attempts == [1, 2] for attempts in intermediate.values()), (
        "confirming runs (attempts 1 and 2: attempt 0 accepted it) of each world accepted on one run")
    assert runs[("a", "h")] == [1, 2, 3, 4, 5], "the confirming runs count once, as the first of the look's 5"
    checks = [event for event in ProbeLog.load(log).own_events() if isinstance(event, events.RateCheck)]
    assert [check.candidate for check in checks] == [("a", "h")], "no comparison but the end's"
    assert result.simulations == len(calls) == result.probes + sum(map(len, runs.values()))
    assert_evidence_is_fresh(log, calls)


def test_a_drifted_world_is_caught_during_the_reduction_and_a_resumed_log_simulates_nothing(tmp_path: Path) -> None:
    log = tmp_path / "runs.jsonl"
    result, calls = run(lucky_without_b(0), log)  # {'a'} is accepted on its attempt 0, then never fails again
    assert result.minimal == ("a", "b") and result.one_minimal
    assert result.rate_check is not None and result.rate_check.decision == "holds"
    assert result.rate_backoffs == 1
    assert any(note.startswith("back-off 1: a 1-element accepted world (drift watch, during the reduction)")
               for note in result.notes), result.notes
    logged = ProbeLog.load(log).own_events()
    below = [event for event in logged if isinstance(event, events.RateBelow)]
    assert [event.candidate for event in below] == [("a",)]
    checks = [event for event in logged if isinstance(event, events.RateCheck)]
    assert checks[0].candidate == ("a",) and checks[0].reduced[0] == 0, "its own fresh runs: all passing"
    assert fresh_runs(log)[("a",)][0] == 1, "the confirming run is its first fresh run, never the accepting one"
    assert_evidence_is_fresh(log, calls)

    again, calls_again = run(lucky_without_b(0), log)
    assert calls_again == [], "every run is in the log"
    assert again.minimal == result.minimal and again.rate_check is not None and again.rate_backoffs == 1
    assert again.notes == result.notes, "the same back-off, replayed from the logged runs"
    assert again.rate_check.decision == "holds"


def test_a_pass_among_the_deciding_runs_starts_the_comparison_without_a_confirming_run(tmp_path: Path) -> None:
    log = tmp_path / "runs.jsonl"
    result, calls = run(lucky_without_b(1), log, deflake=3)  # {'a'}: pass, then f on attempt 1: accepted
    assert result.minimal == ("a", "b") and result.rate_backoffs == 1
    assert fresh_runs(log)[("a",)][:5] == [2, 3, 4, 5, 6], "its fresh runs start after the two that decided it"
    assert_evidence_is_fresh(log, calls)


def test_accepted_on_two_failing_runs_one_run_is_confirmed(tmp_path: Path) -> None:
    """`auto` on a solid failure (2-of-3) accepts on two failing runs: one confirming run (attempt 2) of an
    accepted world a later round rejects a new candidate of; none of a world whose first candidate holds."""
    log = tmp_path / "runs.jsonl"
    result, calls = run(needs_a_and_h, log, deflake="auto")
    assert result.minimal == ("a", "h") and result.deflake == "auto:2-of-3"
    runs = fresh_runs(log)
    intermediate = {world: attempts for world, attempts in runs.items() if world not in (("a", "h"), ELEMENTS)}
    assert intermediate and all(attempts == [2] for attempts in intermediate.values()), intermediate
    assert runs[("a", "h")] == [2, 3, 4, 5, 6]
    assert result.simulations == len(calls) == result.probes + 5 + len(intermediate)
    assert_evidence_is_fresh(log, calls)

    log_b = tmp_path / "runs-b.jsonl"
    result, calls = run(needs_a_and_b, log_b, deflake="auto")  # every accepted world holds its round's first
    assert set(fresh_runs(log_b)) == {("a", "b")} and result.simulations == result.probes + 5


def test_no_drift_watch_once_the_original_has_passed_a_fresh_run(tmp_path: Path) -> None:
    """The original passes one calibration run: a pass of an accepted world says nothing, so accepted worlds
    (each with a pass among the runs that decided it) are left to the end-of-run comparison."""

    def probe(candidate: tuple[str, ...], attempt: int) -> ProbeObservation:
        if candidate == ELEMENTS:
            return observation(attempt != 2, attempt)
        return observation({"a", "b"} <= set(candidate) and attempt != 0, attempt)

    log = tmp_path / "runs.jsonl"
    result, calls = run(probe, log, deflake="auto")
    assert result.calibration == (4, 5) and result.minimal == ("a", "b")
    assert set(fresh_runs(log)) <= {("a", "b"), ELEMENTS}, "no accepted world watched"
    checks = [event for event in ProbeLog.load(log).own_events() if isinstance(event, events.RateCheck)]
    assert [check.candidate for check in checks] == [("a", "b")]
    assert_evidence_is_fresh(log, calls)
