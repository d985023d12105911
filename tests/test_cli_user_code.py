"""`ddenv --import` and `--controller`: the user's robots, predicates and controllers outside pytest, in
this process and in every probe worker."""

from __future__ import annotations

import json
import sys
import textwrap
from collections.abc import Iterator
from pathlib import Path

import pytest

from pytest_ddenv.cli import main as cli
from pytest_ddenv.oracle import PREDICATES
from pytest_ddenv.sim import ROBOTS

USER_MODULE = textwrap.dedent(
    """\
    import math

    from pytest_ddenv import Command, predicate, register_predicate, register_robot
    from pytest_ddenv.sim import Husky


    class SlowHusky(Husky):
        name = "slow_husky"


    register_robot("slow_husky", SlowHusky, replace=True)


    @predicate
    def past_one_metre(state):
        return state.pose[0] > 1.0


    register_predicate("past_one_metre", lambda: past_one_metre, replace=True)


    def crawl(observation):
        return Command(linear=0.3, angular=max(-0.5, min(0.5, observation.goal_bearing)))
    """
)
WORLD = textwrap.dedent(
    """\
    format: 1
    scenario: {robot: slow_husky, start: {x: 0, y: 0, yaw: 0}, goal: {x: 4, y: 0}, timeout: 20}
    models:
      - {name: wall, pose: [2.0, 0, 0.5], box: [0.3, 4.0, 1.0]}
      - {name: crate, pose: [-3, 3, 0.25], box: [0.5, 0.5, 0.5]}
      - {name: barrel, pose: [3, -4, 0.4], cylinder: {radius: 0.3, length: 0.8}}
    """
)


@pytest.fixture
def project(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """A folder with the user's module and a world that needs it; what the module registers is forgotten
    afterwards (as in a fresh `ddenv` process)."""
    (tmp_path / "lab_robots.py").write_text(USER_MODULE)
    (tmp_path / "world.yaml").write_text(WORLD)
    monkeypatch.chdir(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    yield tmp_path
    PREDICATES.pop("past_one_metre", None)
    ROBOTS.pop("slow_husky", None)
    for name in ("lab_robots", "broken_lab"):
        sys.modules.pop(name, None)


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = cli.main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_run_with_imported_robot_predicate_and_controller(capsys: pytest.CaptureFixture[str], project: Path) -> None:
    code, out, err = run(capsys, "run", "world.yaml", "--import", "lab_robots", "--controller", "lab_robots:crawl",
                         "-p", "past_one_metre", "--no-picture", "--json")
    data = json.loads(out)
    assert code == 1 and data["failure"]["predicate"] == "past_one_metre", err
    assert data["failure"]["time"] > 3.0, "crawling at 0.3 m/s takes more than 3 s for a metre"


@pytest.mark.slow  # a real reduction in worker processes: the full tier only
def test_reduce_in_workers_and_replay_use_the_same_user_code(capsys: pytest.CaptureFixture[str], project: Path) -> None:
    code, out, err = run(capsys, "reduce", "world.yaml", "--import", "lab_robots.py", "--controller",
                         "lab_robots:crawl", "-p", "stuck:window=2,min_progress=0.2", "--workers", "2",
                         "--out", "art", "--json", "--quiet")
    summary = json.loads(out)
    assert code == 0, err
    assert summary["minimal_models"] == ["wall"] and summary["errors"] == 0 and summary["workers"]["workers"] == 2
    assert summary["controller"] == "lab_robots:crawl" and summary["imports"] == ["lab_robots.py"]
    assert "--import lab_robots.py --controller lab_robots:crawl" in summary["replay"]
    code, out, err = run(capsys, "replay", "art", "--runs", "2")  # imports and controller from summary.json
    assert code == 0 and "reproduced: 2/2" in out, err


@pytest.mark.parametrize(
    ("argv", "fragment"),
    [
        (["run", "world.yaml", "--import", "no_such_lab_module"], "--import no_such_lab_module: no module named"),
        (["run", "world.yaml", "--import", "missing.py"], "missing.py: no such file"),
        (["run", "world.yaml", "--import", "lab_robots", "--controller", "lab_robots:fly"],
         "--controller lab_robots:fly: lab_robots has no attribute 'fly'"),
        (["run", "world.yaml", "--controller", "crawl"], "expected MODULE:ATTRIBUTE"),
        (["run", "world.yaml"], "unknown robot 'slow_husky'"),
        (["run", "world.yaml", "--import", "lab_robots", "-p", "past_two_metres"],
         "unknown failure predicate 'past_two_metres'"),
    ],
)
def test_user_code_errors_are_one_line(capsys: pytest.CaptureFixture[str], project: Path, argv: list[str],
                                       fragment: str) -> None:
    code, out, err = run(capsys, *argv, "--no-picture")
    assert code == 2 and fragment in err and "Traceback" not in err, err
    assert len(err.strip().splitlines()) == 1, err


def test_a_module_that_raises_on_import_is_named(capsys: pytest.CaptureFixture[str], project: Path) -> None:
    (project / "broken_lab.py").write_text("raise RuntimeError('no licence server')\n")
    code, _, err = run(capsys, "run", "world.yaml", "--import", "broken_lab", "--no-picture")
    assert code == 2 and "--import broken_lab: importing it failed: RuntimeError: no licence server" in err


def test_a_controller_that_raises_fails_the_run_not_ddenv(capsys: pytest.CaptureFixture[str], project: Path) -> None:
    (project / "lab_broken.py").write_text("def boom(observation):\n    raise ZeroDivisionError('no room')\n")
    code, out, err = run(capsys, "run", "world.yaml", "--import", "lab_robots", "--controller",
                         "lab_broken.py:boom", "--no-picture")
    assert code == 1 and "FAILED (the run raised ZeroDivisionError at lab_broken.py:2: no room)" in out, err
    sys.modules.pop("lab_broken", None)


@pytest.mark.slow  # a real reduction in worker processes: the full tier only
def test_quiet_parallel_reduce_prints_nothing_on_stderr(project: Path) -> None:
    import subprocess

    # `-m pytest_ddenv.cli` until the package has a `__main__` (then `-m pytest_ddenv`): this interpreter's
    # ddenv, whatever PATH holds
    done = subprocess.run([sys.executable, "-m", "pytest_ddenv.cli", "reduce", "world.yaml", "--import", "lab_robots",
                           "-p", "stuck:window=2", "--workers", "2", "-q", "--out", "art"],
                          capture_output=True, text=True, cwd=project)
    assert done.returncode == 0 and done.stderr == "", done.stderr


@pytest.mark.slow  # a real reduction in worker processes: the full tier only
def test_a_module_that_imports_here_but_not_in_a_worker_is_named(capsys: pytest.CaptureFixture[str],
                                                                  project: Path) -> None:
    (project / "worker_only_lab.py").write_text(
        "import multiprocessing\n"
        "from lab_robots import *\n"
        "if multiprocessing.parent_process() is not None:  # in probe workers only\n"
        "    import lab_driver_only_on_the_ci_host\n"
    )
    code, _, err = run(capsys, "reduce", "world.yaml", "--import", "worker_only_lab.py", "-p", "stuck", "--workers", "2",
                       "--media", "none", "--out", "art", "--quiet")
    sys.modules.pop("worker_only_lab", None)
    assert code == 2, err
    assert "a probe worker could not start the test" in err
    assert "No module named 'lab_driver_only_on_the_ci_host'" in err and "Traceback" not in err, err
