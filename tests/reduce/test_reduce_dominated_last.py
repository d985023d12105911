"""A round tries last the candidates inside a candidate that did not reproduce f (issue 33, friction): for a
monotone failure they cannot reproduce it either. They are reordered, never skipped, so results stay
1-minimal for any failure (tests/reduce/test_reduce_properties.py, test_reduce_grown_removal.py). Synthetic
outcomes, no physics."""

from __future__ import annotations

from pathlib import Path

from .test_drift_watch import assert_evidence_is_fresh, fresh_runs, needs_a_and_h, run


def test_the_subsets_inside_a_rejected_half_are_tried_after_the_complements(tmp_path: Path) -> None:
    log = tmp_path / "runs.jsonl"
    result, calls = run(needs_a_and_h, log)
    assert result.minimal == ("a", "h") and result.one_minimal and result.rate_backoffs == 0
    # round 0 rejects both halves; round 1's subsets (a b, c d, e f, g h) are each inside one of them, so its
    # complements go first, and the second one is accepted: no subset of round 1 is simulated
    assert [("".join(candidate), attempt) for candidate, attempt in calls[:4]] == [
        ("abcd", 0), ("efgh", 0), ("abcdef", 0), ("abcdgh", 0)]
    assert result.probes == 12, "16 when round 1 tried its subsets first"
    assert_evidence_is_fresh(log, calls)


def test_a_candidate_an_earlier_round_planned_but_never_reached_starts_the_drift_watch(tmp_path: Path) -> None:
    """'g h' is one of round 1's subsets, not reached there (round 1 adopts a complement first). The round of
    'a b g h' decides it for the first time: that is the round's first new rejection, so the world 'a b g h'
    gets its confirming runs (attempts 1 and 2) as every accepted world does."""
    log = tmp_path / "runs.jsonl"
    result, calls = run(needs_a_and_h, log)
    rejected = calls.index((("g", "h"), 0))
    assert rejected == calls.index((("a", "b", "g", "h"), 0)) + 1
    assert calls[rejected + 1:rejected + 3] == [(("a", "b", "g", "h"), 1), (("a", "b", "g", "h"), 2)], (
        "confirmed right at that rejection, not a round later")
    assert fresh_runs(log)[("a", "b", "g", "h")] == [1, 2]
    assert result.simulations == len(calls) == result.probes + sum(map(len, fresh_runs(log).values()))
