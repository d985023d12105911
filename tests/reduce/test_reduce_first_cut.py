"""`first_cut`: one candidate tried before the rounds (the driver's cut by reach), judged like any other."""

from __future__ import annotations

import concurrent.futures
import json
from pathlib import Path

import pytest

from pytest_ddenv.errors import ReductionError
from pytest_ddenv.reduce import reduce

from .conftest import SetOracle, names


def records(path: Path, kind: str) -> list[dict]:
    return [record for line in path.read_text().splitlines() if (record := json.loads(line))["event"] == kind]


def test_a_cut_that_reproduces_is_adopted_in_one_trial_logged_and_resumed(tmp_path: Path) -> None:
    log = tmp_path / "runs.jsonl"
    world = names(40)
    kept = world[:10]
    oracle = SetOracle(frozenset({"m0003"}))
    result = reduce(world, oracle, deflake=0, first_cut=kept, log=log)
    assert result.minimal == ("m0003",) and result.one_minimal
    assert result.first_cut is not None and result.first_cut.holds
    assert (result.first_cut.original, result.first_cut.kept, result.first_cut.simulations) == (40, 10, 1)
    assert result.first_cut.describe() == "first cut by reach: 40 -> 10 models in 1 simulation"
    assert oracle.calls[0] == (kept, 0), "the cut is the first candidate simulated"
    rounds = [candidate for candidate, _ in oracle.calls[1:] if candidate != world]  # not the rate check's
    assert rounds and all(set(candidate) <= set(kept) for candidate in rounds), "the rounds start from it"
    (cut,) = records(log, "first-cut")
    assert (cut["original"], cut["kept"], cut["decision"], cut["simulations"]) == (40, 10, "holds", 1)
    assert records(log, "step")[0]["kind"] == "reach" and records(log, "step")[0]["size"] == 10
    assert result.simulations == len(oracle.calls), "the cut's simulation is counted"

    again = SetOracle(frozenset({"m0003"}))
    resumed = reduce(world, again, deflake=0, first_cut=kept, log=log)
    assert resumed.minimal == ("m0003",) and again.calls == [], "the resumed log answers, the cut included"
    assert resumed.first_cut is not None and resumed.first_cut.holds and resumed.first_cut.simulations == 0


def test_a_cut_that_does_not_reproduce_falls_back_to_the_whole_world(tmp_path: Path) -> None:
    log = tmp_path / "runs.jsonl"
    world = names(40)
    oracle = SetOracle(frozenset({"m0003", "m0030"}))  # m0030 matters but the cut drops it
    result = reduce(world, oracle, deflake=1, first_cut=world[:10], log=log)
    assert result.minimal == ("m0003", "m0030") and result.one_minimal
    assert result.first_cut is not None and not result.first_cut.holds
    assert result.first_cut.simulations == 2, "deflake=1: the cut is run again before it is rejected"
    assert "did not reproduce the failure (2 simulations); reduced from the whole world" in result.first_cut.describe()
    (cut,) = records(log, "first-cut")
    assert cut["decision"] == "does-not-hold"
    assert result.simulations == len(oracle.calls) and oracle.calls[:2] == [(world[:10], 0), (world[:10], 1)]


def test_a_cut_that_keeps_everything_is_not_tried() -> None:
    oracle = SetOracle(frozenset({"m0003"}))
    result = reduce(names(8), oracle, deflake=0, first_cut=names(8))
    assert result.first_cut is None and result.minimal == ("m0003",)


def test_the_cut_keeps_the_kept_elements() -> None:
    oracle = SetOracle(frozenset({"m0003"}))
    result = reduce(names(20), oracle, deflake=0, keep=("m0015",), first_cut=names(5))
    assert oracle.calls[0] == ((*names(5), "m0015"), 0)
    assert result.first_cut is not None and result.first_cut.kept == 6


@pytest.mark.parametrize(("given", "words"), [
    ("m0001", "first_cut: expected a collection of element names, not a string"),
    (("m0001", "nope"), "first_cut names elements that are not in the world: nope"),
])
def test_a_bad_cut_is_refused_naming_the_field(given: object, words: str) -> None:
    with pytest.raises(ReductionError, match=words):
        reduce(names(4), SetOracle(frozenset({"m0001"})), deflake=0, first_cut=given)  # type: ignore[arg-type]


def test_idle_workers_run_the_cuts_attempts_ahead_not_the_whole_worlds_round() -> None:
    world = names(40)
    oracle = SetOracle(frozenset({"m0003"}))
    with concurrent.futures.ThreadPoolExecutor(4) as threads:
        result = reduce(world, oracle, deflake=2, first_cut=world[:10], executor=threads, workers=4,
                        failure_rate_runs=0)
    assert result.minimal == ("m0003",) and result.first_cut is not None and result.first_cut.holds
    assert all(set(candidate) <= set(world[:10]) for candidate, _ in oracle.calls)
    assert result.simulations == len(oracle.calls)
