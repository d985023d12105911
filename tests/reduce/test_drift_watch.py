"""The drift watch (issue 33): an accepted world that may fail less often than the original is compared during
the reduction, not only at its end (reduce/rate_check.py `DriftWatch`). Synthetic outcomes, no physics."""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from pathlib import Path

import pytest

from pytest_ddenv.reduce import Outcome, ProbeLog, ProbeObservation, Reduction, events, reduce
from pytest_ddenv.reduce.rates import SEARCH_LEVEL, Rate, compare, search_below

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


def test_a_world_the_first_look_cannot_call_below_gets_a_second_look(tmp_path: Path) -> None:
    """{'a'} fails 3 of its first 5 fresh runs: against the original's 5/5 that is not below at the search level
    (p = 0.22), so the watch looks again at 10 runs: 6 of 10 against 10/10 is (p = 0.043), and it is backed off
    there, not after the end-of-run comparison's 20 runs of each world (`rate_check.SEARCH_LOOKS`)."""
    assert search_below(Rate(5, 5), Rate(3, 5), 5).decision == "holds"  # type: ignore[union-attr]
    log = tmp_path / "runs.jsonl"
    result, calls = run(lucky_without_b(0, 2, 3, 4, 6, 7, 8), log)
    assert result.minimal == ("a", "b") and result.rate_backoffs == 1
    assert any(note.startswith("back-off 1: a 1-element accepted world (drift watch, during the reduction)")
               for note in result.notes), result.notes
    checks = [event for event in ProbeLog.load(log).own_events() if isinstance(event, events.RateCheck)]
    assert (checks[0].candidate, checks[0].reduced, checks[0].original, checks[0].decision) == (
        ("a",), (6, 10), (10, 10), "below")
    assert fresh_runs(log)[("a",)] == list(range(1, 11)), "10 fresh runs of it, never 20"
    assert_evidence_is_fresh(log, calls)


def test_a_world_that_fails_every_run_of_the_first_look_gets_no_second(tmp_path: Path) -> None:
    """Under any-of-4 {'a'} passes attempt 0 and fails attempt 1 (accepted, tested at once for the pass), then
    fails its 5 fresh runs: it holds on the first look and no second one is made."""
    log = tmp_path / "runs.jsonl"
    result, calls = run(lucky_without_b(*range(1, 30)), log, deflake=3)
    checks = [event for event in ProbeLog.load(log).own_events() if isinstance(event, events.RateCheck)]
    assert (checks[0].candidate, checks[0].reduced, checks[0].decision) == (("a",), (5, 5), "holds")
    assert result.minimal == ("a",) and result.rate_backoffs == 0
    assert fresh_runs(log)[("a",)] == [2, 3, 4, 5, 6], "the first look's 5 runs, reused by the end's comparison"
    assert_evidence_is_fresh(log, calls)


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


def test_the_search_decision_on_the_first_look() -> None:
    """`rates.search_below`: 5 fresh runs of the world against the original's first 5, one-sided Fisher exact at
    SEARCH_LEVEL (0.1): 2 of 5 against 5/5 is below (p = 0.083, the end-of-run test's first look says
    "continue" at 0.0167), 3 of 5 is not (p = 0.22); the original's runs are started only when they matter."""
    assert SEARCH_LEVEL == 0.1
    below = search_below(Rate(5, 5), Rate(2, 5), 5)
    assert below is not None and below.decision == "below" and below.search and below.p_value == pytest.approx(1 / 12)
    assert compare(Rate(5, 5), Rate(2, 5)).decision == "continue", "the guarantee's test needs its second look"
    held = search_below(Rate(5, 5), Rate(3, 5), 5)
    assert held is not None and held.decision == "holds" and held.p_value == pytest.approx(2 / 9)
    unneeded = search_below(Rate(0, 0), Rate(3, 5), 5)
    assert unneeded is not None and unneeded.decision == "holds" and unneeded.skipped == 5, "no run of the original"
    assert search_below(Rate(0, 0), Rate(2, 5), 5) is None, "the original's 5 runs decide it"
    assert search_below(Rate(3, 3), Rate(2, 5), 5) is None
    from_calibration = search_below(Rate(3, 3), Rate(0, 5), 5)
    assert from_calibration is not None and from_calibration.decision == "below" and from_calibration.skipped == 2
    short = search_below(Rate(5, 5), Rate(1, 4), 5)
    assert short is not None and short.decision == "continue", "the budget stopped the world's runs: no verdict"
    assert "search level" in below.describe() and "significantly" not in below.describe()


def test_two_failures_in_the_first_look_back_off_where_the_old_watch_ran_a_second_look(tmp_path: Path) -> None:
    """{'a'} is accepted on attempt 0 and fails attempts 1 and 3 of its 5 first fresh ones: the watch backs off
    on those 5 and the original's first 5 (the runs the end-of-run comparison would make first), no more."""
    log = tmp_path / "runs.jsonl"
    result, calls = run(lucky_without_b(0, 1, 3), log)
    assert result.minimal == ("a", "b") and result.one_minimal and result.rate_backoffs == 1
    runs = fresh_runs(log)
    assert runs[("a",)] == [1, 2, 3, 4, 5] and runs[ELEMENTS] == [1, 2, 3, 4, 5], "one look, each run once"
    checks = [event for event in ProbeLog.load(log).own_events() if isinstance(event, events.RateCheck)]
    assert checks[0].candidate == ("a",) and (checks[0].reduced, checks[0].original) == ((2, 5), (5, 5))
    assert checks[0].decision == "below" and checks[0].p_value == pytest.approx(1 / 12)
    assert any("less often than the original (fails 2/5" in note and "search level" in note for note in result.notes)
    assert result.simulations == len(calls) == result.probes + sum(map(len, runs.values()))
    assert_evidence_is_fresh(log, calls)


def test_a_world_the_watch_holds_is_still_decided_by_the_end_of_run_comparison(tmp_path: Path) -> None:
    """{'a'} fails attempts 0, 1, 3, 4 and 6-9 only: 3 of its first 5 fresh runs hold the first look of the
    search decision; before a second look the original's first 5 runs are made (5/5: not flaky, so the world's
    passes mean something), then 7 of 10 holds (p = 0.105 even against 10/10: no more run of the original), the
    reduction goes on from {'a'}, and the end-of-run comparison, unchanged, reuses those 10 runs, needs its
    last look and backs off (7/20 against 20/20), comparing the world before {'a'} first."""
    log = tmp_path / "runs.jsonl"
    result, calls = run(lucky_without_b(0, 1, 3, 4, 6, 7, 8, 9), log)
    checks = [event for event in ProbeLog.load(log).own_events() if isinstance(event, events.RateCheck)]
    assert checks[0].candidate == ("a",) and (checks[0].reduced, checks[0].original) == ((7, 10), (5, 5))
    assert checks[0].decision == "holds", "the watch's search decision"
    assert checks[1].candidate == ("a",) and checks[1].reduced == (7, 20) and checks[1].original == (20, 20)
    assert checks[1].decision == "below", "the end-of-run comparison at its own level"
    assert checks[2].candidate == ("a", "b") and checks[2].decision == "holds", "the world before it is compared first"
    assert ("a", "b", "c", "d") not in [check.candidate for check in checks], "a binary search would start there"
    assert result.minimal == ("a", "b") and result.rate_backoffs == 1
    assert any(note.startswith("back-off 1: a 1-element minimal world failed significantly less often")
               for note in result.notes), result.notes
    runs = fresh_runs(log)
    assert runs[("a",)] == list(range(1, 21)), "the watch's 10 runs are the end's first 10, each made once"
    assert result.simulations == len(calls) == result.probes + sum(map(len, runs.values()))
    assert_evidence_is_fresh(log, calls)


def test_an_error_among_the_deciding_runs_is_no_reason_to_test(tmp_path: Path) -> None:
    """Under any-of-4 the accepted world {a, b, g, h} errs on attempt 0 (a crash, no outcome of the world) and
    fails on attempt 1: it is watched like a world accepted on failing runs alone (one confirming run, attempt
    2), not tested at once as if it had passed a run."""
    def probe(candidate: tuple[str, ...], attempt: int) -> ProbeObservation:
        if set(candidate) == {"a", "b", "g", "h"} and attempt == 0:
            return ProbeObservation(Outcome.ERROR, signature={"kind": "crash"}, seed=attempt)
        return needs_a_and_h(candidate, attempt)

    log = tmp_path / "runs.jsonl"
    result, calls = run(probe, log, deflake=3)
    assert result.minimal == ("a", "h")
    accepted = {frozenset(event.candidate): event for event in ProbeLog.load(log).own_events()
                if isinstance(event, events.Accept)}
    world = frozenset({"a", "b", "g", "h"})
    assert world in accepted and (accepted[world].runs, accepted[world].errors) == (2, 1), accepted.keys()
    tested = [event.candidate for event in ProbeLog.load(log).own_events() if isinstance(event, events.RateCheck)]
    assert all(frozenset(candidate) != world for candidate in tested), "an ERROR is not a non-failing run"
    ordered = next(candidate for candidate in fresh_runs(log) if frozenset(candidate) == world)
    assert fresh_runs(log)[ordered] == [2], "one confirming run: attempt 2"
    assert_evidence_is_fresh(log, calls)


def test_no_second_look_when_the_original_passes_one_of_its_first_runs(tmp_path: Path) -> None:
    """{'a'} fails 3 of its first 5 fresh runs; before a second look the original's first 5 are made, and one
    of them passes: the original is flaky, so the world's passes say nothing and the watch stops there."""

    def probe(candidate: tuple[str, ...], attempt: int) -> ProbeObservation:
        if candidate == ELEMENTS:
            return observation(attempt != 4, attempt)
        return lucky_without_b(0, 1, 3, 4, 6, 7, 8, 9)(candidate, attempt)

    log = tmp_path / "runs.jsonl"
    result, calls = run(probe, log)
    checks = [event for event in ProbeLog.load(log).own_events() if isinstance(event, events.RateCheck)]
    assert (checks[0].candidate, checks[0].reduced, checks[0].decision) == (("a",), (3, 5), "holds")
    assert fresh_runs(log)[ELEMENTS][:5] == [1, 2, 3, 4, 5], "the original's first look, made once"
    assert_evidence_is_fresh(log, calls)
