"""The three tabletop scenarios (worlds/tabletop_*.yaml, examples/test_tabletop.py) on real PyBullet runs of the
Franka Panda and its default pick-and-place controller: each fails its own way because of the one object put
there for it, and the reduction finds that object, 1-minimal, whatever else is on the table or far from it.
"""

from __future__ import annotations

import importlib.util
import json
import shutil
import sys
import textwrap
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from pytest_ddenv import World
from pytest_ddenv.cli.replay import reference_of
from pytest_ddenv.driver.scenario_job import ScenarioJob, run_scenario
from pytest_ddenv.oracle import PredicateSpec, classify
from pytest_ddenv.reduce import Outcome, Reduction, reduce
from pytest_ddenv.reduce.context import Context
from pytest_ddenv.reduce.priority import make_prioritizer
from pytest_ddenv.reduce.rates import rate_drops
from pytest_ddenv.scenario.probe import keeps_start_support, make_probe, trace_of
from pytest_ddenv.sim import Run
from pytest_ddenv.stages import attributes, passing, scenario_models

ROOT = Path(__file__).resolve().parent.parent
NAMES = ("tall_box", "tight_grasp", "carry")
FRESH_SEEDS = range(100, 110)
"""Noise seeds no reduction uses: the failure rates of the original and the minimal world."""


@pytest.fixture(scope="module")
def bench() -> Iterator[ModuleType]:
    """benchmarks/bench_tabletop.py: the scenarios' worlds, predicates and causes, and `with_distractors`."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        import bench_tabletop

        yield bench_tabletop
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))


def scenario(bench: ModuleType, name: str) -> tuple[World, tuple[PredicateSpec, ...], tuple[str, ...]]:
    path, predicates, cause = bench.TABLETOP[name]
    return World.load(path), predicates, cause


def reduced(world: World, predicates: tuple[PredicateSpec, ...]) -> Reduction:
    """The engine's reduction of `world` with the plugin's probe, precondition and kept models (the arm's table
    and target), in this process (seed 0)."""
    original = run_scenario(world, predicates, seed=0)
    probe = make_probe(world, ScenarioJob(predicates, seed=0).handler(), reference_of(original))
    return reduce(world.names, probe, geometry=world, reference=trace_of(original), partition="model2model",
                  priority="avg-trajectory-proximal", deflake="auto", preconditions=(keeps_start_support(world),),
                  keep=scenario_models(world), seed=0)


def failures(world: World, predicates: tuple[PredicateSpec, ...], reference_run: Run) -> tuple[int, int]:
    """(runs that fail the same way as `reference_run`, runs) over the fresh noise seeds."""
    reference = reference_of(reference_run)
    outcomes = [classify(run_scenario(world, predicates, seed=seed), reference.signature) for seed in FRESH_SEEDS]
    return sum(outcome is Outcome.FAIL for outcome in outcomes), len(outcomes)


@pytest.mark.parametrize("name", NAMES)
def test_each_world_fails_its_own_way_and_passes_without_its_cause(bench: ModuleType, name: str) -> None:
    world, predicates, cause = scenario(bench, name)
    assert world.scenario is not None and 15 <= len(world) <= 30
    assert any(shape.kind == "mesh" for model in world.models for shape in model.shapes)
    run = run_scenario(world, predicates, seed=0)
    assert run.failure is not None and run.failure.predicate == predicates[0].name
    assert set(run.failure.touched) <= {*cause, world.scenario.target, world.scenario.table}
    assert run_scenario(world.without(cause), predicates, seed=0).reached_goal


def test_no_stage_removes_moves_or_freezes_an_arms_table_or_target(bench: ModuleType, tmp_path: Path) -> None:
    world, _, cause = scenario(bench, "tall_box")
    assert scenario_models(world) == ("table", "mug")
    final = world.select(("table", "mug", *cause))
    assert list(passing.differences(final, None)) == ["without cereal_box"]
    changed = {(p.model, p.attribute) for p in attributes.proposals(final, None, tmp_path)}
    assert {("cereal_box", "static"), ("cereal_box", "mass"), ("mug", "mass"), ("table", "friction")} <= changed
    assert not {(m, a) for m, a in changed if m in ("table", "mug") and a in ("x", "y", "yaw", "static", "size#0")}
    mobile = World.load(ROOT / "worlds" / "ditch.yaml")
    assert scenario_models(mobile) == ()


def test_the_schemas_see_the_end_effectors_path_and_the_carried_target(bench: ModuleType) -> None:
    world, predicates, cause = scenario(bench, "carry")
    run = run_scenario(world, predicates, seed=0)
    trace = trace_of(run)
    assert run.failure is not None and trace.carried is not None
    assert np.array_equal(trace.positions, run.positions) and trace.carried.shape == trace.positions.shape
    assert np.array_equal(trace.failure_position, np.asarray(run.failure.pose[:3]))  # the end effector's
    context = Context(elements=world.names, geometry=world, trace=trace)
    points = context.trace_points()
    assert points is not None and len(points[0]) == 2 * len(trace)
    distances = context.trace_distances(list(cause))
    assert distances is not None  # the bottle hangs below the fingers: it comes closer to the divider
    assert distances[len(trace):].min() < distances[: len(trace)].min()
    objects = [(name,) for name in world.names if name not in scenario_models(world)]
    for priority in ("min-trajectory-proximal", "failure-proximal"):
        assert make_prioritizer(priority)(objects, context, 0)[0] == cause, priority


@pytest.mark.slow
@pytest.mark.parametrize("name", NAMES)
def test_each_world_reduces_to_its_cause_one_minimal_and_fails_as_often(bench: ModuleType, name: str) -> None:
    world, predicates, cause = scenario(bench, name)
    assert world.scenario is not None
    reduction = reduced(world, predicates)
    assert reduction.one_minimal and reduction.incomplete_reason is None
    assert set(reduction.minimal) == {world.scenario.table, world.scenario.target, *cause}
    original = run_scenario(world, predicates, seed=0)
    minimal = world.select(reduction.minimal)
    assert classify(run_scenario(minimal, predicates, seed=0), reference_of(original).signature) is Outcome.FAIL
    original_rate = failures(world, predicates, original)
    minimal_rate = failures(minimal, predicates, original)
    assert not rate_drops(minimal_rate, original_rate), (minimal_rate, original_rate)


@pytest.mark.slow
def test_twenty_distractors_far_from_the_arm_change_nothing_and_cost_little(bench: ModuleType) -> None:
    world, predicates, _ = scenario(bench, "tall_box")
    plain = reduced(world, predicates)
    cluttered = reduced(bench.with_distractors(world), predicates)
    assert len(cluttered.minimal) == len(plain.minimal) and set(cluttered.minimal) == set(plain.minimal)
    assert cluttered.one_minimal
    assert cluttered.simulations <= 1.3 * plain.simulations, (cluttered.simulations, plain.simulations)


USER_ARM_TEST = textwrap.dedent(
    """\
    import math

    import pytest

    from pytest_ddenv.oracle import signature
    from pytest_ddenv.sim.arm.control import EndEffectorTarget

    HIGH = 0.3


    class StraightOver:
        \"\"\"The controller under test: over the target at 0.3 m, straight down, close, up, over the place
        region, down, open.\"\"\"

        def reset(self, observation):
            self.phase, self.since = "over", observation.time
            self.pick = observation.target_pose[:3]

        def __call__(self, observation):
            x, y, z = self.pick
            px, py = observation.place[:2]
            goals = {"over": ((x, y, z + HIGH), "open"), "down": ((x, y, z), "open"), "close": ((x, y, z), "close"),
                     "up": ((x, y, z + HIGH), "close"), "carry": ((px, py, z + HIGH), "close"),
                     "lower": ((px, py, z + 0.01), "close"), "open": ((px, py, z + 0.01), "open")}
            goal, gripper = goals[self.phase]
            waited = observation.time - self.since
            there = math.dist(observation.end_effector[:3], goal) < 0.01
            done = waited > 1.0 if self.phase == "close" else there or waited > 5.0
            if done and self.phase != "open":
                self.phase, self.since = list(goals)[list(goals).index(self.phase) + 1], observation.time
            return EndEffectorTarget(goal, 0.0, gripper)


    class TouchesClutter:
        \"\"\"The test's own predicate: any link touches a model other than the target and the table.\"\"\"

        name = "touches_clutter"

        def reset(self):
            pass

        def check(self, state):
            other = [m for m in state.touched if m not in (state.target, state.table)]
            return signature(self.name, state, f"touched {', '.join(other)}") if other else None


    @pytest.mark.ddenv(world="tabletop_tall_box.yaml", deflake=1)
    @pytest.mark.robot_failure(TouchesClutter())
    def test_picks_the_mug(robot_world):
        assert robot_world.run(controller=StraightOver()).reached_goal
    """
)


@pytest.fixture
def user_arm_project(pytester: pytest.Pytester) -> pytest.Pytester:
    world = (ROOT / "worlds" / "tabletop_tall_box.yaml").read_text()
    pytester.makefile(".yaml", tabletop_tall_box=world)
    (pytester.path / "meshes").mkdir()
    for mesh in (ROOT / "worlds" / "meshes").glob("tabletop_*.obj"):
        (pytester.path / "meshes" / mesh.name).write_bytes(mesh.read_bytes())
    pytester.makepyfile(test_arm=USER_ARM_TEST)
    return pytester


@pytest.mark.slow
def test_user_arm_controller_and_predicate_reduce_to_the_same_world_however_probes_run(
        user_arm_project: pytest.Pytester) -> None:
    ways = [[], ["--ddenv-workers", "1"], ["-n", "2"]]
    if importlib.util.find_spec("distributed") is not None:  # not imported here: see conftest.py
        ways.append(["--ddenv-executor", "dask", "--ddenv-workers", "2"])
    minimal = []
    for how in ways:
        result = user_arm_project.runpytest_subprocess("--ddenv-reduce", "--ddenv-media", "none", *how)
        result.assert_outcomes(failed=1)
        result.stdout.fnmatch_lines(["*'touches_clutter' predicate fired*", "*reduced 18 -> 3 models*"])
        (summary_path,) = Path(user_arm_project.path, "ddenv-artifacts").glob("*/summary.json")
        summary = json.loads(summary_path.read_text())
        assert summary["one_minimal"] and summary["errors"] == 0, how
        minimal.append(summary["minimal_models"])
    assert all(models == ["table", "mug", "cereal_box"] for models in minimal), minimal


TALL_BOX_TEST = textwrap.dedent(
    """\
    import pytest


    @pytest.mark.ddenv(world="tabletop_tall_box.yaml", stages="all")
    @pytest.mark.robot_failure("arm_collision")
    def test_picks_the_mug(robot_world):
        assert robot_world.run().reached_goal
    """
)


@pytest.mark.slow
def test_the_stages_run_on_an_arm_world_and_leave_its_table_and_target_alone(
        user_arm_project: pytest.Pytester) -> None:
    user_arm_project.makepyfile(test_arm=TALL_BOX_TEST)
    result = user_arm_project.runpytest_subprocess("--ddenv-reduce", "--ddenv-media", "none", "--ddenv-workers", "1")
    result.assert_outcomes(failed=1)
    (summary_path,) = Path(user_arm_project.path, "ddenv-artifacts").glob("*/summary.json")
    summary = json.loads(summary_path.read_text())
    assert summary["minimal_models"] == ["table", "mug", "cereal_box"] and summary["errors"] == 0
    assert summary["precondition_kept"] == [] and summary["without_precondition_kept"] is None
    findings = {stage["stage"]: stage["findings"] for stage in summary["stages"]["results"]}
    assert "an arm's base does not move along its path: no later start is tried" in findings["time"]
    assert "without mug: not run: the scenario names it (an arm's table or target), it is no culprit" in \
        findings["explain"]
    assert any(line.startswith("without cereal_box: passes") for line in findings["explain"])
    assert any(line.startswith("nearest passing world: without cereal_box") for line in findings["passing"])
    moved = tuple(f"{model}: {what}" for model in ("mug", "table") for what in ("x ", "y ", "yaw ", "size", "static"))
    assert not any(line.startswith(moved) for line in findings["attributes"]), findings["attributes"]


@pytest.mark.slow
def test_the_tabletop_examples_reduce_to_their_causes(pytester: pytest.Pytester) -> None:
    """`pytest examples --ddenv-reduce` on examples/test_tabletop.py, as the README runs it."""
    (pytester.path / "examples").mkdir()
    (pytester.path / "examples" / "test_tabletop.py").write_bytes((ROOT / "examples" / "test_tabletop.py").read_bytes())
    shutil.copytree(ROOT / "worlds", pytester.path / "worlds")
    result = pytester.runpytest_subprocess("examples", "--ddenv-reduce", "--ddenv-media", "none")
    result.assert_outcomes(failed=3)
    minimal = {}
    for path in Path(pytester.path, "ddenv-artifacts").glob("*/summary.json"):
        summary = json.loads(path.read_text())
        assert summary["one_minimal"] and summary["errors"] == 0, summary["test"]
        minimal[summary["test"].rsplit("::", 1)[1]] = summary["minimal_models"]
    assert minimal == {
        "test_panda_picks_the_mug_behind_the_cereal_box": ["table", "mug", "cereal_box"],
        "test_panda_grasps_the_block_beside_the_juice_box": ["table", "block", "juice_box"],
        "test_panda_carries_the_bottle_over_the_divider": ["table", "bottle", "divider"],
    }
