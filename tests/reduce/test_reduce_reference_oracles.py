"""picire's three reference oracles over elements 1..8 (delta-debugging.md §1.3) and the cost figures.

Each oracle has exactly one 1-minimal failing subset, so any correct 1-minimal reducer must return it,
whatever its partition, priority, granularity or parallelism.
"""

from __future__ import annotations

import itertools
import statistics
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from types import ModuleType

import pytest

from pytest_ddenv.reduce import PARTITIONS, PRIORITIES, reduce

ELEMENTS = tuple(str(i) for i in range(1, 9))


def case_a(config: frozenset[str]) -> bool:
    """Contains 5 and 8, except that a config containing 7 but not 2 does not fail (non-monotone)."""
    return {"5", "8"} <= config and not ("7" in config and "2" not in config)


def case_b(config: frozenset[str]) -> bool:
    return len(config) > 0 and set(ELEMENTS) <= config


def case_c(config: frozenset[str]) -> bool:
    return {"1", "2", "3", "4", "6", "8"} <= config


CASES: list[tuple[str, Callable[[frozenset[str]], bool], tuple[str, ...]]] = [
    ("a", case_a, ("5", "8")),
    ("b", case_b, ELEMENTS),
    ("c", case_c, ("1", "2", "3", "4", "6", "8")),
]


def test_the_answers_are_the_unique_one_minimal_subsets() -> None:
    for _, oracle, expected in CASES:
        one_minimal = [
            subset
            for size in range(len(ELEMENTS) + 1)
            for subset in itertools.combinations(ELEMENTS, size)
            if oracle(frozenset(subset)) and not any(oracle(frozenset(subset) - {e}) for e in subset)
        ]
        assert one_minimal == [expected]


@pytest.mark.parametrize("case, oracle, expected", CASES, ids=[case for case, _, _ in CASES])
@pytest.mark.parametrize("partition", PARTITIONS)
def test_every_schema_finds_the_unique_answer(
    synthetic: ModuleType,
    case: str,
    oracle: Callable[[frozenset[str]], bool],
    expected: tuple[str, ...],
    partition: str,
) -> None:
    geometry = synthetic.line_geometry(ELEMENTS)
    trace = synthetic.line_trace(8.0)
    for priority, granularity, n_partitions in itertools.product(PRIORITIES, ("ddmin", "paper"), (2, 8)):
        for with_context in (False, True):
            result = reduce(
                ELEMENTS,
                synthetic.FunctionOracle(oracle),
                geometry=geometry if with_context else None,
                reference=trace if with_context else None,
                partition=partition,
                priority=priority,
                granularity=granularity,
                n_partitions=n_partitions,
                deflake=0,
                failure_rate_runs=0,
            )
            assert result.minimal == expected, (priority, granularity, n_partitions, with_context)
            assert result.one_minimal


@pytest.mark.parametrize("case, oracle, expected", CASES, ids=[case for case, _, _ in CASES])
def test_parallel_finds_the_unique_answer(
    synthetic: ModuleType, case: str, oracle: Callable[[frozenset[str]], bool], expected: tuple[str, ...]
) -> None:
    with ThreadPoolExecutor(max_workers=4) as executor:
        for partition in PARTITIONS:
            result = reduce(
                ELEMENTS, synthetic.FunctionOracle(oracle), partition=partition, deflake=0, executor=executor,
                workers=4,
            )
            assert result.minimal == expected


@pytest.mark.parametrize("case, oracle, expected", CASES, ids=[case for case, _, _ in CASES])
def test_probe_counts_on_picire_oracles(
    synthetic: ModuleType,
    case: str,
    oracle: Callable[[frozenset[str]], bool],
    expected: tuple[str, ...],
    record_property: Callable[[str, object], None],
) -> None:
    result = reduce(ELEMENTS, synthetic.FunctionOracle(oracle), partition="even", priority="sequential", deflake=0)
    record_property(f"probes_case_{case}", result.probes)
    print(f"picire case {case}: {result.probes} probes (picire default 30/29/35, skip+backward 24/17/21)")
    assert result.minimal == expected


def test_1024_elements_one_culprit_needs_at_most_30_probes(
    synthetic: ModuleType, record_property: Callable[[str, object], None]
) -> None:
    elements = synthetic.names(1024)
    counts = []
    for trial in range(20):
        culprit = elements[(trial * 389 + 17) % 1024]
        oracle = synthetic.SetOracle(frozenset({culprit}))
        result = reduce(elements, oracle, partition="even", priority="sequential", deflake=0, failure_rate_runs=0)
        assert result.minimal == (culprit,)
        assert result.probes <= 30
        counts.append(result.probes)
    # the default schemas without geometry (model2model falls back to an even split)
    result = reduce(elements, synthetic.SetOracle(frozenset({elements[700]})), deflake=0, failure_rate_runs=0)
    assert result.minimal == (elements[700],) and result.probes <= 30
    record_property("probes_1024_1_mean", statistics.mean(counts))
    print(f"1024 elements, 1 culprit: mean {statistics.mean(counts):.1f}, max {max(counts)} probes")


def test_1024_elements_one_culprit_with_geometry(synthetic: ModuleType) -> None:
    elements = synthetic.names(1024)
    geometry = synthetic.line_geometry(elements)
    oracle = synthetic.SetOracle(frozenset({elements[333]}))
    result = reduce(elements, oracle, geometry=geometry, deflake=0, failure_rate_runs=0)
    assert result.minimal == (elements[333],)
    assert result.probes <= 30


def test_1024_elements_eight_culprits_probe_count(
    synthetic: ModuleType, record_property: Callable[[str, object], None]
) -> None:
    import random

    elements = synthetic.names(1024)
    counts = []
    for trial in range(10):
        culprits = frozenset(random.Random(trial).sample(elements, 8))
        result = reduce(
            elements,
            synthetic.SetOracle(culprits),
            partition="even",
            priority="sequential",
            deflake=0,
            failure_rate_runs=0,
        )
        assert set(result.minimal) == culprits and result.one_minimal
        counts.append(result.probes)
    mean = statistics.mean(counts)
    record_property("probes_1024_8_mean", mean)
    print(
        f"1024 elements, 8 culprits: mean {mean:.1f} probes over 10 sets (complement-only ddmin 292, "
        f"picire 219-330, adaptive deletion 137)"
    )
    assert mean < 400  # a regression guard, well above the measured ~274
