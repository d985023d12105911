"""The paper's three scenarios in MuJoCo (issue 30), as tests/test_paper_regression.py checks them in PyBullet:
each world fails for the same reason as there (the predicate, where, and the model that makes it), reduces to a
comparable minimal world, and a run is bit-identical in two fresh processes. Recorded with mujoco 4.0.0
(docs/scenarios-tuning.md, "In MuJoCo")."""

from __future__ import annotations

import dataclasses
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

pytest.importorskip("mujoco", reason="needs mujoco: pip install \"pytest-ddenv[mujoco]\"")

from pytest_ddenv.driver import ReductionOutcome, ReductionPlan, run_reduction
from pytest_ddenv.driver.markers import ReductionSpec
from pytest_ddenv.driver.scenario_job import ScenarioJob
from pytest_ddenv.execution import LocalPool
from pytest_ddenv.oracle import PredicateSpec
from pytest_ddenv.scenario.probe import FailureReference, ProbeResult
from pytest_ddenv.world import World

WORLDS = Path(__file__).resolve().parent.parent / "worlds"
STUCK = PredicateSpec("stuck", {"window": 5.0, "min_progress": 0.2})


@dataclasses.dataclass(frozen=True)
class Recorded:
    predicates: tuple[PredicateSpec, ...]
    partition: str
    seed: int
    predicate: str
    position: tuple[float, float, float]
    cause: str
    """The model the failure is about: it is touched when the predicate fires, and kept by the reduction."""
    minimal: tuple[str, ...]
    backoffs: int = 0


RECORDED = {
    # trapped nose-down in the gap against the far plateau (PyBullet: stuck at 9.5 s at (1.44, -0.65, 0.95),
    # touching asphalt_plane_clone and the pads; minimal world the two plateaus, as here)
    "ditch": Recorded((STUCK,), "model2model", 0, "stuck", (1.4353, -0.9679, 0.9581), "asphalt_plane_clone",
                      ("asphalt_plane", "asphalt_plane_clone")),
    # high-centred on the cinder block (PyBullet: at 4.25 s at (-0.78, -0.75, 0.27); minimal world the ground
    # tile, two boards and cinder_block_0; here one board)
    "rubble": Recorded((PredicateSpec("high_centered", {}), STUCK), "timeseg", 0, "high_centered",
                       (-0.3991, -0.7158, 0.2733), "cinder_block_0",
                       ("asphalt_plane", "lumber_2x4x48_clone_3_clone_0_clone_1_clone_clone_4", "cinder_block_0")),
    # pinned against Construction Barrel_1 (PyBullet: at 9.65 s at (0.67, 0.10, 0.41); minimal world two tiles and
    # Construction Barrel_1, after one back-off of the rate check; here the start tile, another and the barrel)
    "friction": Recorded((STUCK,), "model2model", 0, "stuck", (0.6169, 0.2083, 0.4084), "Construction Barrel_1",
                         ("grey_wall", "asphalt_plane_0", "Construction Barrel_1")),
}


def first_failure(name: str, pool: LocalPool) -> tuple[World, ProbeResult]:
    """The world in MuJoCo and its first run (attempt 0), which fails with a predicate."""
    world = World.load(WORLDS / f"{name}.yaml").with_engine("mujoco")
    original = pool.call(world, 0)
    assert original.run is not None and original.run.engine == "mujoco"
    assert original.error is not None and original.error.signature is not None, "the world did not fail"
    return world, original


def in_pool(name: str) -> tuple[ScenarioJob, Recorded]:
    recorded = RECORDED[name]
    return ScenarioJob(recorded.predicates, seed=recorded.seed), recorded


@pytest.mark.parametrize("name", sorted(RECORDED))
def test_the_paper_world_fails_in_mujoco_for_the_same_reason(name: str) -> None:
    job, recorded = in_pool(name)
    with LocalPool(job, 1, in_process=job.handler()) as pool:
        _, original = first_failure(name, pool)
    signature = original.error.signature
    assert signature.predicate == recorded.predicate
    assert signature.position == pytest.approx(recorded.position, abs=0.1)
    assert recorded.cause in signature.touched


def reduce_in_mujoco(name: str, artifacts: Path) -> ReductionOutcome:
    """The reduction of the world's first failing run in MuJoCo, as tests/test_paper_regression.py reduces in
    PyBullet (one in-process worker, the examples' partition)."""
    job, recorded = in_pool(name)
    with LocalPool(job, 1, in_process=job.handler()) as pool:
        world, original = first_failure(name, pool)
        spec = dataclasses.replace(ReductionSpec(), partition=recorded.partition, seed=recorded.seed)
        plan = ReductionPlan(
            world=world, test_id=name, reference=FailureReference.of(original.error), reference_run=original.run,
            spec=spec, artifacts=artifacts, replay_command="", fingerprint={}, confirmed=True,
        )
        return run_reduction(plan, pool)


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(RECORDED))
def test_the_paper_world_reduces_in_mujoco_as_recorded(name: str, tmp_path: Path) -> None:
    outcome = reduce_in_mujoco(name, tmp_path)
    recorded = RECORDED[name]
    assert outcome.reduction is not None and tuple(outcome.reduction.minimal) == recorded.minimal
    assert recorded.cause in outcome.reduction.minimal
    assert outcome.reduction.one_minimal
    assert outcome.reduction.rate_check is not None and outcome.reduction.rate_check.decision == "holds"
    assert outcome.reduction.rate_backoffs == recorded.backoffs


def test_a_paper_world_runs_the_same_in_two_fresh_processes() -> None:
    code = textwrap.dedent(
        """
        import hashlib
        from pytest_ddenv.oracle import make_predicate
        from pytest_ddenv.sim import simulate
        from pytest_ddenv.world import World
        world = World.load(WORLDS).with_engine("mujoco")
        run = simulate(world, seed=0, predicates=[make_predicate("stuck", window=5.0, min_progress=0.2)])
        print(run.engine, hashlib.sha1(run.poses.tobytes() + run.velocities.tobytes()
                                      + run.wheel_contacts.tobytes()).hexdigest(), sorted(run.first_touch))
        """
    ).replace("WORLDS", repr(str(WORLDS / "friction.yaml")))
    outputs = [subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
               .stdout.strip().splitlines()[-1] for _ in range(2)]
    assert outputs[0].startswith("mujoco ") and "Construction Barrel_1" in outputs[0]
    assert outputs[0] == outputs[1]
