"""The first cut by reach (pytest_ddenv/driver/reach.py) on real worlds and real runs, and through `ddenv reduce`."""

from __future__ import annotations

import dataclasses
import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from pytest_ddenv.driver import ReductionPlan, run_reduction
from pytest_ddenv.driver import run as driver_run
from pytest_ddenv.driver.markers import ReductionSpec
from pytest_ddenv.driver.reach import ReachCut, reach_cut
from pytest_ddenv.driver.scenario_job import ScenarioJob
from pytest_ddenv.execution import LocalPool
from pytest_ddenv.oracle import PredicateSpec, make_predicate
from pytest_ddenv.scenario.probe import FailureReference
from pytest_ddenv.scenario.reported import REPORTED
from pytest_ddenv.sim import Run, simulate
from pytest_ddenv.world import Model, Pose, Scenario, Shape, World

BENCHMARKS = Path(__file__).resolve().parent.parent / "benchmarks"
STUCK = "stuck:window=5,min_progress=0.2"


def yard(count: int) -> World:
    sys.path.insert(0, str(BENCHMARKS))
    try:
        import make_yard

        return make_yard.make_yard(count, seed=0)
    finally:
        sys.path.remove(str(BENCHMARKS))


def stuck_run(world: World) -> Run:
    return simulate(world, seed=0, predicates=[make_predicate("stuck", window=5.0, min_progress=0.2)])


@pytest.fixture(scope="module")
def yard_and_run() -> tuple[World, Run]:
    world = yard(300)
    return world, stuck_run(world)


def test_the_cut_keeps_every_model_the_robot_touched_or_sensed_and_drops_only_far_ones(
        yard_and_run: tuple[World, Run]) -> None:
    world, run = yard_and_run
    assert run.failure is not None and run.failure.predicate == "stuck"
    cut = reach_cut(world, run)
    assert cut.made and not cut.reason and len(cut.kept) + len(cut.dropped) == len(world)
    assert {"pocket_back", "pocket_left", "pocket_right"} <= set(cut.kept)
    assert set(run.first_touch) | set(run.first_sensed) <= set(cut.kept)
    assert set(run.first_sensed), "the laser saw some clutter: the cut must keep it"
    gaps = world.distances(run.positions, cut.dropped).min(axis=0)  # the shapes' true surfaces
    assert (gaps > cut.robot_reach).all()
    assert cut.robot_reach > run.settings.laser_range


def test_the_cut_world_runs_exactly_as_the_original(yard_and_run: tuple[World, Run]) -> None:
    world, run = yard_and_run
    again = stuck_run(world.select(reach_cut(world, run).kept))
    assert again.failure == run.failure
    assert np.array_equal(again.poses, run.poses) and again.first_sensed == run.first_sensed


def test_the_laser_range_counts_only_when_the_run_has_laser_rays(yard_and_run: tuple[World, Run]) -> None:
    world, run = yard_and_run
    blind = replace(run, settings=replace(run.settings, laser_rays=0))
    laser = run.settings.laser_range
    assert reach_cut(world, blind).robot_reach == pytest.approx(reach_cut(world, run).robot_reach - laser)
    assert set(reach_cut(world, blind).kept) < set(reach_cut(world, run).kept)


def box(name: str, at: tuple[float, float, float], size: float = 0.5, *, static: bool = True) -> Model:
    return Model(name, (Shape("box", size=(size, size, size)),), pose=Pose(*at), static=static,
                 mass=None if static else 1.0)


def ball(name: str, at: tuple[float, float, float], radius: float = 0.2) -> Model:
    return Model(name, (Shape("sphere", radius=radius),), pose=Pose(*at), static=False, mass=1.0)


def test_dynamic_models_and_the_static_models_they_may_reach_are_kept() -> None:
    world = World(models=(
        box("wall", (4.0, 0.0, 0.4), 0.8),          # on the path: the robot hits it
        ball("ball", (0.0, 30.0, 0.2)),             # far from the path, but it might roll
        box("ramp", (0.0, 31.0, 0.25)),             # next to the ball: it could deflect it
        box("far", (0.0, -60.0, 0.25)),             # far from the robot and from the ball
    ), scenario=Scenario(goal=(7.0, 0.0, None), timeout=3.0), name="ball")
    run = simulate(world, seed=0)
    cut = reach_cut(world, run)
    assert cut.kept == ("wall", "ball", "ramp") and cut.dropped == ("far",)
    still = World(models=world.models[:1] + world.models[2:], scenario=world.scenario, name="no ball")
    assert set(reach_cut(still, simulate(still, seed=0)).dropped) == {"ramp", "far"}, "the ball kept the ramp"


def test_the_cut_is_skipped_with_a_reason_when_the_reach_is_not_bounded(yard_and_run: tuple[World, Run]) -> None:
    world, run = yard_and_run
    for given, reason in [
        (None, "no run of the original world to bound the reach by"),
        (replace(run, robot_kind="arm"), "the robot is an arm: only a wheeled robot's reach is bounded"),
        (replace(run, engine=REPORTED), "the test ran a simulator of its own: its reach is unknown"),
        (replace(run, poses=np.zeros((0, 6))), "the original run recorded no trajectory"),
    ]:
        cut = reach_cut(world, given)
        assert cut.reason == reason and cut.kept == world.names and not cut.dropped and not cut.made


@pytest.mark.slow
def test_ddenv_reduce_of_a_300_object_yard_reports_the_cut_and_finds_the_back_wall(tmp_path: Path) -> None:
    from pytest_ddenv.cli.main import main as cli

    path = tmp_path / "yard.yaml"
    yard(300).save(path)
    out = tmp_path / "out"
    assert cli(["reduce", str(path), "-p", STUCK, "--media", "none", "--workers", "1", "--out", str(out),
                "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["minimal_models"] == ["pocket_back"] and summary["one_minimal"]
    cut = summary["first_cut"]
    assert cut["holds"] and cut["original"] == 300 and 3 <= cut["kept"] < 300 and cut["simulations"] >= 1
    logged = [json.loads(line) for line in (out / "runs.jsonl").read_text().splitlines()]
    (event,) = [record for record in logged if record["event"] == "first-cut"]
    assert event["decision"] == "holds" and event["kept"] == cut["kept"]
    probes = [record for record in logged if record["event"] == "probe"]
    assert any(record["size"] == cut["kept"] and record["attempt"] == 0 for record in probes)
    assert summary["simulations"] >= len(probes), "every simulation is counted, the cut's included"
    assert cli(["reduce", str(path), "-p", STUCK, "--media", "none", "--workers", "1", "--out", str(out),
                "--quiet"]) == 0  # resumed from its log: the cut's verdict is read, not simulated again
    again = json.loads((out / "summary.json").read_text())
    assert again["minimal_models"] == ["pocket_back"] and again["first_cut"]["holds"]
    assert again["first_cut"]["simulations"] == 0 and again["first_cut"]["kept"] == cut["kept"]


@pytest.mark.slow  # a reduction (the driver finds its code's identity with a subprocess)
def test_a_cut_that_does_not_reproduce_the_failure_falls_back_to_the_whole_world(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    world = World(models=(box("wall", (3.6, 0.0, 0.4), 0.8), box("left", (2.0, 4.0, 0.25)),
                          box("right", (2.0, -4.0, 0.25))),
                  scenario=Scenario(goal=(7.0, 0.0, None), timeout=15.0), name="wall")
    # a cut that drops what matters (as one that missed a rolling ball would): the probe says so
    monkeypatch.setattr(driver_run, "reach_cut", lambda world, run: ReachCut(("left", "right"), ("wall",), 12.0))
    job = ScenarioJob((PredicateSpec("stuck", {"window": 5.0, "min_progress": 0.2}),))
    with LocalPool(job, 1, in_process=job.handler()) as pool:
        original = pool.call(world, 0)
        assert original.error is not None and original.run is not None
        spec = dataclasses.replace(ReductionSpec(), stages=("models",))
        plan = ReductionPlan(world=world, test_id="wall", reference=FailureReference.of(original.error),
                             reference_run=original.run, spec=spec, artifacts=tmp_path, replay_command="",
                             fingerprint={}, confirmed=True, media="none")
        outcome = run_reduction(plan, pool)
    reduction = outcome.reduction
    assert reduction is not None and reduction.minimal == ("wall",) and reduction.one_minimal
    assert reduction.first_cut is not None and not reduction.first_cut.holds and reduction.first_cut.kept == 2
    assert reduction.first_cut.simulations >= 2, "the cut was re-run by the deflake rule before it was rejected"
    logged = [json.loads(line) for line in (tmp_path / "runs.jsonl").read_text().splitlines()]
    assert [record["decision"] for record in logged if record["event"] == "first-cut"] == ["does-not-hold"]
    cut_runs = [record for record in logged if record["event"] == "probe" and record["candidate"] == ["left", "right"]]
    assert len(cut_runs) == reduction.first_cut.simulations
    assert outcome.report is not None and outcome.report.cost.simulations >= reduction.simulations
