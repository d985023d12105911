"""A run log written by the release before the typed run log (issue 29) reads the same: every reader of
`runs.jsonl` (resume, usage, the pictures, other failures, the stages, `ddenv replay`'s recorded seeds,
`ddenv show --runs`) gives the answers that release gave on the two logs in tests/data/runlogs (a real
reduction of the yard world, complete and killed mid-reduction; tests/data/runlogs/make_runlogs.py).
`read_by_release.json` holds those answers, computed by that release's readers; the resume itself is
tests/reliability/test_old_run_logs_resume.py."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path
from typing import Any

import pytest

from pytest_ddenv.cli.replay import recorded_seeds
from pytest_ddenv.cli.show_command import _read_runs
from pytest_ddenv.driver import picture_data
from pytest_ddenv.driver.artifacts import usage_of
from pytest_ddenv.driver.other_failures import other_failures
from pytest_ddenv.driver.run import _last_step
from pytest_ddenv.reduce.log import ProbeLog
from pytest_ddenv.stages.explain import logged_without
from pytest_ddenv.stages.structure import touched_at_failure

RUNLOGS = Path(__file__).parent / "data" / "runlogs"
LOGS = ("complete", "killed")


def _decisions(log: ProbeLog) -> list[list[Any]]:
    return sorted([sorted(key), decision.reproduces, decision.fails, decision.runs]
                  for key, decision in log.decisions().items())


def readings(path: Path) -> dict[str, Any]:
    """What every reader of a run log makes of the log at `path` (a copy: opening a log may repair it)."""
    log = ProbeLog(path)
    started = log.started_with()
    elements = [] if started is None else list(started[0])
    minimal = _last_step(log.own_events()) or ()
    _, poses, outcomes = _read_runs(path)
    return {
        "records": len(log.events), "notes": log.notes,
        "started_with": None if started is None else [list(part) for part in started],
        "calibration": log.calibration(), "decisions": _decisions(log),
        "partial_runs": sorted([sorted(key), [outcome.value for outcome in outcomes]]
                               for key, outcomes in log.partial_runs().items()),
        "measured": {purpose: {str(attempt): outcome.value for attempt, outcome in
                               sorted(log.measured(purpose, elements).items())}
                     for purpose in ("calibration", "failure-rate", "independence")},
        "decided_probes": log.decided_probes(), "last_step": list(minimal),
        "usage": vars(usage_of(log.events)),
        "stages": {stage: {"decisions": _decisions(log.view(stage)), "records": len(log.view(stage).own_events()),
                           "failure-rate": {label: {str(attempt): outcome.value for attempt, outcome in sorted(
                               log.view(stage).measured("failure-rate", [label]).items())}
                               for label in ("minimal world", "time world")}}
                   for stage in ("time", "one-minimal", "rates")},
        "explain": logged_without(log, minimal, minimal[0]) if minimal else None,
        "touched": sorted(touched_at_failure(log.probes(), minimal)),
        "probe_sizes": [list(entry) for entry in picture_data.probe_sizes_from_log(path)],
        "steps": [list(entry) for entry in picture_data.steps_from_log(path)],
        "accepted_probes": sorted(picture_data.accepted_probes_from_log(path)),
        "other_failures": [group.to_json() for group in other_failures(log.events)],
        "recorded_seeds": recorded_seeds(path, minimal, -1),
        "show_runs": [poses, outcomes],
    }


def _copy(name: str, folder: Path) -> Path:
    path = folder / f"{name}.jsonl"
    shutil.copy(RUNLOGS / name / "runs.jsonl", path)
    return path


@pytest.mark.parametrize("name", LOGS)
def test_an_old_run_log_reads_the_same(name: str, tmp_path: Path) -> None:
    expected = json.loads((RUNLOGS / "read_by_release.json").read_text())[name]
    assert json.loads(json.dumps(readings(_copy(name, tmp_path)))) == expected


if __name__ == "__main__":  # write read_by_release.json (only with the release that wrote the logs)
    import tempfile

    folder = Path(tempfile.mkdtemp())
    found = {name: readings(_copy(name, folder)) for name in LOGS}
    (RUNLOGS / "read_by_release.json").write_text(json.dumps(found, indent=1) + "\n")
    sys.exit(0)
