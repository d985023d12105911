"""The grown removal (issue 33, rubble any-of-1): after carried rounds in a row adopted their first candidate,
the engine removes the next 2, 4, 8, ... parts at once instead of one part per probe.

The case it is for (rubble, seed 1 of the benchmark, any-of-1): one element masks the failure and sits with
the culprits in every part until the parts are single elements; once the finest round has removed it, every
other element can go, and plain ddmin removes them one per probe."""

from __future__ import annotations

from pytest_ddenv.reduce import reduce

from .conftest import FunctionOracle, names


def masked(count: int) -> tuple[tuple[str, ...], FunctionOracle, set[str]]:
    """`count` elements; f iff both culprits (elements 0 and 2) are present and element 1 is not."""
    elements = names(count)
    culprits = {elements[0], elements[2]}
    return elements, FunctionOracle(lambda candidate: culprits <= candidate and elements[1] not in candidate), culprits


def test_after_the_masking_element_the_rest_goes_in_a_few_probes() -> None:
    elements, oracle, culprits = masked(64)
    result = reduce(elements, oracle, deflake=0, failure_rate_runs=0, partition="even", priority="sequential")
    assert set(result.minimal) == culprits and result.one_minimal
    (found_at, size), *later = result.steps[1:]
    assert size == 63  # the finest round removed the masking element
    # one element per probe would take 61 probes (310 in all); growing removals of 2, 4, 8, ... parts: 12
    assert result.steps[-1][0] - found_at <= 12
    # (199 in all: the rounds before try the candidates inside a rejected one last; the last 2 are the single
    # removals of the minimal world, no longer decided on the way)
    assert result.probes - found_at <= 14
    assert any(before - after > 1 for (_, before), (_, after) in zip(result.steps[1:], later, strict=False))
    assert result.probes == len(oracle.calls)

