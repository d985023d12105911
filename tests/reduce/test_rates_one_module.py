"""One failure-rate statistics module (issue 29, point 6): the engine's comparison, the stages' "the rate
drops", the deflake rule's sizing and `ddenv replay`'s interval all compute in `pytest_ddenv.reduce.rates`."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import pytest_ddenv
from pytest_ddenv.reduce import rates
from pytest_ddenv.reduce.deflake import CalibratedReruns, ConfirmedRuns
from pytest_ddenv.reduce.rates import Rate, chance_at_most, estimated, looks_up_to, wilson_interval

PACKAGE = Path(pytest_ddenv.__file__).parent


def test_only_the_rates_module_does_failure_rate_statistics() -> None:
    """No other module imports a statistical test or distribution (scipy.stats) or sums binomial terms."""
    elsewhere = []
    for path in sorted(PACKAGE.rglob("*.py")):
        if path == Path(rates.__file__):
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("scipy.stats"):
                elsewhere.append(f"{path.relative_to(PACKAGE)}: from {node.module} import ...")
            if isinstance(node, ast.Attribute) and node.attr == "comb":
                elsewhere.append(f"{path.relative_to(PACKAGE)}:{node.lineno}: math.comb")
    assert elsewhere == []


def test_the_stages_and_the_engine_share_the_rate_functions() -> None:
    from pytest_ddenv import stages
    from pytest_ddenv.reduce import rate_check

    assert stages.rate_drops is rates.rate_drops and rate_check.looks_up_to is rates.looks_up_to
    assert looks_up_to(12) == (5, 10, 12) and looks_up_to(0) == ()


def test_the_binomial_tail_and_the_estimate() -> None:
    assert estimated(Rate(3, 3)) == pytest.approx(0.875) and estimated(Rate(0, 5)) == pytest.approx(0.5 / 6)
    assert chance_at_most(0, 3, 0.5) == pytest.approx(0.125)
    assert chance_at_most(3, 3, 0.3) == pytest.approx(1.0)
    # the deflake rule sized from them, as docs/algorithm.md §6 says
    rule = CalibratedReruns().rule_for
    assert [rule(3, 3), rule(5, 5), rule(3, 5), rule(2, 5), rule(1, 5)] == [
        ConfirmedRuns(3, 2), ConfirmedRuns(3, 2), ConfirmedRuns(6, 2), ConfirmedRuns(6, 1), ConfirmedRuns(10, 1)]


def test_the_wilson_interval() -> None:
    low, high = wilson_interval(Rate(3, 10), 0.95)
    assert (round(low, 4), round(high, 4)) == (0.1078, 0.6032)
    assert wilson_interval(Rate(0, 0), 0.95) == (0.0, 1.0)
