"""The oracle on real simulations: one failure told apart from other failures of the same robot."""

from __future__ import annotations

from engines import in_engine
from helpers import ditch_world

from pytest_ddenv.oracle import classify, make_predicate
from pytest_ddenv.reduce.types import Outcome
from pytest_ddenv.sim import simulate


def test_trapped_in_gap_vs_fell_off_edge_vs_blocked_by_wall(physics_engine: str) -> None:
    """Real simulations of a small ditch, in each engine: only the two-plateau world reproduces f."""
    def run(world):
        return simulate(in_engine(world, physics_engine), seed=0,
                        predicates=[make_predicate("flipped"), make_predicate("stuck")])

    reference = run(ditch_world())
    assert reference.failure is not None and reference.failure.predicate == "stuck"
    assert classify(run(ditch_world()), reference.failure) == Outcome.FAIL
    fell_off = run(ditch_world(far=False))  # drives off the edge, lands on the bare ground
    blocked = run(ditch_world(near=False))  # starts on the ground, blocked by the far plateau's wall
    assert fell_off.failure is not None and blocked.failure is not None
    assert classify(fell_off, reference.failure) == Outcome.OTHER
    assert classify(blocked, reference.failure) == Outcome.OTHER
