"""The same-failure rule (`oracle.SameFailureRule`, issue 27): the default rule, the place only, the touched
models only, a user's function; per test and per predicate; why a failure is other; recorded and re-applied;
the original world's rare reproduction said up front. Synthetic signatures and log records (no simulation);
the dithering robot end to end is tests/plugin/test_plugin_same_failure.py."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from typing import Any

import pytest

from pytest_ddenv.driver.markers import MarkerError, ReductionSpec, parse_ddenv_marker, parse_failure_markers
from pytest_ddenv.oracle import (
    FailureSignature,
    SameFailureError,
    SameFailureRule,
    classify,
    most_common_reason,
    same_failure_match,
    why_other,
)
from pytest_ddenv.driver.other_failures import original_reproduction, other_failures
from pytest_ddenv.scenario.probe import ErrorInfo, FailureReference, check_rule, classify_result, why_not_reproduced
from pytest_ddenv.reduce import Outcome, Reduction, events
from pytest_ddenv.driver.report import Cost, ReductionReport, ReportFiles
from pytest_ddenv.cli.replay import ArtifactError, recorded_rule
from pytest_ddenv.driver.report_text import result_lines

REF = FailureSignature("no_goal_progress", 13.85, (1.35, 0.0, 0.15, 0.0, 0.0, 0.0), ("wall",))


def at(x: float, touched: tuple[str, ...] = (), predicate: str = "no_goal_progress") -> FailureSignature:
    return FailureSignature(predicate, 13.8, (x, 0.0, 0.15, 0.0, 0.0, 0.0), touched)


def same_place(reference: FailureSignature, signature: FailureSignature) -> bool:
    """A user's rule: the same predicate within 0.5 m."""
    return signature.predicate == reference.predicate and math.dist(signature.position, reference.position) < 0.5


def says_maybe(reference: FailureSignature, signature: FailureSignature) -> Any:
    return "maybe"


def breaks(reference: FailureSignature, signature: FailureSignature) -> bool:
    raise KeyError("pose")


def never(reference: FailureSignature, signature: FailureSignature) -> bool:
    return False


def one_argument(signature: FailureSignature) -> bool:
    return True


# -- the verdict ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("failure", "expected"),
    [
        (at(1.30, ("wall",)), {"all": True, "place": True, "touched": True}),
        (at(1.30), {"all": False, "place": True, "touched": False}),  # dithering: not touching at that moment
        (at(1.30, ("crate",)), {"all": False, "place": True, "touched": False}),
        (at(0.30, ("wall",)), {"all": False, "place": False, "touched": True}),  # 1.05 m away, against the wall
        (at(0.30), {"all": False, "place": False, "touched": False}),
        (at(1.35, ("wall",), predicate="collided"), {"all": False, "place": False, "touched": False}),
    ],
)
def test_each_built_in_match_checks_its_part_of_the_signature(failure: FailureSignature,
                                                               expected: dict[str, bool]) -> None:
    for match, same in expected.items():
        assert SameFailureRule(match).same(failure, REF) is same, match
        verdict = classify(_Failed(failure), REF, SameFailureRule(match))  # type: ignore[arg-type]
        assert (verdict is Outcome.FAIL) is same


class _Failed:  # classify only reads `.failure`
    def __init__(self, failure: FailureSignature) -> None:
        self.failure = failure


def test_a_reference_that_touched_nothing_matches_any_contact_by_default_and_none_by_touched() -> None:
    untouched = dataclasses.replace(REF, touched=())
    assert SameFailureRule("all").same(at(1.3, ("wall",)), untouched)
    assert SameFailureRule("touched").same(at(0.3), untouched)
    assert not SameFailureRule("touched").same(at(1.3, ("wall",)), untouched)
    assert why_other(at(1.3, ("wall",)), untouched, SameFailureRule("touched")).text == (  # type: ignore[union-attr]
        "the same predicate fired but touching wall (the reference touched no model)")


def test_a_predicates_own_match_takes_precedence_for_its_failures_only() -> None:
    rule = SameFailureRule("all", 0.5, (("no_goal_progress", "place"),))
    assert rule.same(at(1.3), REF)
    stuck = dataclasses.replace(REF, predicate="stuck")
    assert not rule.same(at(1.3, predicate="stuck"), stuck)  # the test's rule for the other predicates


def test_a_user_function_decides_with_the_reference_first() -> None:
    rule = SameFailureRule(f"{__name__}:same_place")
    assert rule.same(at(1.3), REF) and not rule.same(at(0.3, ("wall",)), REF)
    reason = why_other(at(0.3, ("wall",)), REF, rule)
    assert reason is not None and reason.text == f"{__name__}:same_place returned False"


def test_a_user_function_that_breaks_or_does_not_say_yes_or_no_is_a_clear_error() -> None:
    with pytest.raises(SameFailureError, match=r"breaks raised KeyError: 'pose' \(reference no_goal_progress"):
        SameFailureRule(f"{__name__}:breaks").same(at(1.3), REF)
    with pytest.raises(SameFailureError, match=r"says_maybe returned str 'maybe'; expected True or False"):
        SameFailureRule(f"{__name__}:says_maybe").same(at(1.3), REF)
    reference = FailureReference("RobotFailure", "t.py:3", REF)
    with pytest.raises(SameFailureError, match=r"says the failure being reduced .* is not the same as itself"):
        check_rule(reference, SameFailureRule(f"{__name__}:never"))
    check_rule(reference, SameFailureRule("touched"))  # every built-in rule matches the reference itself


# -- what the user gives --------------------------------------------------------------------------------------
def test_a_match_is_a_built_in_name_or_a_module_level_function_held_by_its_name() -> None:
    assert same_failure_match("place", "x") == "place"
    assert same_failure_match(same_place, "x") == f"{__name__}:same_place"
    assert same_failure_match(f"{__name__}:same_place", "x") == f"{__name__}:same_place"

    def local(reference: FailureSignature, signature: FailureSignature) -> bool:
        return True

    problems = {
        "places": "expected one of 'all', 'place', 'touched' or a module-level function",
        3: "expected one of",
        (lambda reference, signature: True): "<lambda> is not a module-level function; define it at module level",
        local: "function_held_by_its_name.<locals>.local is not a module-level function",
        print: "print is not a function",
        one_argument: "one_argument must take two arguments, (reference, signature)",
        f"{__name__}:missing": f"module {__name__} has no function 'missing'",
        "no_such_module_xyz:f": "the same-failure function no_such_module_xyz:f cannot be imported",
    }
    for value, message in problems.items():
        with pytest.raises(SameFailureError, match=r"^where: .*" + message.replace("(", r"\(").replace(")", r"\)")):
            same_failure_match(value, "where")


def test_the_markers_take_the_rule_per_test_and_per_predicate() -> None:
    spec = parse_ddenv_marker((), {"same_failure": same_place, "tolerance": 0.3})
    assert spec.same_failure == f"{__name__}:same_place"
    (predicate,) = parse_failure_markers([(("stuck",), {"window": 2.0, "same_failure": "place"})])
    assert predicate.params == {"window": 2.0} and predicate.same_failure == "place"
    assert predicate.to_json() == {"name": "stuck", "params": {"window": 2.0}, "same_failure": "place"}
    assert spec.same_failure_rule((predicate,)) == SameFailureRule(f"{__name__}:same_place", 0.3, (("stuck", "place"),))
    assert ReductionSpec().same_failure_rule() == SameFailureRule()
    with pytest.raises(MarkerError, match=r"^ddenv\(same_failure=...\): expected one of"):
        parse_ddenv_marker((), {"same_failure": "placed"})
    with pytest.raises(MarkerError, match=r"^robot_failure\('stuck', same_failure=...\): .*<lambda> is not a"):
        parse_failure_markers([(("stuck",), {"same_failure": lambda reference, signature: True})])


# -- why other ----------------------------------------------------------------------------------------------
def test_why_other_names_the_part_of_the_rule_a_failure_missed() -> None:
    rule = SameFailureRule()
    assert why_other(at(1.3, ("wall",)), REF, rule) is None
    reasons = {
        "predicate": why_other(at(1.3, ("wall",), predicate="collided"), REF, rule),
        "far": why_other(at(0.3, ("wall",)), REF, rule),
        "no model": why_other(at(1.3), REF, rule),
        "other model": why_other(at(1.3, ("crate",)), REF, rule),
        "both": why_other(at(0.3), REF, rule),
    }
    texts = {key: None if reason is None else reason.text for key, reason in reasons.items()}
    assert texts == {
        "predicate": "another predicate fired: collided (the reference: no_goal_progress)",
        "far": "the same predicate fired 1.05 m from the reference failure (more than 0.5 m)",
        "no model": "the same predicate fired at the same place (0.05 m away) but touching no model (the reference "
                    "touched wall)",
        "other model": "the same predicate fired at the same place (0.05 m away) but touching crate, not wall",
        "both": "the same predicate fired 1.05 m from the reference failure (more than 0.5 m) and touching no model "
                "(the reference touched wall)",
    }
    assert reasons["no model"].advice == "consider same_failure='place'"  # type: ignore[union-attr]
    assert reasons["far"].advice == "consider a larger tolerance or same_failure='touched'"  # type: ignore[union-attr]
    assert why_other(at(0.3), REF, SameFailureRule("place")).advice == "consider a larger tolerance"  # type: ignore[union-attr]


def test_the_reason_seen_most_is_counted_over_every_run() -> None:
    rule = SameFailureRule()
    reasons = [why_other(at(1.3 - k / 100), REF, rule) for k in range(3)] + [why_other(at(0.3, ("wall",)), REF, rule)]
    assert most_common_reason([r for r in reasons if r is not None], 5) == (
        "the same predicate fired at the same place but touching no model in 3 of 5 runs (the reference touched "
        "wall); consider same_failure='place'")
    assert most_common_reason([], 5) == ""


def test_a_probe_that_passed_or_raised_says_so() -> None:
    reference = FailureReference("RobotFailure", "t.py:3", REF)
    rule = SameFailureRule()
    assert why_not_reproduced(None, reference, rule).summary == "the test passed (no failure)"  # type: ignore[union-attr]
    raised = why_not_reproduced({"exception": "KeyError", "location": "t.py:9"}, reference, rule)
    assert raised is not None
    assert raised.text == "the test raised KeyError at t.py:9 (the reference: no_goal_progress at t=13.8 s)"
    asserted = FailureReference("AssertionError", "t.py:9")
    assert why_not_reproduced({"exception": "AssertionError", "location": "t.py:9"}, asserted, rule) is None
    assert why_not_reproduced(at(1.3).to_dict(), asserted, rule).summary == (  # type: ignore[union-attr]
        "the 'no_goal_progress' predicate fired instead")


def test_classify_result_takes_a_rule_or_a_tolerance() -> None:
    reference = FailureReference("RobotFailure", "t.py:3", REF)
    error = ErrorInfo("RobotFailure", "", "t.py:3", signature=at(1.3))
    assert classify_result(error, reference, 0.5) is Outcome.OTHER
    assert classify_result(error, reference, SameFailureRule("place")) is Outcome.FAIL


# -- recorded ------------------------------------------------------------------------------------------------
def test_the_rule_is_recorded_as_plain_json_and_read_back() -> None:
    rule = SameFailureRule(f"{__name__}:same_place", 0.3, (("stuck", "place"),))
    data = json.loads(json.dumps(rule.to_json()))
    assert data == {"match": f"{__name__}:same_place", "tolerance": 0.3, "predicates": {"stuck": "place"}}
    assert SameFailureRule.from_json(data) == rule
    assert recorded_rule({"same_failure": data}, Path("s.json")) == rule
    assert recorded_rule({"tolerance": 0.7}, Path("s.json")) == SameFailureRule(tolerance=0.7)  # an older summary
    with pytest.raises(ArtifactError, match=r"s.json: same_failure: the same-failure function gone_module_xyz:f "
                                            r"cannot be imported"):
        recorded_rule({"same_failure": {"match": "gone_module_xyz:f"}}, Path("s.json"))
    with pytest.raises(ArtifactError, match="tolerance"):
        recorded_rule({"same_failure": {"match": "all", "tolerance": -1}}, Path("s.json"))


# -- the report ---------------------------------------------------------------------------------------------
ORIGINAL = ("far_box", "wall")


def record(outcome: str, attempt: int, signature: FailureSignature | None, *, purpose: str = "failure-rate",
           candidate: tuple[str, ...] = ORIGINAL, **extra: Any) -> events.Probe:
    return events.Probe(purpose=purpose, candidate=candidate, attempt=attempt, seed=attempt, outcome=outcome,
                        signature=None if signature is None else signature.to_dict(), **extra)


def test_the_original_worlds_rare_reproduction_is_said_with_the_reason_seen_most() -> None:
    reference = FailureReference("RobotFailure", "t.py:3", REF)
    purposes = ((1, "calibration"), (2, "calibration"), (3, "calibration"), (4, "failure-rate"))
    records = [record("other", attempt, at(1.3 - attempt / 100), purpose=purpose) for attempt, purpose in purposes]
    records += [record("fail", 5, at(1.35, ("wall",))),
                record("other", 1, at(1.3), purpose="failure-rate"),  # a resumed duplicate: counted once
                record("error", 6, None), record("other", 7, at(1.3), stage="shapes"),  # left out
                record("other", 8, at(1.3), candidate=("wall",)), record("other", 0, at(1.3), purpose="confirmation")]
    note = original_reproduction(records, ORIGINAL, reference, SameFailureRule())
    assert note is not None and (note.fails, note.runs) == (1, 5)
    assert note.describe() == (
        "the original world failed the same way in only 1 of 5 fresh runs: the same predicate fired at the same "
        "place but touching no model in 4 of 5 runs (the reference touched wall); consider same_failure='place'")
    mostly = [record("fail", attempt, at(1.3)) for attempt in (1, 2, 3)] + [record("other", 4, at(0.3))]
    assert original_reproduction(mostly, ORIGINAL, reference, SameFailureRule("place")) is None  # 3 of 4
    assert original_reproduction(records[:2], ORIGINAL, reference, SameFailureRule()) is None  # too few runs


def test_the_failure_itself_is_never_an_other_failure_and_each_says_why(tmp_path: Path) -> None:
    reference = FailureReference("RobotFailure", "t.py:3", REF)
    records = [record("other", 1, at(1.3)), record("other", 2, at(1.3, ("crate",))),
               record("other", 3, at(0.3, ("wall",)))]
    default = other_failures(records, rule=SameFailureRule(), reference=reference)
    no_model = ("the same predicate fired at the same place (0.05 m away) but touching no model (the reference "
                "touched wall)")
    assert [(g.probes, g.why) for g in default] == [
        (2, no_model), (1, "the same predicate fired 1.05 m from the reference failure (more than 0.5 m)")]
    by_place = other_failures(records, rule=SameFailureRule("place"), reference=reference)
    assert [g.signature.position[0] for g in by_place if g.signature] == [0.3]  # the dithering runs are f itself
    assert other_failures(records, rule=SameFailureRule(f"{__name__}:same_place"), reference=reference)[0].why == (
        f"{__name__}:same_place returned False")
    report = _report(tmp_path, default, original_reproduction(records, ORIGINAL, reference, SameFailureRule()))
    lines = result_lines(report)
    assert lines[0].startswith("warning: the original world failed the same way in only 0 of 3 fresh runs: the same "
                               "predicate fired at the same place but touching no model in 1 of 3 runs")
    rule_line = ("same failure: no_goal_progress within 0.5 m, touching one of the models the reference touched "
                 "(the default rule)")
    assert rule_line in lines
    assert "  not the failure: the same predicate fired 1.05 m from the reference failure (more than 0.5 m)" in lines
    summary = json.loads(json.dumps(report.to_json()))
    assert summary["same_failure"] == {"match": "all", "tolerance": 0.5, "predicates": {}}
    assert summary["original_reproduction"]["fails"] == 0 and summary["other_failures"][0]["why"]
    place = dataclasses.replace(report, same_failure=SameFailureRule("place", 0.5, (("no_goal_progress", "place"),)))
    assert "same failure: no_goal_progress within 0.5 m, whatever it touches (same_failure='place')" in \
        result_lines(place)


def _report(folder: Path, others: Any, reproduction: Any) -> ReductionReport:
    reduction = Reduction(
        original=ORIGINAL, minimal=("wall",), kept=(), probes=4, cache_hits=0, skipped=0, errors=0,
        steps=((0, 2), (4, 1)), one_minimal=True, incomplete_reason=None, failure_rate=(0, 5), wall_time=1.0,
        partition="model2model", priority="sequential", granularity="ddmin", deflake=1, seed=0)
    files = ReportFiles(folder / "minimal.yaml", folder / "runs.jsonl", folder / "summary.json")
    return ReductionReport(test="t", world="w.yaml", reduction=reduction,
                           reference_failure=FailureReference("RobotFailure", "t.py:3", REF).to_dict(), replay="r",
                           fingerprint="f", files=files, cost=Cost(4, 6, 1.0), tolerance=0.5, other_failures=others,
                           reproduction=reproduction)
