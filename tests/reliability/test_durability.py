"""The journal survives anything: kill -9 mid-reduction, a full disk, a torn last line, a second reduction
into the same folder, a log of another problem. Real pytest and `ddenv reduce` processes; the checks are on
what they leave on disk and on what the next run does with it."""

from __future__ import annotations

import json
import shutil
import subprocess
import textwrap

import pytest

from pytest_ddenv import World

from .conftest import (
    Project,
    decided,
    kill_group,
    mid_reduction,
    records,
    scenario_test,
    simulated,
    wait_for,
)

pytestmark = pytest.mark.slow  # real reductions (subprocesses, simulations): the full tier only


def check_best_world_after_a_kill(project: Project) -> list[dict]:
    """What a killed reduction left: the best world so far, a provisional summary, a log of whole lines."""
    folder = project.folder()
    before = records(project.log())
    assert project.log().read_bytes().endswith(b"\n")
    steps = [r for r in before if r.get("event") == "step"]
    best = World.load(folder / "minimal.yaml")
    assert steps and best.names == tuple(steps[-1]["candidate"]), "minimal.yaml is the last accepted world"
    summary = project.summary()
    assert summary["complete"] is False and summary["incomplete_reason"] == "in progress"
    assert summary["minimal_models"] == list(best.names)
    return before


def check_resumed(project: Project, before: list[dict], after: list[dict]) -> None:
    """The resumed run simulated no decided candidate and no (candidate, attempt) again, and finished."""
    new = after[len(before):]
    assert after[: len(before)] == before, "the log is continued, not rewritten"
    again = {candidate for candidate, _ in simulated(new)} & decided(before)
    assert again == set(), f"decided candidates simulated again: {again}"
    assert not set(simulated(new)) & set(simulated(before)), "no (candidate, attempt) simulated twice"
    summary = project.summary()
    assert summary["complete"] is True and summary["one_minimal"] is True and summary["minimal_models"] == ["wall"]
    assert summary["resumed_probes"] == len(simulated(before)) and summary["probes"] >= summary["resumed_probes"]
    assert summary["resumed_runs"] == 1 and summary["cache_hits"] >= 1


@pytest.mark.parametrize("workers", ["1", "2"])
def test_kill_9_of_pytest_mid_reduction_then_resume(project: Project, workers: str) -> None:
    command = project.pytest_command("--ddenv-workers", workers)
    process = project.start(command)
    wait_for(process, mid_reduction(project), "an accepted step and three verdicts")
    kill_group(process)  # kill -9 (with its workers: a CI job killed by the runner)
    before = check_best_world_after_a_kill(project)

    resumed = project.run(command)
    assert resumed.returncode == pytest.ExitCode.TESTS_FAILED, resumed.stdout
    assert "RobotFailure" in resumed.stdout and "1-minimal" in resumed.stdout
    check_resumed(project, before, records(project.log()))


def test_kill_9_of_ddenv_reduce_mid_reduction_then_resume(project: Project) -> None:
    (project.path / "slow.py").write_text(textwrap.dedent(
        """\
        import time
        from pytest_ddenv.sim.controllers import GoToGoal

        class Slow(GoToGoal):  # the built-in law, paused once per run: slow enough to be caught
            def reset(self, observation):
                time.sleep(0.25)
        """
    ))
    command = project.ddenv_command("--workers", "2", "--import", "slow.py", "--controller", "slow.py:Slow")
    process = project.start(command)
    wait_for(process, mid_reduction(project), "an accepted step and three verdicts")
    process.kill()  # kill -9 of the ddenv process only; its workers notice and leave
    process.wait()
    before = check_best_world_after_a_kill(project)

    resumed = project.run(command)
    assert resumed.returncode == 0, resumed.stdout
    check_resumed(project, before, records(project.log()))


def can_mount_tmpfs() -> bool:
    try:
        done = subprocess.run(["unshare", "-Urm", "sh", "-c", "mount -t tmpfs -o size=64k tmpfs /mnt"],
                              check=False, capture_output=True, timeout=30)
    except (OSError, subprocess.SubprocessError):
        return False
    return done.returncode == 0


FULL_DISK_SCRIPT = """\
set -u
mount -t tmpfs -o size=24k tmpfs "$DISK"
"$@" --ddenv-artifacts "$DISK/art" > first.txt 2>&1; echo $? > first.code
cp -a "$DISK/art" first-art
mount -o remount,size=8m "$DISK"
"$@" --ddenv-artifacts "$DISK/art" > second.txt 2>&1; echo $? > second.code
cp -a "$DISK/art" second-art
"""

INJECTED_FULL_DISK = """\
import errno, os
if os.environ.get("FULL_DISK_AFTER"):  # test-only: writes to the artifacts folder fail after N of them
    budget = [int(os.environ["FULL_DISK_AFTER"])]
    real_write = os.write

    def write(fd, data):
        try:
            target = os.readlink(f"/proc/self/fd/{fd}")
        except OSError:
            target = ""
        if "/art/" in target:
            budget[0] -= 1
            if budget[0] < 0:
                raise OSError(errno.ENOSPC, "No space left on device")
        return real_write(fd, data)

    os.write = write
"""


def test_a_full_disk_is_a_clear_error_the_journal_stays_intact_and_the_next_run_resumes(project: Project) -> None:
    command = project.pytest_command("--ddenv-workers", "2")
    if can_mount_tmpfs():  # a real 24 KB file system in a private mount namespace, enlarged for the second run
        (project.path / "disk").mkdir()
        done = subprocess.run(["unshare", "-Urm", "sh", "-c", FULL_DISK_SCRIPT, "full-disk", *command],
                              cwd=project.path, env={**project.env, "DISK": str(project.path / "disk")},
                              check=False, capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, done.stdout + done.stderr
        first = (project.path / "first.txt").read_text()
        first_art, second_art = project.path / "first-art", project.path / "second-art"
        second = (project.path / "second.txt").read_text()
        codes = [(project.path / f"{name}.code").read_text().strip() for name in ("first", "second")]
    else:  # no user namespaces: inject ENOSPC into the writes of the artifacts folder
        project.path.joinpath("conftest.py").write_text(INJECTED_FULL_DISK)
        art = ["--ddenv-artifacts", str(project.path / "art")]
        first = project.run(command + art, FULL_DISK_AFTER="40").stdout
        shutil.copytree(project.path / "art", project.path / "first-art")
        second = project.run(command + art).stdout
        first_art = project.path / "first-art"
        second_art = project.path / "art"
        codes = ["1", "1"]
    assert codes == ["1", "1"], first + second  # the test's own failure either way
    assert "RobotFailure" in first and "No space left on device" in first, first
    assert "run the reduction again: it resumes from the log" in first
    (log,) = first_art.glob("*/runs.jsonl")
    assert log.read_bytes().endswith(b"\n"), "no half record"
    before = records(log)
    assert before[0]["event"] == "problem" and decided(before), "the disk filled up in the middle of the reduction"

    assert "1-minimal" in second, second
    (resumed,) = second_art.glob("*/runs.jsonl")
    after = records(resumed)
    assert after[: len(before)] == before
    new = after[len(before):]
    assert not {candidate for candidate, _ in simulated(new)} & decided(before)
    summary = json.loads((resumed.parent / "summary.json").read_text())
    assert summary["complete"] is True and summary["minimal_models"] == ["wall"]


def test_a_torn_last_line_is_cut_off_said_and_the_run_resumes(project: Project) -> None:
    command = project.pytest_command("--ddenv-workers", "1", "--ddenv-max-probes", "6")
    assert project.run(command).returncode == pytest.ExitCode.TESTS_FAILED
    log = project.log()
    whole = log.read_text()
    log.write_text(whole + '{"event": "probe", "purpose": "reduce", "cand')  # a crash in the middle of a write

    resumed = project.run(project.pytest_command("--ddenv-workers", "1"))
    assert resumed.returncode == pytest.ExitCode.TESTS_FAILED, resumed.stdout
    assert "runs.jsonl: its last line was incomplete (45 bytes" in resumed.stdout
    assert log.read_text().startswith(whole) and '"cand{' not in log.read_text()
    assert project.summary()["complete"] is True and project.summary()["minimal_models"] == ["wall"]
    assert any("last line was incomplete" in note for note in project.summary()["notes"])
    third = project.run(project.pytest_command("--ddenv-workers", "1"))  # the repaired log reads cleanly
    assert third.returncode == pytest.ExitCode.TESTS_FAILED and "incomplete" not in third.stdout.split("ddenv red")[-1]


def test_a_second_reduction_into_the_same_folder_is_refused_and_leaves_the_first_alone(project: Project) -> None:
    command = project.pytest_command("--ddenv-workers", "1")
    first = project.start(command)
    wait_for(first, mid_reduction(project), "the first reduction to be under way")
    second = project.run(command)
    assert second.returncode == pytest.ExitCode.TESTS_FAILED, second.stdout  # the test's own failure stays
    assert "RobotFailure" in second.stdout
    assert f"is in use by another reduction (pid {first.pid}" in second.stdout, second.stdout

    first.terminate()  # SIGTERM: the first reduction stops like Ctrl-C, its journal complete
    output, _ = first.communicate(timeout=120)
    assert first.returncode == pytest.ExitCode.INTERRUPTED, output
    found = records(project.log())
    assert [r["event"] for r in found].count("session") == 1 and [r["event"] for r in found].count("problem") == 1
    assert found[-1]["event"] == "usage" and found[-2]["event"] == "end"
    assert found[-2]["incomplete_reason"] == "interrupted"


def test_a_log_of_another_problem_is_moved_aside_not_deleted(project: Project) -> None:
    command = project.pytest_command("--ddenv-workers", "1", "--ddenv-max-probes", "4")
    assert project.run(command).returncode == pytest.ExitCode.TESTS_FAILED
    old = project.log().read_text()
    (project.path / "test_scenario.py").write_text(scenario_test(deflake=0))  # another problem: the test changed
    again = project.run(command)
    assert again.returncode == pytest.ExitCode.TESTS_FAILED
    assert "the run log of another problem" in again.stdout and "kept as runs.previous-1.jsonl" in again.stdout
    assert (project.folder() / "runs.previous-1.jsonl").read_text() == old
    assert records(project.log())[0]["event"] == "problem" and project.log().read_text() != old
