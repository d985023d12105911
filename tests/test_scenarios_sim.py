"""The shipped scenario worlds fail (or pass) in simulation as the paper's did. Slow: real runs."""

from __future__ import annotations

from pathlib import Path

import pytest

from pytest_ddenv.oracle import make_predicate
from pytest_ddenv.sim import simulate
from pytest_ddenv.world import World

WORLDS = Path(__file__).resolve().parent.parent / "worlds"
SEED = 0


def _predicates():
    return [make_predicate(n) for n in ("flipped", "high_centered", "stuck", "timeout")]


def _run(name: str):
    return simulate(World.load(WORLDS / f"{name}.yaml"), seed=SEED, predicates=_predicates())


@pytest.mark.slow
@pytest.mark.parametrize(
    ("name", "predicate", "touching"),
    [
        ("ditch", "stuck", "asphalt_plane_clone"),  # trapped nose-down in the gap, bumper on the far wall
        ("rubble", "high_centered", "cinder_block"),  # on a cinder block (either of the two)
        ("friction", "stuck", "Construction Barrel"),  # stuck at the barrels
    ],
)
def test_original_world_fails_with_its_failure(name: str, predicate: str, touching: str) -> None:
    run = _run(name)
    assert run.failure is not None, f"{name} did not fail"
    assert run.failure.predicate == predicate, run.failure.explain()
    assert any(touching in model for model in run.failure.touched), run.failure.explain()


@pytest.mark.slow
@pytest.mark.parametrize(
    "name",
    ["ditch_ground_only", "rubble_ground_only", "rubble_no_blocks", "friction_ground_only", "friction_no_barrels"],
)
def test_culprit_free_world_passes(name: str) -> None:
    run = _run(name)
    assert run.reached_goal, run.failure.explain() if run.failure else "no failure, no goal"
