"""Watchdogs everywhere: a hung test body becomes an ERROR outcome (in worker processes and in-process), a
worker killed again and again is reported and never taken for a verdict, and Ctrl-C with a hung probe and
two workers ends pytest with the journal intact."""

from __future__ import annotations

import json
import signal
import time
from pathlib import Path

import pytest

from .conftest import (
    HANG_GUARD,
    HANG_ONCE,
    Project,
    kill_group,
    records,
    scenario_test,
    session_processes,
    wait_for,
)

pytestmark = pytest.mark.slow  # real reductions (subprocesses, simulations): the full tier only

WALL_WORLD = (Path(__file__).resolve().parents[1] / "data" / "wall.yaml").read_text(encoding="utf-8")


@pytest.mark.parametrize("workers", ["1", "2"])
def test_a_hung_test_body_becomes_an_error_and_the_reduction_finishes(project: Project, workers: str) -> None:
    (project.path / "test_scenario.py").write_text(scenario_test(body=HANG_ONCE))
    result = project.run(project.pytest_command("--ddenv-workers", workers), DDENV_PROBE_TIMEOUT="10")
    assert result.returncode == pytest.ExitCode.TESTS_FAILED, result.stdout
    assert (project.path / "hung.flag").exists(), "a probe did hang"
    summary = project.summary()
    assert summary["complete"] is True and summary["one_minimal"] is True and summary["minimal_models"] == ["wall"]
    assert summary["workers"]["timeouts"] == 1
    errors = [r for r in records(project.log()) if r.get("event") == "probe" and r["outcome"] == "error"]
    assert len(errors) == 1 and "10 s watchdog" in errors[0]["detail"], errors
    assert not any(r.get("event") == "reject" and r.get("errors") for r in records(project.log()))


def test_a_worker_killed_now_and_then_is_reported_and_the_result_is_still_one_minimal(project: Project) -> None:
    (project.path / "test_scenario.py").write_text(scenario_test(deflake=0))
    result = project.run(project.pytest_command("--ddenv-workers", "2"),
                         DDENV_FAULT_INJECTION="kill@3x2,kill@6x2,kill@9x2")
    assert result.returncode == pytest.ExitCode.TESTS_FAILED, result.stdout
    summary = project.summary()
    assert summary["workers"]["crashes"] >= 4 and summary["workers"]["errors"] >= 1, summary["workers"]
    assert summary["errors"] >= 1 and "errors" in result.stdout
    assert summary["one_minimal"] is True and summary["minimal_models"] == ["wall"]


def test_a_worker_killed_on_every_probe_is_not_taken_for_a_verdict(tmp_path: Path) -> None:
    """Every probe's worker is killed twice (so every probe errors): nothing may be reported 1-minimal, the
    errors are counted, and the log holds no rejection made of errors."""
    (tmp_path / "wall.yaml").write_text(WALL_WORLD)
    project = Project(tmp_path)
    faults = ",".join(f"kill@{number}x2" for number in range(2, 60))
    command = [*project.ddenv_command("--workers", "2", "--json"), "--deflake", "0"]
    command[command.index("yard.yaml")] = "wall.yaml"
    try:
        result = project.run(command, DDENV_FAULT_INJECTION=faults)
    finally:
        for process in project.started:
            if session_processes(process.pid):
                kill_group(process)
    assert result.returncode == 0, result.stdout
    summary = json.loads(result.stdout[result.stdout.index("{"):])
    assert summary["one_minimal"] is False and summary["minimal_models"] == [
        "far_box_a", "far_box_b", "wall", "side_post", "far_box_c", "ball"]
    assert summary["incomplete_reason"] == "not verified: 6 candidates errored"
    assert summary["errors"] >= 12 and summary["errored_candidates"] >= 6
    log = records(tmp_path / "out" / "runs.jsonl")
    assert not [r for r in log if r.get("event") == "reject"], "errors are not verdicts"
    assert any(note.startswith("not verified: 6 single removals") for note in summary["notes"])


def test_ctrl_c_with_two_workers_and_a_hung_probe_exits_with_the_journal_intact(project: Project) -> None:
    (project.path / "test_scenario.py").write_text(scenario_test(body=HANG_ONCE))
    process = project.start(project.pytest_command("--ddenv-workers", "2"), DDENV_PROBE_TIMEOUT="none")
    wait_for(process, (project.path / "hung.flag").exists, "a probe to hang")
    time.sleep(0.5)  # let the hung probe's worker get into its sleep (not needed for the outcome)
    process.send_signal(signal.SIGINT)  # the pytest process only: its workers ignore SIGINT anyway
    output, _ = process.communicate(timeout=HANG_GUARD)
    assert process.returncode == pytest.ExitCode.INTERRUPTED, output
    found = records(project.log())
    assert project.log().read_bytes().endswith(b"\n")
    assert [r["event"] for r in found[-2:]] == ["end", "usage"] and found[-2]["incomplete_reason"] == "interrupted"
    assert project.summary()["incomplete_reason"] == "interrupted"
    deadline = time.monotonic() + HANG_GUARD
    while session_processes(process.pid) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert session_processes(process.pid) == [], "workers left behind"

