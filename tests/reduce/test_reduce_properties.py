"""Properties of `reduce` with synthetic (simulation-free) probes, checked by hypothesis."""

from __future__ import annotations

import dataclasses
from concurrent.futures import ThreadPoolExecutor
from types import ModuleType
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pytest_ddenv.reduce import PARTITIONS, PRIORITIES, VOLATILE_FIELDS, ProbeLog, Reduction, reduce

from .conftest import line_geometry, line_trace, names, uniform

PROPERTY_SETTINGS = settings(
    max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)


@st.composite
def scenarios(draw: st.DrawFn, max_size: int = 24) -> dict[str, Any]:
    size = draw(st.integers(1, max_size))
    elements = names(size)
    context = draw(st.sampled_from(["none", "geometry", "trace", "coincident", "empty-trace"]))
    geometry = None
    reference = None
    if context != "none":
        geometry = line_geometry(elements, coincident=context == "coincident")
    if context in ("trace", "coincident"):
        reference = line_trace(float(size), sensed={name: 0.1 * i for i, name in enumerate(elements[::2])})
    if context == "empty-trace":
        reference = line_trace(1.0, samples=0)
    return {
        "elements": elements,
        "geometry": geometry,
        "reference": reference,
        "partition": draw(st.sampled_from(PARTITIONS)),
        "priority": draw(st.sampled_from(PRIORITIES)),
        "granularity": draw(st.sampled_from(["ddmin", "paper"])),
        "n_partitions": draw(st.integers(2, 5)),
        "seed": draw(st.integers(0, 2**16)),
    }


def comparable(result: Reduction) -> Reduction:
    return dataclasses.replace(result, wall_time=0.0)


def stable_records(log: ProbeLog) -> list[dict[str, Any]]:
    return [{k: v for k, v in record.items() if k not in VOLATILE_FIELDS} for record in log.records]


def non_monotone(elements: tuple[str, ...], salt: int):  # type: ignore[no-untyped-def]
    """f for the original world and for a pseudo-random 30 % of the other sub-worlds."""
    original = frozenset(elements)
    return lambda config: config == original or uniform(config, 0, salt) < 0.3


@given(scenario=scenarios(), data=st.data())
@PROPERTY_SETTINGS
def test_monotone_failure_reduces_to_exactly_the_culprits(
    synthetic: ModuleType, scenario: dict[str, Any], data: st.DataObject
) -> None:
    elements = scenario["elements"]
    culprits = frozenset(data.draw(st.sets(st.sampled_from(elements), max_size=4)))
    oracle = synthetic.SetOracle(culprits, trace=scenario["reference"])
    result = reduce(probe=oracle, deflake=0, failure_rate_runs=2, **scenario)
    assert set(result.minimal) <= set(elements)
    assert result.minimal == tuple(name for name in elements if name in culprits)
    assert result.one_minimal and result.incomplete_reason is None
    assert result.failure_rate == (2, 2)
    # fresh runs: the minimal world's 2 (failing both: no run of the original can change the decision) and the
    # drift watch's two confirming runs of each accepted world followed by a rejection (deflake=0: one run accepts)
    fresh_runs = len(oracle.calls) - result.probes
    assert 2 <= fresh_runs <= 2 + 2 * max(0, len(result.steps) - 2)
    assert result.simulations == len(oracle.calls)
    assert len(set(oracle.calls)) == len(oracle.calls), "a (candidate, attempt) was simulated twice"
    sizes = [size for _, size in result.steps]
    assert sizes == sorted(sizes, reverse=True) and sizes[0] == len(elements)


@given(scenario=scenarios(), salt=st.integers(0, 10**6))
@PROPERTY_SETTINGS
def test_any_failure_reduces_to_a_failing_one_minimal_subset(
    synthetic: ModuleType, scenario: dict[str, Any], salt: int
) -> None:
    fails = non_monotone(scenario["elements"], salt)
    result = reduce(probe=synthetic.FunctionOracle(fails), deflake=0, failure_rate_runs=0, **scenario)
    minimal = frozenset(result.minimal)
    assert minimal <= set(scenario["elements"])
    assert fails(minimal), "the result does not reproduce the failure"
    assert result.one_minimal
    assert not any(fails(minimal - {name}) for name in minimal), "the result is not 1-minimal"


@given(scenario=scenarios(), salt=st.integers(0, 10**6), deflake=st.sampled_from([0, 2, "adaptive"]))
@PROPERTY_SETTINGS
def test_same_seed_gives_the_same_result_and_the_same_log(
    synthetic: ModuleType, scenario: dict[str, Any], salt: int, deflake: int | str
) -> None:
    culprits = frozenset(scenario["elements"][::3])
    runs = []
    for _ in range(2):
        log = ProbeLog(None)
        oracle = synthetic.SetOracle(culprits, rate=0.8, salt=salt, trace=scenario["reference"])
        result = reduce(probe=oracle, deflake=deflake, log=log, **scenario)
        runs.append((comparable(result), stable_records(log)))
    assert runs[0][0] == runs[1][0]
    assert runs[0][1] == runs[1][1]


@given(scenario=scenarios(), salt=st.integers(0, 10**6), other=st.sampled_from(PARTITIONS))
@PROPERTY_SETTINGS
def test_memoization_never_changes_the_result(
    synthetic: ModuleType, scenario: dict[str, Any], salt: int, other: str
) -> None:
    fails = non_monotone(scenario["elements"], salt)
    fresh = reduce(probe=synthetic.FunctionOracle(fails), deflake=0, **scenario)
    shared: dict[Any, Any] = {}
    warmup = dict(scenario, partition=other)
    reduce(probe=synthetic.FunctionOracle(fails), deflake=0, cache=shared, **warmup)
    oracle = synthetic.FunctionOracle(fails)
    cached = reduce(probe=oracle, deflake=0, cache=shared, **scenario)
    assert cached.minimal == fresh.minimal
    assert [size for _, size in cached.steps] == [size for _, size in fresh.steps]
    assert cached.probes <= fresh.probes
    again = reduce(probe=synthetic.FunctionOracle(fails), deflake=0, cache=shared, failure_rate_runs=0, **scenario)
    assert again.probes == 0 and again.minimal == fresh.minimal


@pytest.fixture(scope="module")
def pool() -> Any:
    with ThreadPoolExecutor(max_workers=3) as executor:
        yield executor


@given(scenario=scenarios(), salt=st.integers(0, 10**6), deflake=st.sampled_from([0, 3, "adaptive"]))
@PROPERTY_SETTINGS
def test_parallel_probing_never_changes_the_result(
    synthetic: ModuleType, pool: ThreadPoolExecutor, scenario: dict[str, Any], salt: int, deflake: int | str
) -> None:
    culprits = frozenset(scenario["elements"][1::4])
    serial = reduce(
        probe=synthetic.SetOracle(culprits, rate=0.7, salt=salt, trace=scenario["reference"]),
        deflake=deflake,
        **scenario,
    )
    oracle = synthetic.SetOracle(culprits, rate=0.7, salt=salt, trace=scenario["reference"])
    parallel = reduce(probe=oracle, deflake=deflake, executor=pool, workers=3, **scenario)
    assert len(oracle.calls) == len(set(oracle.calls)), "a (candidate, attempt) was simulated twice"
    assert parallel.minimal == serial.minimal
    assert [size for _, size in parallel.steps] == [size for _, size in serial.steps]
    assert parallel.one_minimal == serial.one_minimal
    assert parallel.failure_rate == serial.failure_rate


def _drift_backed_off(result: Reduction) -> bool:
    return any("drift watch" in note for note in result.notes)


def test_parallel_probing_after_a_drift_back_off_is_the_serial_reduction(
    synthetic: ModuleType, pool: ThreadPoolExecutor
) -> None:
    """A back-off of the drift watch in the middle of a concurrent round (salt 36 took another path before the
    round recorded its verdicts up to the first new rejection ahead of the watch)."""
    elements = tuple(f"m{index:04d}" for index in range(16))
    scenario: dict[str, Any] = {"elements": elements, "geometry": None, "reference": None, "partition": "learner",
                                "priority": "random", "granularity": "ddmin", "n_partitions": 4, "seed": 0}
    culprits = frozenset(elements[1::4])
    serial = reduce(probe=synthetic.SetOracle(culprits, rate=0.7, salt=36, trace=None), deflake=0, **scenario)
    parallel = reduce(probe=synthetic.SetOracle(culprits, rate=0.7, salt=36, trace=None), deflake=0,
                      executor=pool, workers=3, **scenario)
    assert _drift_backed_off(serial) and _drift_backed_off(parallel)
    assert [size for _, size in parallel.steps] == [size for _, size in serial.steps]
    assert parallel.minimal == serial.minimal


@given(scenario=scenarios(), salt=st.integers(0, 10**6))
@PROPERTY_SETTINGS
def test_parallel_non_monotone(
    synthetic: ModuleType, pool: ThreadPoolExecutor, scenario: dict[str, Any], salt: int
) -> None:
    fails = non_monotone(scenario["elements"], salt)
    serial = reduce(probe=synthetic.FunctionOracle(fails), deflake=0, **scenario)
    parallel = reduce(probe=synthetic.FunctionOracle(fails), deflake=0, executor=pool, workers=3, **scenario)
    assert parallel.minimal == serial.minimal
    assert [size for _, size in parallel.steps] == [size for _, size in serial.steps]
