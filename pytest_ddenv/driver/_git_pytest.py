"""One batch of `ddenv bisect`: the test run with `--ddenv-rate` in a git worktree of one commit, in a pytest
process of its own, and its runs read back from the JUnit XML (the `ddenv_rate_*` and `ddenv_run_<i>`
properties of `--ddenv-rate`, docs/writing-tests.md).

What is isolated: the user's code is the commit's (the worktree is the working directory and comes first on
PYTHONPATH, ahead of an editable install of the project; pytest's rootdir, ini file and conftests are the
worktree's). What is not: the interpreter, pytest-ddenv itself and every installed package (numpy, pybullet,
the project's dependencies) are the bisect's environment, and a compiled extension built in place is not
rebuilt per commit.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import xml.etree.ElementTree as ElementTree
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pytest_ddenv.scenario.robot_world import ATTEMPT_SEED_STRIDE

RUN_OUTCOMES = ("passed", "failed", "error")
KILLED_WAIT = 10.0
"""Seconds to read what a killed pytest process wrote before giving up on its pipe."""
OUTPUT_TAIL = 2000
"""Characters of a pytest process's output kept to say why a commit cannot run."""


def run_seed(seed: int, index: int) -> int:
    """The run seed of run `index` when run 0's is `seed` (as `--ddenv-rate` seeds its runs)."""
    return seed + index * ATTEMPT_SEED_STRIDE


@dataclass(frozen=True)
class BatchRequest:
    """Runs `first` .. `first + count - 1` of the test on the world: run i uses the run seed
    `seed + i * ATTEMPT_SEED_STRIDE` at every commit (the seeds are paired)."""

    test: str
    world: Path
    seed: int
    first: int
    count: int
    timeout: float

    def run_seed(self, index: int) -> int:
        return run_seed(self.seed, index)

    def pytest_arguments(self, junit: Path) -> list[str]:
        return [sys.executable, "-m", "pytest", self.test, "--ddenv-world", str(self.world),
                "--ddenv-rate", str(self.count), "--ddenv-seed", str(self.run_seed(self.first)),
                "--junitxml", str(junit), "-p", "no:cacheprovider", "-q"]


@dataclass(frozen=True)
class BatchResult:
    """The runs of a batch, each the JSON object of its `ddenv_run_<i>` property with "run" renumbered to the
    bisect's run index; or, when the test could not run at that commit (a collection or import error, no such
    test, a hung pytest), `cannot_run` says why and `runs` is empty."""

    runs: tuple[Mapping[str, Any], ...] = ()
    cannot_run: str = ""
    hung: bool = False


def run_batch(worktree: Path, request: BatchRequest, junit: Path) -> BatchResult:
    """Run the batch in `worktree` and read its runs back (see the module docstring for what is isolated)."""
    environment = dict(os.environ)
    environment["PYTHONPATH"] = os.pathsep.join([str(worktree), *filter(None, [environment.get("PYTHONPATH")])])
    junit.unlink(missing_ok=True)
    process = subprocess.Popen(request.pytest_arguments(junit), cwd=worktree, env=environment,
                               stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                               text=True, errors="replace", start_new_session=True, preexec_fn=_die_with_parent)
    try:
        output, _ = process.communicate(timeout=request.timeout)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)  # the test's probe workers too: they are in its session
        with contextlib.suppress(subprocess.TimeoutExpired):  # a process that left the group may hold the pipe
            process.communicate(timeout=KILLED_WAIT)
        process.wait()
        return BatchResult(cannot_run=f"pytest did not finish in {request.timeout:g} s (a hung test; "
                                      "--run-timeout)", hung=True)
    except BaseException:
        os.killpg(process.pid, signal.SIGKILL)
        process.wait()
        raise
    if process.returncode not in (0, 1):  # 2 interrupted or collection errors, 3 internal, 4 usage, 5 no tests
        return BatchResult(cannot_run=f"pytest exited with {process.returncode}: {_tail(output)}")
    return _read_junit(junit, request, output)


def _die_with_parent() -> None:
    """In the pytest child, before it runs: SIGKILL when `ddenv bisect` dies, even by kill -9 (Linux; its probe
    workers end when their pipes to it close). Elsewhere, a killed bisect leaves its batch running to its end."""
    if sys.platform.startswith("linux"):
        import ctypes

        pr_set_pdeathsig = 1
        ctypes.CDLL(None, use_errno=True).prctl(pr_set_pdeathsig, int(signal.SIGKILL), 0, 0, 0)


def _tail(output: str) -> str:
    lines = [line for line in output.strip().splitlines() if line.strip()]
    errors = [line for line in lines if line.startswith(("E ", "ERROR", "ImportError", "ModuleNotFoundError"))]
    text = " | ".join((errors or lines)[-3:])
    return text[-OUTPUT_TAIL:] if text else "(no output)"


def _read_junit(junit: Path, request: BatchRequest, output: str) -> BatchResult:
    try:
        root = ElementTree.parse(junit).getroot()
    except (OSError, ElementTree.ParseError) as error:
        return BatchResult(cannot_run=f"no JUnit XML from pytest ({error}): {_tail(output)}")
    cases = []
    for case in root.iter("testcase"):
        properties = {item.get("name", ""): item.get("value", "") for item in case.iter("property")}
        if "ddenv_rate_runs" in properties:
            cases.append(properties)
    if len(cases) != 1:
        found = "no test" if not cases else f"{len(cases)} tests"
        return BatchResult(cannot_run=f"{found} with --ddenv-rate results in the JUnit XML (does {request.test} "
                                      f"use robot_world at this commit?): {_tail(output)}")
    return BatchResult(runs=tuple(_runs_of(cases[0], request)))


def _runs_of(properties: Mapping[str, str], request: BatchRequest) -> list[dict[str, Any]]:
    runs = []
    for local in range(request.count):
        index = request.first + local
        text = properties.get(f"ddenv_run_{local}")
        record = _record(text, index, request.run_seed(index))
        runs.append(record)
    return runs


def _record(text: str | None, index: int, seed: int) -> dict[str, Any]:
    """A run's JSON object with "run" set to the bisect's index; a missing or malformed one is an error run."""
    try:
        record = json.loads(text) if text is not None else None
    except ValueError:
        record = None
    if not isinstance(record, dict) or record.get("outcome") not in RUN_OUTCOMES:
        return {"run": index, "seed": seed, "outcome": "error", "type": None, "predicate": None, "signature": None,
                "location": None, "message": "no ddenv_run property for this run in the JUnit XML"}
    if record.get("seed") != seed:
        return {**record, "run": index, "seed": seed, "outcome": "error",
                "message": f"ran seed {record.get('seed')!r}, not the paired seed {seed}"}
    return {**record, "run": index}
