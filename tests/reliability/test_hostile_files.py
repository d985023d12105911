"""Issue 28, the journal and command-line part: files a reduction reads back (its lock, its run log, a summary)
damaged or replaced, and what `ddenv` writes where the user says. The one-line messages are rows of the table in
docs/reliability.md (test_bad_input.py); here, what a message alone cannot show: nothing of the user's is
overwritten, a damaged log is resumed with a note, an error line stays short."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from pytest_ddenv.cli import main as cli
from pytest_ddenv.driver.artifacts import ArtifactsError, FolderLock
from pytest_ddenv.errors import ReductionError
from pytest_ddenv.reduce import Outcome, ProbeLog, ProbeObservation, events, reduce
from pytest_ddenv.reduce.records import MAX_JSON_NESTING, json_value

from .test_bad_input import YARD

DEEP = "[" * 100_000 + "]" * 100_000
STUCK = "stuck:window=2.0,min_progress=0.2"


def test_a_lock_file_that_is_a_symbolic_link_is_never_followed(tmp_path: Path) -> None:
    precious = tmp_path / "precious.txt"
    precious.write_text("mine")
    folder = tmp_path / "out"
    folder.mkdir()
    (folder / ".ddenv.lock").symlink_to(precious)
    with pytest.raises(ArtifactsError, match=r"its lock file .*\.ddenv\.lock is a symbolic link"):
        FolderLock(folder).acquire()
    assert precious.read_text() == "mine"


def test_a_lock_file_that_is_a_fifo_neither_blocks_nor_is_used(tmp_path: Path) -> None:
    os.mkfifo(tmp_path / ".ddenv.lock")
    with pytest.raises(ArtifactsError, match="is not a regular file"):
        FolderLock(tmp_path).acquire()


def test_json_read_back_is_bounded_in_nesting_before_it_is_parsed() -> None:
    with pytest.raises(ValueError, match=f"nested more than {MAX_JSON_NESTING} deep"):
        json_value(DEEP)
    with pytest.raises(ValueError, match="nested more than"):
        json_value('{"event": "probe", "x": ' + DEEP + "}")
    brackets_in_strings = json.dumps({"detail": "[" * 10_000})
    assert json_value(brackets_in_strings) == {"detail": "[" * 10_000}
    assert json_value(json.dumps({"a": [[[[1]]]]})) == {"a": [[[[1]]]]}


@pytest.mark.parametrize(("record", "problem"), [
    ({"event": "probe", "candidate": 5, "attempt": 0, "outcome": "fail"}, "'candidate' of a 'probe' record"),
    ({"event": "probe", "candidate": ["a"], "attempt": "zero", "outcome": "fail"}, "'attempt'"),
    ({"event": "probe", "candidate": ["a"], "attempt": 0, "outcome": "banana"}, "'outcome'"),
    ({"event": "probe", "candidate": [["a"]], "attempt": 0, "outcome": "fail"}, "'candidate'"),
    ({"event": "reject", "candidate": ["a"], "reproduces": False, "fails": "many", "runs": 1}, "'fails'"),
    ({"event": "accept", "candidate": ["a"], "fails": 1, "runs": 1}, "without 'reproduces'"),
    ({"event": "usage", "simulations": "x"}, "'simulations'"),
    ({"event": "path", "points": [[1, 2]], "failure_time": 1.0}, "'points'"),
    ({"event": 5}, "no 'event' name"),
    ({"event": "note"}, "an unknown event 'note'"),
])
def test_a_record_of_the_wrong_types_is_named(record: dict, problem: str) -> None:
    found = events.from_json(record)
    assert isinstance(found, events.Unreadable) and problem in found.problem, found


def test_a_log_with_deep_and_mistyped_records_is_read_with_a_note(tmp_path: Path) -> None:
    """Each of these lines crashed the reduction (RecursionError, TypeError in partial_runs, ValueError)."""
    path = tmp_path / "runs.jsonl"
    lines = [{"event": "start", "elements": ["a", "b"]},
             {"event": "probe", "purpose": "reduce", "candidate": ["a"], "attempt": "zero", "outcome": "fail"},
             {"event": "probe", "purpose": "reduce", "candidate": 5, "attempt": 0, "outcome": "fail"},
             {"event": "reject", "candidate": ["b"], "reproduces": False, "fails": "many", "runs": 1},
             {"event": "probe", "purpose": "reduce", "candidate": ["b"], "attempt": 0, "outcome": "pass"}]
    path.write_text("\n".join([json.dumps(lines[0]), DEEP, *map(json.dumps, lines[1:])]) + "\n")
    log = ProbeLog.load(path)
    assert [r["event"] for r in log.records] == ["start", "probe"]
    assert log.partial_runs() == {frozenset({"b"}): [Outcome.PASS]} and log.decisions() == {}
    assert log.notes and "line(s) 2, 3, 4, 5 are not records (damaged; line 2:" in log.notes[0], log.notes


def _ddenv(folder: Path, *words: str, **env: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "pytest_ddenv.cli", *words], cwd=folder, capture_output=True,
                          text=True, timeout=600, check=False, env={**os.environ, **env})


@pytest.mark.slow
def test_ddenv_reduce_resumes_a_damaged_log_with_a_note(tmp_path: Path) -> None:
    (tmp_path / "yard.yaml").write_text(YARD)
    command = ["reduce", "yard.yaml", "-p", STUCK, "--out", "out", "--workers", "1", "--media", "none", "--json"]
    first = _ddenv(tmp_path, *command)
    assert first.returncode == 0, first.stderr
    log = tmp_path / "out" / "runs.jsonl"
    lines = log.read_text().splitlines()
    probe = next(index for index, line in enumerate(lines) if '"purpose": "reduce"' in line)
    damaged = json.loads(lines[probe])
    damaged["attempt"] = "zero"
    lines[probe] = json.dumps(damaged)
    log.write_text("\n".join([*lines[:2], DEEP, *lines[2:]]) + "\n")
    again = _ddenv(tmp_path, *command)
    assert again.returncode == 0, again.stderr
    summary = json.loads(again.stdout)
    assert summary["minimal_models"] == ["wall"] and summary["complete"] is True
    assert any("are not records (damaged; line 3: not a JSON object" in note for note in summary["notes"]), summary


def test_reduce_refuses_a_budget_of_no_simulation_with_nothing_to_decide_from() -> None:
    def probe(candidate: tuple[str, ...], attempt: int) -> ProbeObservation:
        return ProbeObservation(Outcome.FAIL)

    with pytest.raises(ReductionError, match=r"max_probes: expected an integer >= 1 \(0, no simulation at all"):
        reduce(["a", "b"], probe, max_probes=0)
    assert reduce(["a", "b"], probe, max_probes=0, cache={}).incomplete_reason == "budget: max_probes"


def test_an_error_line_naming_thousands_of_folders_stays_short(tmp_path: Path,
                                                               capsys: pytest.CaptureFixture[str],
                                                               monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "inc.world").write_text("<sdf version='1.7'><world name='w'><include><uri>model://nothere</uri>"
                                        "</include></world></sdf>\n")
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("GAZEBO_MODEL_PATH", ":".join(f"/nonexistent/models-{index:04d}" for index in range(5000)))
    assert cli.main(["check", "inc.world"]) == 2
    line = capsys.readouterr().err.strip()
    assert "\n" not in line and len(line) < 2200, len(line)
    assert "characters left out" in line and "/nonexistent/models-4999" in line, line[-300:]


SLOW_CONTROLLER = """\
import time
from pytest_ddenv import Command

def slow(observation):
    time.sleep(0.2)
    return Command(1.0, 0.0)
"""


def test_the_run_timeout_hint_of_ddenv_run_names_its_own_option(tmp_path: Path,
                                                               capsys: pytest.CaptureFixture[str],
                                                               monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "yard.yaml").write_text(YARD)
    (tmp_path / "slow_controller.py").write_text(SLOW_CONTROLLER)  # a name no other test imports in this process
    monkeypatch.chdir(tmp_path)
    code = cli.main(["run", "yard.yaml", "--controller", "slow_controller:slow", "--run-timeout", "0.5",
                     "--no-picture"])
    out = capsys.readouterr().out
    assert code == 1 and "ControllerTimeout" in out, out
    assert "ddenv run --run-timeout SECONDS" in out and "--ddenv-run-timeout" not in out
    assert "max_wall_time" not in out
