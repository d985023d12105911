"""The controller is the system under test: in the cul-de-sac world, the example's laser-guided controller
and the built-in go-to-goal law fail differently, and their failures need different models."""

from __future__ import annotations

from pathlib import Path

import pytest
from engines import installed

from pytest_ddenv.driver import ReductionPlan, run_reduction
from pytest_ddenv.driver.markers import ReductionSpec
from pytest_ddenv.driver.scenario_job import ScenarioJob
from pytest_ddenv.driver.user_code import import_user_code
from pytest_ddenv.execution import LocalPool
from pytest_ddenv.oracle import PredicateSpec, predicate_spec
from pytest_ddenv.scenario.probe import FailureReference
from pytest_ddenv.world import World

ROOT = Path(__file__).resolve().parent.parent


def reduce_with(job: ScenarioJob, world: World, folder: Path) -> tuple[object, list[str]]:
    with LocalPool(job, 1, in_process=job.handler()) as pool:
        original = pool.call(world, 0)
        assert original.error is not None and original.error.signature is not None
        plan = ReductionPlan(world=world, test_id="cul-de-sac", reference=FailureReference.of(original.error),
                             reference_run=original.run, spec=ReductionSpec(), artifacts=folder,
                             replay_command="", fingerprint={}, confirmed=True)
        outcome = run_reduction(plan, pool)
    assert outcome.reduction is not None
    return original.error.signature, list(outcome.reduction.minimal)


@pytest.mark.slow
def test_the_example_controller_and_go_to_goal_fail_differently_in_the_cul_de_sac(tmp_path: Path) -> None:
    example = import_user_code(str(ROOT / "examples" / "test_my_controller.py"))
    world = World.load(ROOT / "worlds" / "cul_de_sac.yaml")
    mine = ScenarioJob((predicate_spec(example.no_progress),), controller=example.Avoider())
    trapped, needed = reduce_with(mine, world, tmp_path / "mine")
    assert trapped.predicate == "no_progress"  # bouncing inside the U, in PyBullet touching nothing at the end;
    # MuJoCo's Husky turns faster and ends within 2 cm of a wall it bounces off (listed as touched, force 0)
    assert trapped.touched == () if installed("pybullet") else set(trapped.touched) <= {"left_wall", "right_wall"}
    assert needed == ["back_wall", "left_wall", "right_wall"]
    law = ScenarioJob((PredicateSpec("stuck", {"window": 5.0, "min_progress": 0.2}),))
    stuck, needed_by_law = reduce_with(law, world, tmp_path / "law")
    assert stuck.predicate == "stuck" and stuck.touched == ("back_wall",)  # nose against the back wall
    assert needed_by_law == ["back_wall"]
