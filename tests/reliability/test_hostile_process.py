"""Issue 28, the process part: what a probe's code does to the process it runs in (exits, ignores or swallows the
watchdog's interrupt, starts processes of its own), and how a reduction ends when it is interrupted late or
loses its folder. Real reductions in real processes; every signal goes to a child the test started."""

from __future__ import annotations

import json
import os
import signal
import textwrap
from pathlib import Path

import pytest

from .conftest import Project, records, scenario_test, wait_for

pytestmark = pytest.mark.slow  # real reductions (subprocesses, simulations): the full tier only

ONCE = """\
try:  # the first smaller candidate does it (once in the whole reduction)
    os.close(os.open('once.flag', os.O_CREAT | os.O_EXCL)) if SMALLER else None
except FileExistsError:
    FIRST = False
else:
    FIRST = SMALLER
"""


def once(action: str) -> str:
    """A test body that does `action` on the first smaller candidate only."""
    return ONCE + "if FIRST:\n" + textwrap.indent(textwrap.dedent(action), "    ")


def probe_errors(project: Project) -> list[dict]:
    return [r for r in records(project.log()) if r.get("event") == "probe" and r.get("outcome") == "error"]


# -- the in-process watchdog (--ddenv-workers 1) ------------------------------------------------------------
IGNORES_SIGALRM = "import signal\nsignal.signal(signal.SIGALRM, signal.SIG_IGN)\ntime.sleep(3600)\n"
SWALLOWS_INTERRUPTS = "while True:\n    try:\n        time.sleep(3600)\n    except BaseException:\n        pass\n"


@pytest.mark.parametrize(("action", "why"), [(IGNORES_SIGALRM, "it replaced the SIGALRM handler"),
                                             (SWALLOWS_INTERRUPTS, "it caught the watchdog's interrupt")])
def test_an_in_process_probe_that_defeats_the_alarm_is_stopped_and_the_rest_runs_in_a_worker(
        project: Project, action: str, why: str) -> None:
    (project.path / "test_scenario.py").write_text(scenario_test(body=once(action)))
    result = project.run(project.pytest_command("--ddenv-workers", "1"), DDENV_PROBE_TIMEOUT="3")
    assert result.returncode == pytest.ExitCode.TESTS_FAILED, result.stdout
    assert (project.path / "once.flag").exists(), "a probe did hang"
    summary = project.summary()
    assert summary["complete"] is True and summary["one_minimal"] is True and summary["minimal_models"] == ["wall"]
    assert summary["workers"]["timeouts"] == 1, summary["workers"]
    errors = probe_errors(project)
    assert len(errors) == 1 and why in errors[0]["detail"], errors
    assert any("the later probes ran in a worker process" in note for note in summary["notes"]), summary["notes"]
    assert "ran in a worker process" in result.stdout


BLOCKS_EVERYTHING = "import signal\nsignal.pthread_sigmask(signal.SIG_BLOCK, signal.valid_signals())\ntime.sleep(3600)\n"


def test_an_in_process_probe_that_cannot_be_stopped_ends_pytest_with_a_message_and_the_log_resumes(
        project: Project) -> None:
    """A probe that blocks every signal and hangs in C: nothing stops it in the pytest process, so the
    watchdog ends pytest with one clear message instead of hanging; run again in worker processes, the
    reduction resumes from the intact log and finishes."""
    (project.path / "test_scenario.py").write_text(scenario_test(body=once(BLOCKS_EVERYTHING)))
    result = project.run(project.pytest_command("--ddenv-workers", "1"), DDENV_PROBE_TIMEOUT="3")
    assert result.returncode == 70, result.stdout
    assert "cannot be stopped in this process" in result.stdout and "--ddenv-workers 2" in result.stdout
    before = [r for r in records(project.log()) if r.get("event") == "probe"]
    resumed = project.run(project.pytest_command("--ddenv-workers", "2"))
    assert resumed.returncode == pytest.ExitCode.TESTS_FAILED, resumed.stdout
    summary = project.summary()
    assert summary["complete"] is True and summary["minimal_models"] == ["wall"]
    assert summary["resumed_probes"] >= len([r for r in before if r.get("purpose") == "reduce"])


# -- processes a probe starts ----------------------------------------------------------------------------
STARTS_PROCESSES = """\
import subprocess, sys
if SMALLER:
    child = subprocess.Popen([sys.executable, '-c', 'import time; time.sleep(600)'], start_new_session=True)
    forked = os.fork()
    if forked == 0:  # the child: record itself, then sleep long
        with open('children.txt', 'a') as out:
            out.write(f'{os.getpid()}\\n')
        time.sleep(600)
        os._exit(0)
    with open('children.txt', 'a') as out:
        out.write(f'{child.pid}\\n')
"""


def alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return False
    return state != "Z"


@pytest.mark.parametrize("workers", ["1", "2"])
def test_processes_a_probe_starts_end_with_it(project: Project, workers: str) -> None:
    (project.path / "test_scenario.py").write_text(scenario_test(body=STARTS_PROCESSES))
    try:
        result = project.run(project.pytest_command("--ddenv-workers", workers, "--ddenv-max-probes", "12"))
        assert result.returncode == pytest.ExitCode.TESTS_FAILED, result.stdout
        started = [int(line) for line in (project.path / "children.txt").read_text().split()]
        assert len(started) >= 4, started  # a Popen child and a forked child of each smaller candidate's probe
        assert [pid for pid in started if alive(pid)] == [], "processes that probes started outlived pytest"
    finally:
        for pid in [int(line) for line in (project.path / "children.txt").read_text().split()] \
                if (project.path / "children.txt").exists() else []:
            if alive(pid):
                os.kill(pid, signal.SIGKILL)


# -- user code that exits ---------------------------------------------------------------------------------
@pytest.mark.parametrize("workers", ["1", "2"])
@pytest.mark.parametrize("exit_call", ["raise SystemExit(0)", "os._exit(0)"])
def test_a_probe_whose_test_exits_is_an_error_never_a_pass(project: Project, workers: str, exit_call: str) -> None:
    (project.path / "test_scenario.py").write_text(scenario_test(body=once(exit_call + "\n")))
    result = project.run(project.pytest_command("--ddenv-workers", workers))
    assert result.returncode == pytest.ExitCode.TESTS_FAILED, result.stdout
    assert (project.path / "once.flag").exists()
    summary = project.summary()
    assert summary["complete"] is True and summary["minimal_models"] == ["wall"]
    errors = probe_errors(project)
    shown = "os._exit(0)" if "os._exit" in exit_call else "SystemExit(0)"
    assert len(errors) == 1 and f"the code under test exited during the probe" in errors[0]["detail"], errors
    assert shown in errors[0]["detail"]
    assert summary["errors"] == 1


# -- what the report says ---------------------------------------------------------------------------------
def test_a_reduction_whose_probes_all_error_does_not_say_decided(tmp_path: Path) -> None:
    from .test_watchdog import WALL_WORLD

    (tmp_path / "wall.yaml").write_text(WALL_WORLD)
    project = Project(tmp_path)
    faults = ",".join(f"error@{number}" for number in range(2, 200))
    command = [*project.ddenv_command("--workers", "1", "--media", "none"), "--deflake", "0"]
    command[command.index("yard.yaml")] = "wall.yaml"
    result = project.run(command, DDENV_FAULT_INJECTION=faults)
    assert result.returncode == 0, result.stdout
    line = next(text for text in result.stdout.splitlines() if text.startswith("probes: "))
    assert "decided" not in line and " run, " in line and "errors (no verdict from them)" in line, line
    summary = project.summary()
    assert summary["errors"] >= summary["probes"] > 0 and summary["one_minimal"] is False


LATE_PAUSE = """\
logs = list(pathlib.Path('ddenv-artifacts').glob('*/runs.jsonl'))
if len(robot_world.world) == 1 and logs and '"event": "end"' in logs[0].read_text():  # a run after the models
    open('sleeping.flag', 'w').close()
    time.sleep(60)
"""


@pytest.mark.parametrize("workers", ["1", "2"])
def test_ctrl_c_after_the_models_leaves_the_final_summary_not_in_progress(project: Project, workers: str) -> None:
    (project.path / "test_scenario.py").write_text(scenario_test(body=LATE_PAUSE))
    process = project.start(project.pytest_command("--ddenv-workers", workers, "--ddenv-media", "all"))
    wait_for(process, (project.path / "sleeping.flag").exists, "a run after the model-level reduction")
    process.send_signal(signal.SIGINT)
    output, _ = process.communicate(timeout=120)
    assert process.returncode == pytest.ExitCode.INTERRUPTED, output
    summary = project.summary()
    assert summary.get("provisional") is None and summary["incomplete_reason"] != "in progress", summary
    assert summary["complete"] is True and summary["minimal_models"] == ["wall"]
    assert records(project.log())[-1]["event"] == "usage"


DELETES_THE_FOLDER = "import shutil\nshutil.rmtree('ddenv-artifacts')\n"


def test_a_test_that_deletes_the_artifacts_folder_is_not_told_its_records_are_intact(project: Project) -> None:
    (project.path / "test_scenario.py").write_text(scenario_test(body=once(DELETES_THE_FOLDER)))
    result = project.run(project.pytest_command("--ddenv-workers", "1"))
    assert result.returncode == pytest.ExitCode.TESTS_FAILED, result.stdout
    assert "RobotFailure" in result.stdout  # the test's own failure is kept
    assert "intact" not in result.stdout and "was deleted while the reduction ran" in result.stdout, result.stdout
    assert "run the reduction again: it starts over" in result.stdout
