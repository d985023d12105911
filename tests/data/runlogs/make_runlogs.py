"""How the run logs in this folder were made, by the release before the typed run log of issue 29 (pytest-ddenv
0.1.0 at commit 7cba542): a real `ddenv reduce` of the yard world (tests/data/yard.yaml), run to the end
(complete/) and killed with SIGKILL mid-reduction (killed/). Run from the repository root: ``python
tests/data/runlogs/make_runlogs.py``. They are the fixtures of tests/test_old_run_logs.py (they read the same)
and tests/reliability/test_old_run_logs_resume.py (they still resume); do not make them again with a later
release."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
SLOW = '''\
import time
from pytest_ddenv.sim.controllers import GoToGoal

class Slow(GoToGoal):  # the built-in law, paused once per run: slow enough to be caught
    def reset(self, observation):
        time.sleep(0.25)
'''
COMMAND = [sys.executable, "-m", "pytest_ddenv.cli", "reduce", "yard.yaml", "-p", "stuck:window=2.0,min_progress=0.2",
           "--partition", "even", "--priority", "sequential", "--deflake", "1", "--out", "out", "--workers", "1",
           "--import", "slow.py", "--controller", "slow.py:Slow", "--media", "none", "--stages", "all"]


def project() -> Path:
    folder = Path(tempfile.mkdtemp())
    shutil.copy(HERE.parent / "yard.yaml", folder / "yard.yaml")
    (folder / "slow.py").write_text(SLOW)
    return folder


def lines(log: Path) -> list[str]:
    data = log.read_bytes() if log.exists() else b""
    return data[: data.rfind(b"\n") + 1].decode().splitlines()


def main() -> None:
    done = project()
    subprocess.run(COMMAND, cwd=done, check=True)
    (HERE / "complete").mkdir(exist_ok=True)
    shutil.copy(done / "out" / "runs.jsonl", HERE / "complete" / "runs.jsonl")
    killed = project()
    process = subprocess.Popen(COMMAND, cwd=killed, start_new_session=True)
    while True:
        found = lines(killed / "out" / "runs.jsonl")
        verdicts = sum('"event": "accept"' in line or '"event": "reject"' in line for line in found)
        if any('"event": "step"' in line for line in found) and verdicts >= 3:
            break
        time.sleep(0.02)
    os.killpg(process.pid, signal.SIGKILL)
    process.wait()
    (HERE / "killed").mkdir(exist_ok=True)
    shutil.copy(killed / "out" / "runs.jsonl", HERE / "killed" / "runs.jsonl")


if __name__ == "__main__":
    main()
