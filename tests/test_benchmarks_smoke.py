"""Smoke test of the benchmark scripts' building blocks on a tiny yard (< 20 s).

benchmarks/ is not a package: the modules are imported from its directory, as the scripts import them.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parent.parent / "benchmarks"


@pytest.fixture(scope="module")
def bench():
    sys.path.insert(0, str(BENCHMARKS))
    try:
        import common
        import make_yard

        yield common, make_yard
    finally:
        sys.path.remove(str(BENCHMARKS))


@pytest.fixture(scope="module")
def problem(bench):
    common, make_yard = bench
    world = make_yard.make_yard(5, seed=0)
    with common.pool_of(1) as pool:
        yield common.make_problem(world, make_yard.PREDICATES, 0, pool)


def test_yard_is_seeded_and_sized(bench):
    _, make_yard = bench
    text = make_yard.yard_yaml(50, seed=3)
    assert text == make_yard.yard_yaml(50, seed=3)
    assert text != make_yard.yard_yaml(50, seed=4)
    world = make_yard.make_yard(50, seed=3)
    assert len(world.names) == 50
    assert set(make_yard.CULPRITS) <= set(world.names)


def test_original_yard_fails_with_stuck(problem):
    assert problem.failure.startswith("stuck")
    assert len(problem.reducible) == 5


def test_our_engine_finds_the_culprit(bench, problem):
    common, make_yard = bench
    row = common.ddenv_reduce(problem, partition="even", priority="sequential", deflake=0, workers=1,
                              failure_rate_runs=1)
    assert tuple(row.minimal) == make_yard.CULPRITS
    assert row.one_minimal
    assert row.failure_rate == (1, 1)
    assert 0 < row.simulations < 20
    assert row.to_dict()["reduction_percent"] == pytest.approx(80.0)


def test_picire_adapter_finds_the_culprit(bench, problem):
    pytest.importorskip("picire")
    common, make_yard = bench
    row = common.picire_reduce(problem, config_name="default", deflake=0, failure_rate_runs=0)
    assert tuple(row.minimal) == make_yard.CULPRITS
    assert row.one_minimal and not row.note
    assert row.simulations == row.extra["tests"] - row.extra["skipped"]
    assert row.extra["retests"] >= 1


def test_plain_text_table(bench):
    common, _ = bench
    text = common.table(["a", "bb"], [[1, 2], ["xyz", 4]])
    assert text.splitlines()[0] == "| a   | bb |"
    assert len(text.splitlines()) == 4
