"""What a front end hands to `run_reduction` (`ReductionPlan`: the world, the failure, the settings, the folder,
what identifies the problem), what it gets back (`ReductionOutcome`), and the schemas a plan's reduction uses
when there is no trajectory to guide them."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pytest_ddenv.driver.code_identity import CodeIdentity
from pytest_ddenv.driver.confirm import ConfirmationRun
from pytest_ddenv.driver.markers import ReductionSpec
from pytest_ddenv.driver.report import ReductionReport
from pytest_ddenv.media.writer import DEFAULT_MEDIA
from pytest_ddenv.oracle.verdict import FailureReference, SameFailureRule
from pytest_ddenv.reduce import Reduction, ReductionInterrupted

if TYPE_CHECKING:
    from pytest_ddenv.driver.media_phase import LaterMedia
    from pytest_ddenv.sim import Run
    from pytest_ddenv.world.model import World

TRAJECTORY_PARTITIONS = ("timeseg", "trajectoryseg")
TRAJECTORY_PRIORITIES = ("failure-proximal", "avg-trajectory-proximal", "min-trajectory-proximal", "timestep")


@dataclass(frozen=True)
class ReductionPlan:
    """What to reduce and how.

    `reference` is the failure to reproduce and `reference_run` the run it happened in (None: the test
    made no run and reported none, so trajectory-guided schemas fall back). `confirmed`: the failure was
    already seen on the pool (skip the confirmation runs), in `confirmations` (the caller's runs of the
    original world on the pool, logged as the confirmation runs: every simulation has its line in the run log).
    `fingerprint` (the settings), `test_source`, `code`
    and the world identify the problem for resume (`problem.problem_of`).
    """

    world: World
    test_id: str
    reference: FailureReference
    reference_run: Run | None
    spec: ReductionSpec
    artifacts: Path
    replay_command: str
    fingerprint: Mapping[str, Any]
    test_source: str = ""
    code: CodeIdentity = field(default_factory=CodeIdentity)
    """The code under test (`code_identity.identify`): part of the problem, so an edit starts a fresh log."""
    confirmed: bool = False
    confirmations: tuple[ConfirmationRun, ...] = ()
    run_settings: Mapping[str, Any] = field(default_factory=dict)
    """The caller's own entries of `summary.json` (predicates, noise seed, command line ...)."""
    model_paths: tuple[str, ...] = ()
    """The folders the world's SDF `model://` includes were found in (to cut `minimal.sdf` from the file)."""
    media: str = DEFAULT_MEDIA
    """What to show besides the files: "all" (pictures, animations, 3D recording), "pictures" or "none"
    (`pytest_ddenv.media`)."""
    keep_other: int = 0
    """Write the smallest worlds of this many other failures the probes met as `other-<k>.yaml`
    (`--ddenv-keep-other`, `ddenv reduce --keep-other`; `artifacts.write_other_worlds`)."""
    other_replay: Callable[[Path, int | None], str] | None = None
    """The command that replays a kept other failure: (its `other-<k>.yaml`, the run seed it failed with, None
    when unknown) -> command line; None: no command."""
    no_run_reason: str = ""
    """Why there is no `reference_run` when the caller knows better than "no run was made" (the run raised)."""
    same_failure: SameFailureRule | None = None
    """Which failures are the reference failure (None: `spec`'s match and tolerance, `spec.same_failure_rule()`)."""
    media_later: bool = False
    """Render the animations and recordings in a background process once the summary is written, the pictures
    first in that process (the outcome's `media`, which the caller finishes), instead of before `run_reduction`
    returns. Without animations or recordings to make, the pictures are drawn before it returns."""

    @property
    def rule(self) -> SameFailureRule:
        return self.same_failure if self.same_failure is not None else self.spec.same_failure_rule()


@dataclass
class ReductionOutcome:
    """What `run_reduction` did. `status`: "reduced" (maybe incomplete: see the reduction), "not-reproducible"
    (the confirmation runs never failed the same way), "world-independent" (the world without its removable
    models fails the same way: nothing to reduce) or "error" (the test could not be run: `message`)."""

    status: str
    message: str = ""
    report: ReductionReport | None = None
    """The result of a reduction (status "reduced"), also written as `summary.json`."""
    attachments: list[Path] = field(default_factory=list)
    interrupted: ReductionInterrupted | None = None
    minimal_run: Run | None = None
    media: LaterMedia | None = None
    """The pictures, animations and recordings still being made (`plan.media_later`): `media.finish()` waits for
    them and adds them to `summary.json`; their files are among the `attachments` already."""

    @property
    def reduction(self) -> Reduction | None:
        return None if self.report is None else self.report.reduction


def interrupted_outcome(stop: ReductionInterrupted) -> ReductionOutcome | None:
    """The outcome `run_reduction` wrote before Ctrl-C or SIGTERM stopped it (None: `reduce` itself was
    interrupted, or a caller of its own)."""
    return stop.outcome if isinstance(stop.outcome, ReductionOutcome) else None


NO_RUN = "the test made no robot_world.run() and no robot_world.report(), so there is no trajectory"


def schemas(spec: ReductionSpec, reference_run: Run | None, no_run_reason: str = "") -> tuple[str, str, list[str]]:
    """The partition and priority to use, and notes on any fallback (no trajectory to guide them)."""
    partition, priority, notes = spec.partition, spec.priority, []
    if reference_run is None:
        why = no_run_reason or NO_RUN
        if partition in TRAJECTORY_PARTITIONS:
            notes.append(f"{why}: partition {partition} -> model2model")
            partition = "model2model"
        if priority in TRAJECTORY_PRIORITIES:
            notes.append(f"{why}: priority {priority} -> sequential")
            priority = "sequential"
    return partition, priority, notes
