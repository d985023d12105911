"""Limits that fit the world (issue 33): the automatic watchdog of runs not timed yet and of worlds bigger than
the timed ones; a run stopped by its wall-clock cap is an error of the run, never a verdict (`ddenv reduce
--run-timeout`, `ddenv run`, `ddenv replay`, and a test whose own failure is the cap)."""

from __future__ import annotations

import json
import textwrap
from pathlib import Path

import pytest

from pytest_ddenv.cli import main as cli
from pytest_ddenv.driver.scenario_job import ScenarioJob
from pytest_ddenv.driver.settings import RUN_TIMEOUT, SETTING
from pytest_ddenv.execution.base import (
    DEFAULT_RUN_CAP,
    FIRST_RUN_MARGIN,
    StatsBook,
    automatic_watchdog,
    run_cap_of,
    world_size,
)
from pytest_ddenv.oracle.verdict import ErrorInfo, FailureReference, classify_result, is_run_error
from pytest_ddenv.reduce import Outcome
from pytest_ddenv.scenario.robot_world import DEFAULT_MAX_WALL_TIME
from pytest_ddenv.world import World

from .conftest import STUCK, Project, records

WALL_WORLD = (Path(__file__).resolve().parents[1] / "data" / "wall.yaml").read_text(encoding="utf-8")
SLOW_PAST_THE_WALL = textwrap.dedent(
    """\
    import time

    from pytest_ddenv import Command

    TOUCHED = {"run": -1.0, "wall": False}


    def slow_past_the_wall(observation):
        # Where the wall stands the robot touches it at t ~ 1.9 s and is stuck at ~3 s; where it was removed,
        # the robot touches nothing and every control tick after t = 2.5 s takes 0.5 s of wall time.
        if observation.time < TOUCHED["run"]:  # a new run
            TOUCHED["wall"] = False
        TOUCHED["run"] = observation.time
        TOUCHED["wall"] = TOUCHED["wall"] or any(contact.model == "wall" for contact in observation.contacts)
        if observation.time > 2.5 and not TOUCHED["wall"]:
            time.sleep(0.5)
        return Command(linear=1.0, angular=max(-1.0, min(1.0, observation.goal_bearing)))
    """
)


# -- the automatic watchdog ----------------------------------------------------------------------------
def test_before_any_run_is_timed_the_watchdog_is_the_run_cap_plus_a_margin() -> None:
    book = StatsBook(1)
    assert book.watchdog(60.0, 10.0) == DEFAULT_RUN_CAP + FIRST_RUN_MARGIN  # not the 60 s floor
    assert book.watchdog(60.0, 10.0, run_cap=900.0) == 900.0 + FIRST_RUN_MARGIN
    assert book.watchdog(600.0, 10.0, run_cap=1.0) == 600.0  # the floor still holds
    book.completed(0.0, 2.0, size=100)  # once a run is timed: factor x the longest
    assert book.watchdog(60.0, 10.0, size=100, run_cap=900.0) == 60.0
    assert book.watchdog(10.0, 10.0, size=50) == 20.0


def test_a_world_bigger_than_the_timed_ones_gets_a_watchdog_scaled_by_its_size() -> None:
    book = StatsBook(1)
    book.expect(3.0, size=300)  # the original: 300 shapes in 3 s
    assert book.watchdog(60.0, 10.0, size=300) == 60.0
    assert book.watchdog(60.0, 10.0, size=3000) == pytest.approx(300.0)  # 10 x the shapes: 10 x the time
    book.completed(0.0, 8.0, size=30)  # a small world that was slow (a start-up) raises the longest only
    assert book.watchdog(1.0, 10.0, size=30) == 80.0
    assert book.watchdog(1.0, 10.0, size=3000) == pytest.approx(300.0)
    assert automatic_watchdog(60.0, 10.0, 0.0, (0, 0.0), 10**6, None) == DEFAULT_RUN_CAP + FIRST_RUN_MARGIN


def test_the_run_cap_and_the_size_come_from_the_job_and_the_world() -> None:
    assert run_cap_of(ScenarioJob((), max_wall_time=42.0)) == 42.0
    assert run_cap_of(ScenarioJob((), max_wall_time=None)) is None and run_cap_of(object()) is None
    assert DEFAULT_RUN_CAP == DEFAULT_MAX_WALL_TIME == RUN_TIMEOUT == SETTING["run_timeout"].default
    world = World.from_yaml(WALL_WORLD)
    assert world_size(world) == 6 and world_size(world.select(["wall"])) == 1


# -- the oracle ----------------------------------------------------------------------------------------
CAPPED = ErrorInfo("ControllerTimeout", "the run took more than its wall-clock limit of 1 s", "test_x.py:9")


def test_a_run_stopped_by_its_wall_clock_cap_is_an_error_never_a_verdict() -> None:
    assert is_run_error(CAPPED)
    for reference in (FailureReference("ControllerTimeout", "test_x.py:9"),
                      FailureReference("AssertionError", "test_x.py:9")):
        assert classify_result(CAPPED, reference, 0.5) is Outcome.ERROR
    asserted = ErrorInfo("AssertionError", "", "test_x.py:9")  # every other exception as before
    assert classify_result(asserted, FailureReference("AssertionError", "test_x.py:9"), 0.5) is Outcome.FAIL
    assert classify_result(asserted, FailureReference("AssertionError", "test_x.py:7"), 0.5) is Outcome.OTHER
    assert not is_run_error(asserted) and not is_run_error(None)


# -- real runs with a tiny cap ---------------------------------------------------------------------------
@pytest.fixture
def wall_project(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    (tmp_path / "wall.yaml").write_text(WALL_WORLD)
    (tmp_path / "slow_past_the_wall.py").write_text(SLOW_PAST_THE_WALL)
    monkeypatch.chdir(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    return tmp_path


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = cli.main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_ddenv_run_past_its_cap_is_an_error(capsys: pytest.CaptureFixture[str], wall_project: Path) -> None:
    code, out, err = run(capsys, "run", "wall.yaml", "-p", STUCK, "--run-timeout", "0.001", "--no-picture", "--json")
    data = json.loads(out)
    assert code == 1 and data["outcome"] == "error" and data["exception"] == "ControllerTimeout", err
    assert "ddenv run --run-timeout SECONDS" in data["message"]


def test_reduce_of_a_world_whose_original_run_passes_its_cap_says_it_cannot_be_reduced(
        capsys: pytest.CaptureFixture[str], wall_project: Path) -> None:
    code, out, err = run(capsys, "reduce", "wall.yaml", "-p", STUCK, "--run-timeout", "0.001", "--workers", "1",
                         "--out", "art", "--quiet", "--json")
    assert code == 1, err
    message = json.loads(out)["error"]
    assert "ControllerTimeout" in message and "cannot be reduced as a failure" in message
    assert "ddenv reduce --run-timeout SECONDS" in message and not (wall_project / "art" / "summary.json").exists()


@pytest.mark.slow  # a real reduction whose wall-less probes each run for the 3 s cap
def test_a_probe_stopped_by_the_wall_clock_cap_is_logged_as_an_error(capsys: pytest.CaptureFixture[str],
                                                                     wall_project: Path) -> None:
    code, out, err = run(capsys, "reduce", "wall.yaml", "-p", STUCK, "--import", "slow_past_the_wall.py",
                         "--controller", "slow_past_the_wall:slow_past_the_wall", "--run-timeout", "3",
                         "--workers", "1", "--deflake", "0", "--stages", "models", "--media", "none",
                         "--out", "art", "--quiet", "--json")
    summary = json.loads(out)
    assert code == 0 and summary["minimal_models"] == ["wall"], err
    probes = [r for r in records(wall_project / "art" / "runs.jsonl") if r.get("event") == "probe"]
    capped = [r for r in probes if "wall" not in r["candidate"]]
    assert capped and all(r["outcome"] == "error" for r in capped), capped
    assert all("ControllerTimeout" in r["detail"] and "wall-clock limit of 3 s" in r["detail"] for r in capped)
    assert summary["errors"] >= len(capped)  # counted as errors, and as simulations
    assert summary["workers"]["simulations"] >= len(probes)
    code, out, err = run(capsys, "replay", "art", "--runs", "2", "--run-timeout", "0.001", "--json")
    replayed = json.loads(out)
    assert code == 1 and replayed["errors"] == 2 and replayed["rate"] is None, out
    assert {r["outcome"] for r in replayed["runs"]} == {"error"}


@pytest.mark.slow  # pytest in a subprocess
def test_a_test_whose_own_failure_is_the_cap_is_not_reduced_and_says_why(project: Project) -> None:
    (project.path / "test_scenario.py").write_text(textwrap.dedent(
        """\
        import pytest

        @pytest.mark.ddenv(world='yard.yaml')
        @pytest.mark.robot_failure('stuck', window=2.0, min_progress=0.2)
        def test_reaches_goal(robot_world):
            assert robot_world.run(max_wall_time=0.001).reached_goal
        """))
    result = project.run(project.pytest_command("--ddenv-workers", "1"))
    assert result.returncode == pytest.ExitCode.TESTS_FAILED, result.stdout
    assert "cannot be reduced as a failure" in result.stdout and "No reduction was run" in result.stdout, \
        result.stdout


@pytest.mark.slow  # `ddenv reduce` in a subprocess beside a CPU burner
def test_bench_loaded_completes_a_small_yard_beside_a_burner(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.syspath_prepend(str(Path(__file__).resolve().parents[2] / "benchmarks"))
    import bench_loaded

    result = bench_loaded.measure(12, 0, 1, "1", None, tmp_path)
    assert result["completed"] and result["culprit_found"], result
    assert result["errors"] == 0 and result["watchdog_kills"] == 0 and result["simulations"] > 0
