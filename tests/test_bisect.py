"""`ddenv bisect`: the first commit at which a scenario test fails, found in a throwaway git repository made
here (a test module using `robot_world` on a copy of tests/data/wall.yaml, and a controller that goes around
the wall by two waypoints until a known commit drops them and drives it into the wall).

The sequential test, the search's bound and the journal are checked without simulations; the searches in the
repository run the test for real, at each commit in a git worktree of it (slow).
"""

from __future__ import annotations

import json
import math
import shutil
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

from pytest_ddenv.cli import main as cli
from pytest_ddenv.driver.bisect import BisectJournal, SequentialTest, binary_search

DATA = Path(__file__).parent / "data"
COMMITS = 10
"""Commits after the good one (the line searched)."""
FIRST_BAD = 6
"""The commit (1-based after the good one) that drops the waypoints."""

CONTROLLER = '''"""The controller under test: around the wall by waypoints, then to the goal."""
import math

from pytest_ddenv import Command
{broken}
WAYPOINTS = {waypoints}


class Controller:
    def reset(self, observation):
        self.left = list(WAYPOINTS)

    def __call__(self, observation):
        x, y, yaw = observation.pose
        if self.left and math.hypot(self.left[0][0] - x, self.left[0][1] - y) < 0.4:
            self.left.pop(0)
        tx, ty = self.left[0] if self.left else observation.goal[:2]
        bearing = math.atan2(ty - y, tx - x) - yaw
        bearing = math.atan2(math.sin(bearing), math.cos(bearing))
        speed = min(0.4 + 0.6 * max(0.0, math.cos(bearing)) ** 2, 0.5 * math.hypot(tx - x, ty - y) + 0.2)
        return Command(linear=speed, angular=max(-1.5, min(1.5, 3.0 * bearing)))
'''
TEST_MODULE = '''import pytest

from robot_control import Controller


@pytest.mark.ddenv(world="world.yaml")
@pytest.mark.robot_failure("stuck", window=2.0, min_progress=0.2)
def test_reaches_the_goal(robot_world):
    run = robot_world.run(controller=Controller())
    assert run.reached_goal
'''
TEST_ID = "test_robot.py::test_reaches_the_goal"


def git(repository: Path, *arguments: str) -> str:
    return subprocess.run(["git", "-C", str(repository), *arguments], check=True, capture_output=True,
                          text=True).stdout.strip()


def make_repository(folder: Path, *, broken: tuple[int, ...] = (), hung: tuple[int, ...] = ()) -> list[str]:
    """A repository of COMMITS + 1 commits (the good one first): the controller loses its waypoints at commit
    FIRST_BAD; at the commits in `broken` it does not import, at those in `hung` its import hangs. The shas,
    oldest first."""
    folder.mkdir(parents=True)
    git(folder, "init", "-q")
    git(folder, "config", "user.email", "bisect@example.org")
    git(folder, "config", "user.name", "bisect test")
    world = (DATA / "wall.yaml").read_text().replace("timeout: 20", "timeout: 40")
    (folder / "world.yaml").write_text(world)
    (folder / "test_robot.py").write_text(TEST_MODULE)
    (folder / "pytest.ini").write_text("[pytest]\n")
    shas = []
    for number in range(COMMITS + 1):
        waypoints = "[]" if number >= FIRST_BAD else "[(0.8, 2.7), (3.2, 2.7)]"
        broken_line = "\nraise ImportError('half-done refactoring')\n" if number in broken else ""
        broken_line += "\nimport time\ntime.sleep(600)\n" if number in hung else ""
        (folder / "robot_control.py").write_text(CONTROLLER.format(waypoints=waypoints, broken=broken_line))
        (folder / "history.txt").write_text(f"step {number}\n")
        git(folder, "add", "-A")
        subject = "drive straight to the goal" if number == FIRST_BAD else f"step {number}"
        git(folder, "commit", "-q", "-m", subject)
        shas.append(git(folder, "rev-parse", "HEAD"))
    return shas


def run_cli(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = cli.main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def repository(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[str]]:
    folder = tmp_path_factory.mktemp("bisect") / "project"
    return folder, make_repository(folder)


# -- without simulations -----------------------------------------------------------------------------------
def test_the_sequential_test_decides_clear_commits_in_few_runs_and_leaves_mixed_ones_undecided() -> None:
    test = SequentialTest()  # good 5 %, bad 60 %, level 2 % both ways
    assert test.decide([True, True]) == ("bad", 2)
    assert test.decide([False] * 5) == ("good", 5)
    assert test.decide([False] * 4) == ("undecided", 4)
    assert test.decide([True, False, False, False] * 5)[0] == "undecided"  # 25 %: between the two
    assert test.decide([True, False, False, True, True])[0] == "bad"


@given(st.integers(1, 300), st.data())
def test_the_binary_search_finds_the_first_bad_position_within_the_bound(count: int, data: st.DataObject) -> None:
    first_bad = data.draw(st.integers(0, count - 1))
    asked: list[int] = []

    def decide(index: int) -> str:
        asked.append(index)
        return "bad" if index >= first_bad else "good"

    low, high = binary_search(count, decide)
    assert (low, high) == (first_bad - 1, first_bad)
    assert len(asked) <= math.ceil(math.log2(count))  # + 1 for the bad revision itself: the bound


def test_skipped_positions_next_to_the_first_bad_leave_a_range() -> None:
    low, high = binary_search(10, lambda index: "skip" if index in (4, 5) else "bad" if index >= 6 else "good")
    assert (low, high) == (3, 6)  # 4, 5 or 6 could be the first bad one, as git bisect says


def test_the_journal_reuses_only_runs_of_the_same_world_and_test_and_survives_a_cut_line(tmp_path: Path) -> None:
    path = tmp_path / "journal.jsonl"
    record = {"run": 0, "seed": 7, "outcome": "failed", "type": "RobotFailure"}
    BisectJournal.open(path, "t.py::a", "w1").append([{"kind": "run", "commit": "c1", "record": record}])
    BisectJournal.open(path, "t.py::b", "w1").append([{"kind": "run", "commit": "c1", "record": record}])
    with path.open("a") as stream:
        stream.write('{"version": 1, "test": "t.py::a", "world_sha256": "w1", "kind": "run", "comm')  # kill -9
    journal = BisectJournal.open(path, "t.py::a", "w1")
    assert journal.runs == {("c1", 7): record}
    assert journal.foreign == 1
    assert BisectJournal.open(path, "t.py::a", "w2").runs == {}


# -- clear errors (git only) -------------------------------------------------------------------------------
def test_input_errors_are_one_line_and_exit_2(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                              repository: tuple[Path, list[str]]) -> None:
    folder, shas = repository
    world = str(folder / "world.yaml")
    common = ["bisect", "--test", TEST_ID, "--world", world, "--folder", str(tmp_path / "b")]
    cases = [
        ([*common, "--good", shas[0], "--repo", str(tmp_path)], "not a git repository"),
        ([*common, "--good", "no-such-revision", "--repo", str(folder)], "unknown good revision 'no-such-revision'"),
        ([*common, "--good", shas[0], "--bad", "nope", "--repo", str(folder)], "unknown bad revision 'nope'"),
        ([*common, "--good", shas[5], "--bad", shas[2], "--repo", str(folder)], "is not an ancestor of the bad"),
        (["bisect", str(tmp_path), "--good", shas[0], "--repo", str(folder)], "summary.json: missing"),
        (["bisect", "--test", TEST_ID, "--world", str(tmp_path / "none.yaml"), "--good", shas[0]],
         "no such world file"),
        (["bisect", "--good", shas[0]], "give an artifacts folder, or --test ID and --world FILE"),
    ]
    for argv, fragment in cases:
        code, out, err = run_cli(capsys, *argv)
        assert code == 2, (argv, err)
        assert err.startswith("ddenv: error: ") and fragment in err, (argv, err)
        assert err.count("\n") == 1 and out == ""


def test_a_hung_bad_revision_is_skipped_after_the_run_timeout_and_said_so(
        capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    folder = tmp_path / "project"
    shas = make_repository(folder, hung=(COMMITS,))
    monkeypatch.chdir(tmp_path)  # the default folder: ./ddenv-bisect/<test>-seed0-<hash>
    code, out, err = run_cli(capsys, "bisect", "--test", TEST_ID, "--world", str(folder / "world.yaml"),
                             "--good", shas[0], "--repo", str(folder), "--run-timeout", "3")
    assert code == 1 and out == ""
    assert f"ddenv bisect: {shas[COMMITS][:7]} skip: pytest did not finish in 3 s (a hung test; --run-timeout)" in err
    assert "ddenv: error: the bad revision" in err and "does not fail like the reference" in err
    assert git(folder, "worktree", "list").count("\n") == 0
    (journal,) = (tmp_path / "ddenv-bisect").glob("test_robot.py__test_reaches_the_goal-seed0-*/journal.jsonl")
    (entry,) = [json.loads(line) for line in journal.read_text().splitlines()]
    assert entry["kind"] == "cannot_run" and entry["hung"] and entry["commit"] == shas[COMMITS]


# -- real searches -------------------------------------------------------------------------------------------
@pytest.mark.slow
def test_bisect_finds_the_known_bad_commit_within_the_bound_and_a_rerun_starts_no_simulation(
        capsys: pytest.CaptureFixture[str], tmp_path: Path, repository: tuple[Path, list[str]]) -> None:
    folder, shas = repository
    git(folder, "bisect", "start")  # a bisect of the user's own, under way
    git(folder, "bisect", "bad", shas[-1])
    status_before, bisect_log = git(folder, "status", "--porcelain"), git(folder, "bisect", "log")
    argv = ["bisect", "--test", TEST_ID, "--world", str(folder / "world.yaml"), "--good", shas[0],
            "--repo", str(folder), "--folder", str(tmp_path / "bisect"), "--json"]
    code, out, err = run_cli(capsys, *argv)
    assert code == 0, err
    result = json.loads(out)
    assert result["first_bad"] == {"commit": shas[FIRST_BAD], "subject": "drive straight to the goal"}
    assert result["evaluations"] <= math.ceil(math.log2(COMMITS)) + 1 == result["bound"]
    assert result["simulations_started"] == sum(verdict["started"] for verdict in result["verdicts"]) > 0
    assert result["reference_failure"]["signature"]["predicate"] == "stuck"
    assert result["answer"].startswith(f"first bad: {shas[FIRST_BAD][:7]} drive straight to the goal - fails ")
    verdicts = {verdict["commit"]: verdict for verdict in result["verdicts"]}
    assert all(verdicts[sha]["decision"] == ("bad" if shas.index(sha) >= FIRST_BAD else "good") for sha in verdicts)
    assert git(folder, "status", "--porcelain") == status_before  # the user's checkout untouched
    assert git(folder, "bisect", "log") == bisect_log  # and their own bisect
    git(folder, "bisect", "reset")
    assert git(folder, "worktree", "list").count("\n") == 0  # every worktree removed
    assert not list((tmp_path / "bisect" / "worktrees").iterdir())

    code, out, _ = run_cli(capsys, *argv)
    again = json.loads(out)
    assert code == 0 and again["first_bad"] == result["first_bad"]
    assert again["simulations_started"] == 0
    assert again["simulations_reused"] == result["simulations"]


@pytest.mark.slow
def test_a_rerun_after_kill_9_reuses_every_recorded_run(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                                        repository: tuple[Path, list[str]]) -> None:
    folder, shas = repository
    argv = ["bisect", "--test", TEST_ID, "--world", str(folder / "world.yaml"), "--good", shas[0],
            "--repo", str(folder), "--folder", str(tmp_path / "bisect"), "--json"]
    journal = tmp_path / "bisect" / "journal.jsonl"
    process = subprocess.Popen([sys.executable, "-m", "pytest_ddenv", *argv], stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL)
    try:
        while process.poll() is None and len(journal.read_text().splitlines() if journal.exists() else []) < 4:
            time.sleep(0.05)  # polling for the journal, not timing anything
    finally:
        process.kill()  # SIGKILL: no cleanup, the worktree of the commit being run is left behind
        process.wait()
    recorded = [json.loads(line) for line in journal.read_text().splitlines()]
    assert len(recorded) >= 4 and all(entry["kind"] == "run" for entry in recorded)

    code, out, err = run_cli(capsys, *argv)
    assert code == 0, err
    result = json.loads(out)
    assert result["first_bad"]["commit"] == shas[FIRST_BAD]
    assert result["simulations_reused"] == len(recorded)  # every recorded run reused, none simulated again
    seeds = [(entry["commit"], entry["record"]["seed"]) for entry in journal.read_text().splitlines()
             for entry in [json.loads(entry)]]
    assert len(seeds) == len(set(seeds)) == len(recorded) + result["simulations_started"]
    assert git(folder, "worktree", "list").count("\n") == 0


@pytest.mark.slow
def test_a_commit_that_cannot_import_is_skipped(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    folder = tmp_path / "project"
    shas = make_repository(folder, broken=(FIRST_BAD + 1,))  # the second commit asked
    code, out, err = run_cli(capsys, "bisect", "--test", TEST_ID, "--world", str(folder / "world.yaml"),
                             "--good", shas[0], "--repo", str(folder), "--folder", str(tmp_path / "bisect"),
                             "--json")
    assert code == 0, err
    result = json.loads(out)
    assert result["first_bad"]["commit"] == shas[FIRST_BAD]
    skipped = [verdict for verdict in result["verdicts"] if verdict["decision"] == "skip"]
    assert [verdict["commit"] for verdict in skipped] == [shas[FIRST_BAD + 1]]
    assert "half-done refactoring" in skipped[0]["reason"] and skipped[0]["started"] == 0
    assert f"{shas[FIRST_BAD + 1][:7]} skip: pytest exited with 4: " in err


@pytest.mark.slow
def test_a_skipped_parent_of_the_first_bad_commit_leaves_a_range(capsys: pytest.CaptureFixture[str],
                                                                 tmp_path: Path) -> None:
    folder = tmp_path / "project"
    shas = make_repository(folder, broken=(FIRST_BAD - 1,))
    code, out, err = run_cli(capsys, "bisect", "--test", TEST_ID, "--world", str(folder / "world.yaml"),
                             "--good", shas[0], "--repo", str(folder), "--folder", str(tmp_path / "bisect"))
    assert code == 1, err
    assert out.startswith("no single first bad commit: skipped commits leave 2 that could be it (oldest first): "
                          f"{shas[FIRST_BAD - 1][:7]} step {FIRST_BAD - 1}, {shas[FIRST_BAD][:7]} drive straight")


@pytest.mark.slow
def test_bisect_from_a_real_reductions_artifacts_folder(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                                        repository: tuple[Path, list[str]]) -> None:
    folder, shas = repository
    artifacts = tmp_path / "artifacts"
    reduced = subprocess.run([sys.executable, "-m", "pytest", TEST_ID, "--ddenv-reduce", "--ddenv-artifacts",
                              str(artifacts), "-p", "no:cacheprovider", "-q"], cwd=folder, capture_output=True,
                             text=True, check=False)
    assert reduced.returncode == 1, reduced.stdout[-2000:]
    (reduction,) = (path.parent for path in artifacts.glob("*/summary.json"))
    summary: dict[str, Any] = json.loads((reduction / "summary.json").read_text())
    assert summary["minimal_models"] == ["wall"]
    code, out, err = run_cli(capsys, "bisect", str(reduction), "--good", shas[0], "--repo", str(folder))
    assert code == 0, err
    assert out.startswith(f"first bad: {shas[FIRST_BAD][:7]} drive straight to the goal - fails ")
    assert (reduction / "bisect" / "journal.jsonl").is_file()
    shutil.rmtree(reduction / "bisect")
