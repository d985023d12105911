"""Ctrl-C or SIGTERM in the middle of a reduction: nothing is lost, and the next run resumes."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from pytest_ddenv import World

from .conftest import SCENARIO_TEST

pytestmark = pytest.mark.slow  # real reductions (subprocesses, simulations): the full tier only

SLOW_SCENARIO_TEST = SCENARIO_TEST.replace(
    'partition="model2model", priority="avg-trajectory"', 'partition="even", priority="sequential"'
).replace(
    "    run = robot_world.run()\n",
    "    import time\n"
    "    time.sleep(0.25 if len(robot_world.world) < 31 else 0)  # probes slow enough to be interrupted\n"
    "    run = robot_world.run()\n",
)

YARD_WORLD = (Path(__file__).resolve().parents[1] / "data" / "yard.yaml").read_text(encoding="utf-8")


def default_signal_handlers() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def probe_records(log: Path) -> list[dict]:
    records = [json.loads(line) for line in log.read_text().splitlines()]
    return [r for r in records if r.get("event") == "probe" and r.get("purpose") == "reduce"]


@pytest.mark.parametrize(("signal_number", "workers"), [(signal.SIGTERM, "1"), (signal.SIGINT, "1"), (signal.SIGINT, "2")])
def test_interrupted_reduction_keeps_everything_and_the_rerun_resumes(
    pytester: pytest.Pytester, signal_number: int, workers: str
) -> None:
    pytester.makefile(".yaml", wall=YARD_WORLD)
    pytester.makepyfile(test_scenario=SLOW_SCENARIO_TEST)
    command = [sys.executable, "-m", "pytest", "--ddenv-reduce", "--ddenv-workers", workers, "-p", "no:cacheprovider"]
    process = subprocess.Popen(  # the signal goes to this child only, never to the test process
        command, cwd=pytester.path, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        preexec_fn=default_signal_handlers,  # a background job (CI, nohup) inherits SIGINT ignored
        start_new_session=True,
    )
    deadline = time.monotonic() + 120  # a hang guard, not a speed check
    logs: list[Path] = []
    while time.monotonic() < deadline and process.poll() is None:
        logs = list(Path(pytester.path, "ddenv-artifacts").glob("*/runs.jsonl"))
        if logs and len(probe_records(logs[0])) >= 3:
            break
        time.sleep(0.05)
    assert process.poll() is None, "the reduction ended before it could be interrupted"
    process.send_signal(signal_number)
    output, _ = process.communicate(timeout=120)
    assert process.returncode == pytest.ExitCode.INTERRUPTED, output
    assert "ReductionInterrupted: reduction interrupted after" in output  # pytest's own interrupt report

    folder = logs[0].parent
    summary = json.loads((folder / "summary.json").read_text())
    assert summary["complete"] is False and summary["incomplete_reason"] == "interrupted"
    assert World.load(folder / "minimal.yaml").names == tuple(summary["minimal_models"])
    assert "wall" in summary["minimal_models"]
    first_run = probe_records(logs[0])
    decided = {(frozenset(r["candidate"]), r["attempt"]) for r in first_run}

    resumed = subprocess.run(command, cwd=pytester.path, capture_output=True, text=True, timeout=300, check=False)
    assert resumed.returncode == pytest.ExitCode.TESTS_FAILED, resumed.stdout
    final = json.loads((folder / "summary.json").read_text())
    assert final["complete"] is True and final["minimal_models"] == ["wall"]
    new_probes = probe_records(logs[0])[len(first_run):]
    assert not {(frozenset(r["candidate"]), r["attempt"]) for r in new_probes} & decided
    assert final["cache_hits"] >= 1
