"""A run log written by the release before the typed run log (issue 29) still resumes: the logs in
tests/data/runlogs (a real `ddenv reduce` of the yard world, complete and killed mid-reduction with SIGKILL;
tests/data/runlogs/make_runlogs.py) are continued by a real `ddenv reduce` of the same problem, which
simulates no candidate they decided again (models and stages alike). What their readers make of them is
tests/test_old_run_logs.py."""

from __future__ import annotations

import json
import runpy
import shutil
from pathlib import Path
from typing import Any

import pytest

from .conftest import Project, decided, kill_group, records, simulated, wait_for

pytestmark = [pytest.mark.slow,  # real reductions (subprocesses, simulations): the full tier only
              pytest.mark.pybullet]  # the committed logs are pybullet runs: another engine is another problem

RUNLOGS = Path(__file__).resolve().parents[1] / "data" / "runlogs"
MAKER = runpy.run_path(str(RUNLOGS / "make_runlogs.py"))
IDENTITY = ("fingerprint", "parts", "code")
"""The header fields that name the problem by digests of today's code and of how it writes the world and the
settings (pytest-ddenv's version is part of them: a log of another release is never resumed by a user)."""


def _header_of_today(project: Project) -> dict[str, Any]:
    """The first record today's `ddenv reduce` writes for the fixtures' problem (started, then killed)."""
    fresh = project.path / "fresh"
    fresh.mkdir()
    shutil.copy(project.path / "yard.yaml", fresh / "yard.yaml")
    shutil.copy(project.path / "slow.py", fresh / "slow.py")
    process = Project(fresh).start(MAKER["COMMAND"])
    project.started.append(process)
    log = fresh / "out" / "runs.jsonl"
    wait_for(process, lambda: bool(records(log)), "the run log's first record")
    kill_group(process)
    return records(log)[0]


def _resume(project: Project, name: str) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """Resume the fixture log `name` in `project`; (its records, the records after the resumed run)."""
    (project.path / "slow.py").write_text(MAKER["SLOW"])
    (project.path / "out").mkdir()
    lines = (RUNLOGS / name / "runs.jsonl").read_text().splitlines(keepends=True)
    header, today = json.loads(lines[0]), _header_of_today(project)
    if header["fingerprint"] != today["fingerprint"]:  # the records are the point, not the versions' digests
        header.update({key: today[key] for key in IDENTITY})
        lines[0] = json.dumps(header) + "\n"
    project.log = lambda: project.path / "out" / "runs.jsonl"  # type: ignore[method-assign]
    project.log().write_text("".join(lines))
    before = records(project.log())
    resumed = project.run(MAKER["COMMAND"])
    assert resumed.returncode == 0, resumed.stdout
    after = records(project.log())
    assert after[: len(before)] == before, "the log is continued, not rewritten"
    return before, after


def _decided_by_stage(found: list[dict[str, Any]]) -> set[tuple[str | None, frozenset[str]]]:
    return {(r.get("stage"), frozenset(r["candidate"])) for r in found if r.get("event") in ("accept", "reject")}


def _check_nothing_decided_again(before: list[dict[str, Any]], after: list[dict[str, Any]]) -> None:
    new = after[len(before):]
    again = {candidate for candidate, _ in simulated(new)} & decided(before)
    assert again == set(), f"decided candidates simulated again: {again}"
    assert not set(simulated(new)) & set(simulated(before)), "no (candidate, attempt) simulated twice"
    # The drift watch's fresh runs (purpose "failure-rate") of worlds an old log accepted are new attempts of
    # them, which logs from before the watch lack (no (candidate, attempt) runs twice: checked above).
    probed = {(r.get("stage"), frozenset(r["candidate"])) for r in new
              if r.get("event") == "probe" and r.get("purpose") != "failure-rate"}
    assert probed & _decided_by_stage(before) == set(), "a stage simulated a candidate it had decided"


def test_an_old_complete_log_resumes_without_a_simulation_of_the_reduction(project: Project) -> None:
    before, after = _resume(project, "complete")
    _check_nothing_decided_again(before, after)
    new = after[len(before):]
    assert simulated(new) == [], "a complete log decided every candidate"
    summary = project.summary()
    assert summary["complete"] is True and summary["minimal_models"] == ["wall"]
    models = [record for record in before if "stage" not in record]
    assert summary["resumed_probes"] == summary["probes"] == len(simulated(models))


def test_an_old_log_killed_mid_reduction_resumes_and_finishes(project: Project) -> None:
    before, after = _resume(project, "killed")
    _check_nothing_decided_again(before, after)
    assert simulated(after[len(before):]), "the killed log left candidates to decide"
    summary = project.summary()
    assert summary["complete"] is True and summary["one_minimal"] is True and summary["minimal_models"] == ["wall"]
    assert summary["resumed_probes"] == len(simulated(before)) and summary["resumed_runs"] == 1
