"""What a stage may not change (`stages/structure.py`): how models stand to each other, and which models the
robot fails touching. Geometry and synthetic observations only; the real reductions are in
test_stages_keep_the_cause.py."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import pytest

from pytest_ddenv.outcome import Outcome
from pytest_ddenv.reduce import ProbeObservation
from pytest_ddenv.stages.attributes import proposals, simplified
from pytest_ddenv.stages.structure import clearance, keeps_structure, nearest_gaps, relation, touching_only
from pytest_ddenv.world import Model, Pose, Shape, World

HUSKY_WIDTH = 0.67


def post(name: str, x: float, y: float, radius: float = 0.15) -> Model:
    return Model(name, (Shape("cylinder", radius=radius, length=1.0),), pose=Pose(x, y, 0.5))


def gap_world(y: float = 0.45) -> World:
    return World(models=(post("left", 4.2, y), post("right", 4.2, -y)))


def test_clearance_tells_overlap_touch_and_gaps_apart() -> None:
    world = gap_world()
    assert clearance(world.model("left"), world.model("right"), None) == pytest.approx(0.6, abs=1e-3)
    assert clearance(post("a", 0, 0), post("b", 0.1, 0), None) < 0  # sharing space
    assert relation(clearance(post("a", 0, 0), post("b", 0.3, 0), None), HUSKY_WIDTH) == "touch"
    assert relation(0.6, HUSKY_WIDTH) == "narrow" and relation(0.7, HUSKY_WIDTH) == "wide"
    slab = Model("slab", (Shape("box", size=(4.0, 4.0, 0.1)),), pose=Pose(0, 0, 0.05))
    crate = Model("crate", (Shape("box", size=(0.5, 0.5, 0.5)),), pose=Pose(0, 0, 0.35))
    assert clearance(slab, crate, None) == math.inf  # resting on it: no common height, neither overlap nor gap


def test_rounding_two_posts_onto_one_another_is_refused_with_the_reason() -> None:
    world = gap_world()

    def build(kept: tuple[str, ...]) -> World:
        moved = {"left": 0.0, "right": 0.0}
        return dataclasses.replace(world, models=tuple(
            dataclasses.replace(m, pose=dataclasses.replace(m.pose, y=moved[m.name])) if m.name not in kept else m
            for m in world.models))

    check = keeps_structure(world, build, HUSKY_WIDTH)
    reason = check(())
    assert reason is not None and reason.startswith("changes left and right from a 0.60 m gap, narrower than the robot")
    assert "to sharing space: a different structure" in reason
    assert check(("left",)) is None  # only the right one moved: a 0.15 m gap, still narrower than the robot
    assert check(("left", "right")) is None  # nothing moved
    arm = keeps_structure(world, build, 0.2, "the arm's hand")(())  # an arm's: the gap is measured against its hand
    assert arm is not None
    assert arm.startswith("changes left and right from a 0.60 m gap, wider than the arm's hand (0.20 m)")


def test_no_position_or_size_is_rounded_on_a_grid_coarser_than_the_nearest_gap() -> None:
    world = gap_world()
    assert nearest_gaps(world) == {"left": pytest.approx(0.6, abs=1e-3), "right": pytest.approx(0.6, abs=1e-3)}
    offered = {p.name: p for p in proposals(world, None, Path("/nonexistent"))}
    assert offered["left:y"].after == "0.5" and offered["right:y"].after == "-0.5"  # the 0.5 m rung, not 1 m
    assert offered["left:x"].after == "4"  # 4.2 on the 0.5 m grid
    alone = World(models=(post("left", 4.2, 0.45),))
    assert {p.name: p for p in proposals(alone, None, Path("/nonexistent"))}["left:y"].after == "0"  # nothing near
    rounded = simplified(world, list(offered.values()))
    assert clearance(rounded.model("left"), rounded.model("right"), None) > 0.02


def observation(outcome: Outcome, touched: list[str]) -> ProbeObservation:
    return ProbeObservation(outcome, signature={"predicate": "stuck", "touched": touched, "pose": [0, 0, 0, 0, 0, 0]})


def test_a_failure_touching_a_model_the_world_never_failed_on_is_another_failure() -> None:
    seen: dict[str, ProbeObservation] = {
        "same": observation(Outcome.FAIL, ["left"]), "new": observation(Outcome.FAIL, ["left", "crate"]),
        "passes": ProbeObservation(Outcome.PASS),
    }
    probe = touching_only(lambda candidate, attempt: seen[candidate[0]], frozenset({"left", "right"}))
    assert probe(("same",), 0).outcome is Outcome.FAIL
    changed = probe(("new",), 0)
    assert changed.outcome is Outcome.OTHER and "a different structure" in changed.detail and "crate" in changed.detail
    assert probe(("passes",), 0).outcome is Outcome.PASS
    untouched = touching_only(lambda candidate, attempt: seen["new"], frozenset())
    assert untouched(("new",), 0).outcome is Outcome.FAIL  # the world failed touching nothing: no rule
