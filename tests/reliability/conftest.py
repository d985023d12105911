"""Real processes for the reliability tests: a pytest (or `ddenv reduce`) run reducing a small world, started,
watched through its run log, killed or interrupted, and resumed.

Nothing here sends a signal to the test process: every signal goes to a child the test started, in a
session of its own (so that the child's workers can be cleaned up as a group). Time limits are hang guards,
never assertions of speed (DESIGN.md section 10).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

HANG_GUARD = 180.0
"""Seconds after which a child that should have ended long before is killed and the test fails."""
STUCK = "stuck:window=2.0,min_progress=0.2"

YARD_WORLD = (Path(__file__).resolve().parents[1] / "data" / "yard.yaml").read_text(encoding="utf-8")
"""31 models: thirty boxes far from the path, and the wall that stops the robot (the only culprit)."""


def scenario_test(*, deflake: int | str = 1, body: str = "", name: str = "test_reaches_goal") -> str:
    """A scenario test of the yard world; `body` runs before the simulation (a probe's own code: a pause, a
    hang). `SMALLER` is true on candidates smaller than the original world (probes, not the original run)."""
    lines = [
        "import os, pathlib, time",
        "import pytest",
        "",
        f"@pytest.mark.ddenv(world='yard.yaml', partition='even', priority='sequential', deflake={deflake!r})",
        "@pytest.mark.robot_failure('stuck', window=2.0, min_progress=0.2)",
        f"def {name}(robot_world):",
        "    SMALLER = len(robot_world.world) < 31",
        *("    " + line for line in textwrap.dedent(body).splitlines()),
        "    assert robot_world.run().reached_goal",
    ]
    return "\n".join(lines) + "\n"


PAUSE = "time.sleep(0.25 if SMALLER else 0)  # slow enough to be caught mid-reduction\n"
HANG_ONCE = (
    "try:  # the first smaller candidate hangs (once in the whole reduction)\n"
    "    os.close(os.open('hung.flag', os.O_CREAT | os.O_EXCL)) if SMALLER else None\n"
    "except FileExistsError:\n"
    "    pass\n"
    "else:\n"
    "    if SMALLER:\n"
    "        time.sleep(3600)\n"
)


def default_signals() -> None:
    """In the child: Ctrl-C and SIGTERM act normally (a background job inherits SIGINT ignored)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


@dataclass
class Project:
    """A folder with the yard world and a scenario test; runs pytest or `ddenv reduce` on it."""

    path: Path
    env: dict[str, str] = field(default_factory=lambda: dict(os.environ))
    started: list[subprocess.Popen[str]] = field(default_factory=list)

    def pytest_command(self, *args: str) -> list[str]:
        return [sys.executable, "-m", "pytest", "--ddenv-reduce", "-p", "no:cacheprovider", *args]

    def ddenv_command(self, *args: str) -> list[str]:
        return [sys.executable, "-m", "pytest_ddenv.cli", "reduce", "yard.yaml", "-p", STUCK, "--partition", "even",
                "--priority", "sequential", "--deflake", "1", "--out", "out", *args]

    def start(self, command: list[str], **env: str) -> subprocess.Popen[str]:
        process = subprocess.Popen(
            command, cwd=self.path, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
            env={**self.env, **env}, start_new_session=True,
            preexec_fn=default_signals,  # noqa: PLW1509 - only resets two signal dispositions before exec
        )
        self.started.append(process)
        return process

    def run(self, command: list[str], **env: str) -> subprocess.CompletedProcess[str]:
        process = self.start(command, **env)
        try:
            output, _ = process.communicate(timeout=HANG_GUARD)
        except subprocess.TimeoutExpired:
            kill_group(process)
            output, _ = process.communicate()
            pytest.fail(f"{' '.join(command)} did not end within {HANG_GUARD:g} s:\n{output}")
        return subprocess.CompletedProcess(command, process.returncode, output, "")

    def folder(self) -> Path:
        """The artifacts folder of the (single) reduction."""
        found = sorted(self.path.glob("ddenv-artifacts/*/runs.jsonl")) + sorted(self.path.glob("out/runs.jsonl"))
        assert found, f"no run log under {self.path}"
        return found[0].parent

    def log(self) -> Path:
        return self.folder() / "runs.jsonl"

    def summary(self) -> dict[str, Any]:
        return json.loads((self.folder() / "summary.json").read_text())


def kill_group(process: subprocess.Popen[str]) -> None:
    """SIGKILL a child and everything it started (its session: workers, forkserver)."""
    try:
        os.killpg(process.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    process.wait()


def session_processes(sid: int) -> list[int]:
    """Live processes of session `sid` (the children a test's child started), zombies excluded."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[3]) == sid and fields[0] != "Z":
            found.append(int(entry.name))
    return found


def records(log: Path) -> list[dict[str, Any]]:
    """The complete records of a run log (a line still being written is left out)."""
    data = log.read_bytes() if log.exists() else b""
    complete = data[: data.rfind(b"\n") + 1].decode("utf-8")
    return [json.loads(line) for line in complete.splitlines() if line.strip()]


def decided(found: list[dict[str, Any]]) -> set[frozenset[str]]:
    """Candidates with a verdict (accept or reject) in these records."""
    return {frozenset(r["candidate"]) for r in found if r.get("event") in ("accept", "reject")}


def simulated(found: list[dict[str, Any]], purposes: tuple[str, ...] = ("reduce", "calibration")) -> list[tuple[frozenset[str], int]]:
    """(candidate, attempt) of the simulations logged with these purposes, ERROR runs excluded."""
    return [(frozenset(r["candidate"]), int(r["attempt"])) for r in found
            if r.get("event") == "probe" and r.get("purpose") in purposes and r.get("outcome") != "error"]


def wait_for(process: subprocess.Popen[str], condition: Callable[[], bool], what: str) -> None:
    """Poll `condition` until it holds; fail if `process` ends first or the hang guard passes."""
    deadline = time.monotonic() + HANG_GUARD
    while time.monotonic() < deadline:
        if condition():
            return
        if process.poll() is not None:
            output = process.stdout.read() if process.stdout else ""
            pytest.fail(f"the run ended (exit {process.returncode}) before {what}:\n{output}")
        time.sleep(0.05)
    pytest.fail(f"{what} did not happen within {HANG_GUARD:g} s")


def mid_reduction(project: Project) -> Callable[[], bool]:
    """True once the log shows an accepted step and a few verdicts (and more work is left)."""

    def check() -> bool:
        try:
            found = records(project.log())
        except (AssertionError, OSError, ValueError):
            return False
        return any(r.get("event") == "step" for r in found) and len(decided(found)) >= 3

    return check


@pytest.fixture
def project(tmp_path: Path) -> Iterator[Project]:
    (tmp_path / "yard.yaml").write_text(YARD_WORLD)
    (tmp_path / "test_scenario.py").write_text(scenario_test(body=PAUSE))
    made = Project(tmp_path)
    yield made
    for process in made.started:  # whatever a test left running (orphaned workers included)
        if process.poll() is None or session_processes(process.pid):
            kill_group(process)
