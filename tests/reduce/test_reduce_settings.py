"""`reduce(elements, probe, settings, *, geometry, reference, log, executor, on_progress)`: the settings in one
`ReductionSettings` object; the former keyword spelling gives the same reduction."""

from __future__ import annotations

import inspect

import pytest

import pytest_ddenv.reduce
from pytest_ddenv.errors import ReductionError
from pytest_ddenv.reduce import ReductionSettings, reduce

from .conftest import SetOracle, names

CULPRITS = frozenset({"m0004", "m0017"})


def test_reduce_takes_at_most_eight_parameters() -> None:
    parameters = inspect.signature(pytest_ddenv.reduce.reduce).parameters
    assert list(parameters) == ["elements", "probe", "settings", "geometry", "reference", "log", "executor",
                                "on_progress"]


def test_the_settings_object_and_the_keywords_reduce_alike() -> None:
    settings = ReductionSettings(deflake=0, max_probes=30, n_partitions=3, seed=4, failure_rate_runs=2)
    by_object = reduce(names(40), SetOracle(CULPRITS), settings)
    by_keywords = reduce(names(40), SetOracle(CULPRITS), deflake=0, max_probes=30, n_partitions=3, seed=4,
                         failure_rate_runs=2)
    assert by_object.minimal == by_keywords.minimal
    assert (by_object.probes, by_object.failure_rate) == (by_keywords.probes, by_keywords.failure_rate)


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda: reduce(names(4), SetOracle(CULPRITS), ReductionSettings(), deflake=0),
         "reduce(): deflake given beside settings=; put them in the ReductionSettings"),
        (lambda: reduce(names(4), SetOracle(CULPRITS), budget=3),
         "reduce() got an unknown argument 'budget'; its arguments are elements, probe, settings"),
        (lambda: reduce(names(4), SetOracle(CULPRITS), {"deflake": 0}),
         "settings: expected a ReductionSettings, got {'deflake': 0}"),
        (lambda: reduce(names(4), SetOracle(CULPRITS), ReductionSettings(n_partitions=1)),
         "n_partitions: expected an integer >= 2, got 1"),
    ],
)
def test_wrong_settings_are_named(call: object, message: str) -> None:
    with pytest.raises(ReductionError) as raised:
        call()  # type: ignore[operator]
    assert message in str(raised.value)
