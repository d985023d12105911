"""Issue 33: the drift watch on a real reduction. Friction under any-of-1 (`--deflake 0`: one failing run
accepts a 7-model world that fails 1 of its first 5 fresh runs (the original: every run); the watch's
confirming runs flag it and its search decision on the first look backs off during the reduction (5 runs of
the world and 5 of the original, which the end-of-run comparison reuses), the reduction goes on from the
world before it, and a rerun on the same folder resumes with no new reduction run."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from pytest_ddenv.cli.main import main

FRICTION = Path(__file__).parents[1] / "worlds" / "friction.yaml"


def reduce(out: Path) -> dict[str, Any]:
    code = main(["reduce", str(FRICTION), "-p", "stuck:window=5,min_progress=0.2", "--deflake", "0", "--workers", "1",
                 "--out", str(out), "-q", "--media", "none"])
    assert code == 0
    return json.loads((out / "summary.json").read_text())


@pytest.mark.slow
@pytest.mark.pybullet  # which world drifts, and on which attempts it fails, are PyBullet's runs
def test_friction_drift_is_caught_during_the_reduction_and_resumed_without_new_runs(tmp_path: Path) -> None:
    summary = reduce(tmp_path / "out")
    assert summary["minimal_models"] == ["grey_wall", "grey_wall_0", "grey_wall_clone_clone_5",
                                         "Construction Barrel_1"]
    assert summary["one_minimal"] and summary["rate_check"]["decision"] == "holds", summary["rate_check"]
    notes = [note for note in summary["notes"] if note.startswith("back-off")]
    assert notes and all("accepted world (drift watch, during the reduction)" in note for note in notes), notes
    assert "fails 1/5 fresh runs vs the original's 5/5: below the original's at the drift watch's search level" \
        in notes[0], notes[0]
    log = [json.loads(line) for line in (tmp_path / "out" / "runs.jsonl").read_text().splitlines() if line.strip()]
    below = [event for event in log if event.get("event") == "rate-below"]
    steps = [event for event in log if event.get("event") == "step"]
    assert below and len(below[0]["candidate"]) == 7
    assert steps[-1]["size"] == 4 and log.index(below[0]) < log.index(steps[-1]), "caught before the end"
    original = [event["attempt"] for event in log if event.get("purpose") == "failure-rate" and
                len(event["candidate"]) == 25]
    assert original == [1, 2, 3, 4, 5], "the original's first look only, each run once (the end reuses them)"

    again = reduce(tmp_path / "out")
    assert again["minimal_models"] == summary["minimal_models"] and again["notes"] == summary["notes"]
    assert again["resumed_probes"] == again["probes"] == summary["probes"], "no new reduction run"
    assert again["this_run"]["simulations"] <= 1, "at most the original's confirmation run"
