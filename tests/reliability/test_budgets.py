"""Exact budgets and honest counts: a probe budget bounds every simulation (speculative, calibration,
confirmation and picture runs included), the time budget stops a running probe, deflake is bounded, a resumed
run reports its whole history, and worker statistics belong to one reduction."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from pytest_ddenv import World
from pytest_ddenv.driver import ReductionPlan, run_reduction
from pytest_ddenv.errors import ReductionError
from pytest_ddenv.driver.markers import ReductionSpec
from pytest_ddenv.scenario.probe import FailureReference

from .conftest import HANG_ONCE, PAUSE, YARD_WORLD, Project, records, scenario_test

pytestmark = pytest.mark.slow  # real reductions (subprocesses, simulations): the full tier only


def probe_records(log: Path) -> list[dict]:
    return [r for r in records(log) if r.get("event") == "probe"]


def test_a_probe_budget_bounds_every_simulation(project: Project) -> None:
    (project.path / "test_scenario.py").write_text(scenario_test(deflake="auto"))
    result = project.run(project.pytest_command("--ddenv-workers", "2", "--ddenv-max-probes", "10"))
    assert result.returncode == pytest.ExitCode.TESTS_FAILED, result.stdout
    summary = project.summary()
    assert summary["incomplete_reason"] == "budget: max_probes" and summary["one_minimal"] is False
    assert summary["workers"]["simulations"] <= 10, "speculative, prefetched and calibration runs included"
    assert summary["simulations"] == summary["this_run"]["simulations"] == summary["workers"]["simulations"]
    assert len(probe_records(project.log())) <= 10
    assert summary["failure_rate"]["runs"] + summary["probes"] <= 10
    assert "incomplete (budget: max_probes)" in result.stdout


@pytest.mark.parametrize("workers", ["1", "2"])
def test_the_time_budget_stops_a_running_probe(project: Project, workers: str) -> None:
    """The first smaller candidate hangs (a test body sleeping for an hour) and the probe watchdog is the
    default (60 s at least): the 8 s time budget must stop that probe, not wait for it."""
    (project.path / "test_scenario.py").write_text(scenario_test(body=HANG_ONCE))
    result = project.run(project.pytest_command("--ddenv-workers", workers, "--ddenv-max-time", "8"))
    assert result.returncode == pytest.ExitCode.TESTS_FAILED, result.stdout
    summary = project.summary()
    assert summary["incomplete_reason"] == "budget: max_seconds", summary
    assert summary["errors"] == 0, "a probe stopped by the budget is no error"
    assert summary["workers"]["cancelled"] >= 1 and summary["workers"]["timeouts"] == 0
    assert (project.path / "hung.flag").exists()
    assert World.load(project.folder() / "minimal.yaml").names == tuple(summary["minimal_models"])


class NoSimulations:
    """A pool that fails the test if anything is simulated."""

    size = 1
    in_process = True

    def call(self, world: World, attempt: int, **options: object) -> None:
        raise AssertionError("nothing may be simulated")


def test_an_absurd_deflake_is_refused_before_any_simulation(tmp_path: Path) -> None:
    world = World.from_yaml(YARD_WORLD, source="yard.yaml")
    plan = ReductionPlan(world=world, test_id="t", reference=FailureReference("RobotFailure", "t.py:1"),
                         reference_run=None, spec=ReductionSpec(deflake=10**12), artifacts=tmp_path / "art",
                         replay_command="", fingerprint={})
    with pytest.raises(ReductionError, match="deflake: expected at most 100 re-runs per candidate, got 1000000000000"):
        run_reduction(plan, NoSimulations())  # type: ignore[arg-type]
    assert not (tmp_path / "art").exists()


def test_a_resumed_run_reports_the_whole_history(project: Project) -> None:
    first = project.run(project.pytest_command("--ddenv-workers", "1", "--ddenv-max-probes", "5"))
    assert first.returncode == pytest.ExitCode.TESTS_FAILED
    partial = project.summary()
    assert partial["incomplete_reason"] == "budget: max_probes" and partial["probes"] >= 1

    resumed = project.run(project.pytest_command("--ddenv-workers", "1"))
    assert resumed.returncode == pytest.ExitCode.TESTS_FAILED
    summary = project.summary()
    found = probe_records(project.log())
    decided = [r for r in found if r["purpose"] in ("reduce", "calibration")]
    assert summary["resumed_probes"] == partial["probes"] and summary["resumed_runs"] == 1
    assert summary["probes"] == len(decided) > partial["probes"], "the whole history, not this run's alone"
    assert summary["simulations"] == len(found), "one worker: every simulation is in the log"
    assert summary["simulations"] == partial["simulations"] + summary["this_run"]["simulations"]
    assert summary["cpu_seconds"] >= summary["this_run"]["cpu_seconds"] > 0 and summary["cpu_seconds_complete"]
    assert f"{summary['probes']} probes, {summary['simulations']} simulations" in resumed.stdout


def test_worker_statistics_are_per_reduction(project: Project) -> None:
    (project.path / "test_scenario.py").write_text(
        scenario_test(body=PAUSE, name="test_one") + "\n\n" + scenario_test(body=PAUSE, name="test_two")
    )
    result = project.run(project.pytest_command("--ddenv-workers", "2"))
    assert result.returncode == pytest.ExitCode.TESTS_FAILED and "2 failed" in result.stdout, result.stdout
    logs = sorted(project.path.glob("ddenv-artifacts/*/runs.jsonl"))
    assert len(logs) == 2
    own = [len(probe_records(log)) for log in logs]
    for index, log in enumerate(logs):
        summary = json.loads((log.parent / "summary.json").read_text())
        assert own[index] <= summary["workers"]["simulations"] < own[index] + own[1 - index], (own, summary["workers"])
        assert summary["workers"]["workers"] == 2
