"""The typed result of one reduction: built once by the driver, written as `summary.json`, worded by the report.

`ReductionReport` joins the engine's `Reduction` (what was removed, the probes, the failure rate) with what
only the driver knows (the test, the reference failure, the files written, every simulation started and its
CPU time, the stages and the media) and with the caller's own settings (`run_settings`: predicates, noise
seed, command line, imports). `to_json()` is the `summary.json` format (`SUMMARY_FORMAT`); the pytest report
section, the terminal line and `ddenv reduce` read the typed fields.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pytest_ddenv.reduce import Reduction

if TYPE_CHECKING:
    from pytest_ddenv.driver.cross_engine import CrossEngine
    from pytest_ddenv.driver.other_failures import OtherFailure, Reproduction
    from pytest_ddenv.oracle.verdict import SameFailureRule
    from pytest_ddenv.stages import StagesOutcome

SUMMARY_FORMAT = 1


@dataclass(frozen=True)
class Cost:
    """Every simulation the reduction started and the worker CPU time they took, earlier (resumed) runs of
    the same reduction included; `this_run_*`: this run alone; `workers`: the pool's counters."""

    probes: int
    simulations: int
    cpu_seconds: float
    this_run_simulations: int = 0
    this_run_cpu_seconds: float = 0.0
    workers: Mapping[str, Any] = field(default_factory=dict)
    resumed_runs: int = 0
    """The earlier runs of this reduction in the log (killed or interrupted ones included)."""
    cpu_seconds_complete: bool = True
    """False when an earlier run was killed before it recorded its CPU time."""

    def to_json(self) -> dict[str, Any]:
        return {"probes": self.probes, "simulations": self.simulations, "cpu_seconds": round(self.cpu_seconds, 3),
                "this_run": {"simulations": self.this_run_simulations,
                             "cpu_seconds": round(self.this_run_cpu_seconds, 3)},
                "workers": dict(self.workers)}


@dataclass(frozen=True)
class ReportFiles:
    """The files of the reduction in its artifacts folder (`minimal_sdf`: None when none was written)."""

    minimal_yaml: Path
    log: Path
    summary: Path
    minimal_sdf: Path | None = None
    other_worlds: tuple[Path, ...] = ()
    """`other-1.yaml`, `other-2.yaml` ...: the smallest worlds of the other failures kept (`--ddenv-keep-other`)."""
    minimal_xml: Path | None = None
    """`minimal.xml`, of a world read from an MJCF scene (None: not written)."""

    @property
    def folder(self) -> Path:
        return self.summary.parent

    def to_json(self) -> dict[str, str]:
        files = {"minimal_yaml": str(self.minimal_yaml), "log": str(self.log), "summary": str(self.summary)}
        if self.minimal_sdf is not None:
            files["minimal_sdf"] = str(self.minimal_sdf)
        if self.minimal_xml is not None:
            files["minimal_xml"] = str(self.minimal_xml)
        for number, path in enumerate(self.other_worlds, start=1):
            files[f"other_{number}_yaml"] = str(path)
        return files


@dataclass(frozen=True)
class ReductionReport:
    """One reduction's result; see the module docstring."""

    test: str
    world: str
    """The original world's file (or name when it has none)."""
    reduction: Reduction
    reference_failure: Mapping[str, Any]
    replay: str
    fingerprint: str
    files: ReportFiles
    cost: Cost
    tolerance: float
    minimal_sdf: str | None = None
    """How `minimal.sdf` was made ("cut" from the user's file, "generated"), None: not written."""
    minimal_xml: str | None = None
    """How `minimal.xml` was made ("cut from ...", "regenerated: ...", "not written: ..."); None: the world is
    not an MJCF scene."""
    notes: tuple[str, ...] = ()
    world_notes: tuple[str, ...] = ()
    """What the world file holds that is not simulated (joints, plugins, lights ...)."""
    stages: StagesOutcome | None = None
    stage_files: Mapping[str, str] = field(default_factory=dict)
    media: Mapping[str, Any] | None = None
    """The animations and recording written: {"files": {name: info}, "seconds": s}."""
    run_settings: Mapping[str, Any] = field(default_factory=dict)
    """The caller's own entries of `summary.json` (predicates, scenario_seed, timeout, command, imports ...)."""
    other_failures: tuple[OtherFailure, ...] = ()
    """The other failures the reduction's probes met, grouped, largest first (`pytest_ddenv.driver.other_failures`)."""
    same_failure: SameFailureRule | None = None
    """The rule that decided which failures are the reference failure (None: the default rule, `tolerance`)."""
    engine: str = ""
    """The physics engine that ran every probe and its version ("pybullet 3.2.7"; empty: not known)."""
    cross_engine: CrossEngine | None = None
    """The minimal and original worlds' failure rates in other engines (`--ddenv-confirm-engines`), if asked."""
    reproduction: Reproduction | None = None
    """Set when the original world's fresh runs rarely failed the same way: how often, and the reason seen most
    (`other_failures.original_reproduction`)."""

    @property
    def rule(self) -> SameFailureRule:
        from pytest_ddenv.oracle.verdict import SameFailureRule

        return self.same_failure if self.same_failure is not None else SameFailureRule(tolerance=self.tolerance)

    @property
    def removed_models(self) -> list[str]:
        return list(self.reduction.removed)

    @property
    def reduction_percent(self) -> float:
        return percent_removed(self.reduction.original_size, self.reduction.minimal_size)

    def with_media(self, files: Mapping[str, Any], seconds: float) -> ReductionReport:
        return replace(self, media={"files": dict(files), "seconds": round(seconds, 3)})

    def to_json(self) -> dict[str, Any]:
        """The `summary.json` of the reduction (plain JSON types)."""
        reduction = self.reduction
        fails, runs = reduction.failure_rate
        summary: dict[str, Any] = {
            **identity_json(self.test, self.world, reduction.original, reduction.minimal),
            "complete": reduction.incomplete_reason is None,
            "incomplete_reason": reduction.incomplete_reason,
            "one_minimal": reduction.one_minimal,
            "kept_models": list(reduction.kept),
            "resumed_probes": reduction.resumed_probes,
            "cache_hits": reduction.cache_hits,
            "skipped": reduction.skipped,
            "errors": reduction.errors,
            "errored_candidates": reduction.errored,
            "steps": [list(step) for step in reduction.steps],
            "failure_rate": {"fails": fails, "runs": runs},
            "original_failure_rate": _rate_json(reduction.original_failure_rate),
            "rate_check": None if reduction.rate_check is None else {
                "decision": reduction.rate_check.decision,
                "p_value": round(reduction.rate_check.p_value, 6),
                "level_per_look": round(reduction.rate_check.level, 6),
                "original_runs_skipped": reduction.rate_check.skipped,
                "backoffs": reduction.rate_backoffs,
            },
            "needed_models": list(reduction.needed),
            "precondition_kept": [{"model": name, "reason": reason} for name, reason in reduction.precondition_kept],
            "without_precondition_kept": _rate_json(reduction.without_precondition_kept),
            "first_cut": None if reduction.first_cut is None else reduction.first_cut.to_json(),
            "wall_time": round(reduction.wall_time, 3),
            "schemas": {"partition": reduction.partition, "priority": reduction.priority,
                        "granularity": reduction.granularity, "deflake": reduction.deflake},
            "seed": reduction.seed,
            "engine": _engine_json(self.engine),
            "reference_failure": dict(self.reference_failure),
            "replay": self.replay,
            "fingerprint": self.fingerprint,
            "files": self.files.to_json(),
            "minimal_sdf": self.minimal_sdf,
            **({} if self.minimal_xml is None else {"minimal_xml": self.minimal_xml}),
            **dict(self.run_settings),
            "tolerance": self.tolerance,
            "same_failure": self.rule.to_json(),
            "original_reproduction": None if self.reproduction is None else self.reproduction.to_json(),
            "notes": list(self.notes),
            "world_notes": list(self.world_notes),
            **self.cost.to_json(),
            "resumed_runs": self.cost.resumed_runs,
            "cpu_seconds_complete": self.cost.cpu_seconds_complete,
            "other_failures": [failure.to_json() for failure in self.other_failures],
        }
        if self.stages is not None:
            summary["stages"] = self.stages.to_dict()
            summary["stage_files"] = dict(self.stage_files)
        if self.media is not None:
            summary["media"] = dict(self.media)
        if self.cross_engine is not None:
            summary["cross_engine"] = self.cross_engine.to_json()
        return summary


def _engine_json(engine: str) -> dict[str, str] | None:
    """{"name": "pybullet", "version": "3.2.7"} (None: not known)."""
    name, _, version = engine.partition(" ")
    return {"name": name, "version": version} if name else None


def identity_json(test: str, world: str, original: Sequence[str], minimal: Sequence[str]) -> dict[str, Any]:
    """The entries a summary has whether final or provisional (`provisional_summary`): which test and
    world, and which models the (best so far) minimal world keeps."""
    kept = set(minimal)
    return {
        "format": SUMMARY_FORMAT,
        "test": test,
        "world": world,
        "original_size": len(original),
        "minimal_size": len(minimal),
        "reduction_percent": percent_removed(len(original), len(minimal)),
        "minimal_models": list(minimal),
        "removed_models": [name for name in original if name not in kept],
    }


def percent_removed(original_size: int, minimal_size: int) -> float:
    return round(100.0 * (1 - minimal_size / max(original_size, 1)), 1)


def _rate_json(rate: tuple[int, int] | None) -> dict[str, int] | None:
    return None if rate is None else {"fails": rate[0], "runs": rate[1]}


def provisional_summary(*, test_id: str, world: str, original: Sequence[str], best: Sequence[str],
                        problem_fingerprint: str, replay_command: str, reference: Mapping[str, Any],
                        counts: Mapping[str, Any], files: ReportFiles,
                        extra: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The summary of a reduction in progress (``"complete": false``, ``"incomplete_reason": "in progress"``),
    with the best world so far: what a reduction stopped at any moment leaves behind."""
    return {
        **identity_json(test_id, world, original, best),
        "complete": False,
        "incomplete_reason": "in progress",
        "provisional": True,
        "one_minimal": False,
        **dict(counts),
        "reference_failure": dict(reference),
        "replay": replay_command,
        "fingerprint": problem_fingerprint,
        "files": files.to_json(),
        **dict(extra or {}),
    }


def world_independent_summary(*, test_id: str, world: str, original_size: int, kept: Sequence[str], message: str,
                              reference: Mapping[str, Any], counts: Mapping[str, Any], log: Path,
                              summary: Path) -> dict[str, Any]:
    """The summary of a failure that does not depend on the world (its world without the removable models
    fails the same way): nothing was reduced."""
    return {
        "format": SUMMARY_FORMAT, "test": test_id, "world": world,
        "original_size": original_size, "status": "world-independent", "complete": True, "message": message,
        "kept_models": list(kept),
        "reference_failure": dict(reference), **dict(counts),
        "files": {"log": str(log), "summary": str(summary)},
    }
