"""The reduction engine on real simulations of the shipped ditch world, with each of the paper's pairings."""

from __future__ import annotations

from pathlib import Path

import pytest

from pytest_ddenv import World
from pytest_ddenv.oracle import PredicateSpec
from pytest_ddenv.oracle import classify
from pytest_ddenv.scenario.probe import keeps_start_support, make_probe, trace_of
from pytest_ddenv.reduce import Outcome, reduce
from pytest_ddenv.cli.replay import reference_of
from pytest_ddenv.driver.scenario_job import ScenarioJob, run_scenario

WORLDS = Path(__file__).resolve().parent.parent / "worlds"
STUCK = (PredicateSpec("stuck", {"window": 5.0, "min_progress": 0.2}),)
PAPER_PAIRINGS = [
    ("model2model", "failure-proximal"),
    ("model2model", "avg-trajectory-proximal"),
    ("timeseg", "avg-trajectory-proximal"),
]


@pytest.mark.slow
@pytest.mark.parametrize(("partition", "priority"), PAPER_PAIRINGS)
def test_ditch_reduces_to_a_one_minimal_world_that_fails_the_same_way(partition: str, priority: str) -> None:
    world = World.load(WORLDS / "ditch.yaml")
    original = run_scenario(world, STUCK, seed=0)
    reference = reference_of(original)
    probe = make_probe(world, ScenarioJob(STUCK, seed=0).handler(), reference, tolerance=0.5)
    reduction = reduce(
        world.names, probe, geometry=world, reference=trace_of(original), partition=partition,
        priority=priority, deflake=2, preconditions=(keeps_start_support(world),), seed=0,
    )
    assert reduction.one_minimal and reduction.incomplete_reason is None
    assert reduction.minimal_size <= 3 < 43 == reduction.original_size
    assert {"asphalt_plane", "asphalt_plane_clone"} <= set(reduction.minimal)  # the two sides of the gap
    replayed = run_scenario(world.select(reduction.minimal), STUCK, seed=0)
    assert classify(replayed, reference.signature, 0.5) is Outcome.FAIL
    assert reduction.failure_rate[0] >= 1
