"""`ddenv bisect`: the first commit at which a scenario test fails, between a good and a bad revision.

Each commit is run in a detached git worktree of it (`driver/_git.py`), in batches of paired runs
(`driver/_git_pytest.py`: run i uses the same run seed at every commit), and decided by Wald's sequential
probability ratio test (`SequentialTest`) of "fails the same way as the reference like a bad commit"
against "passes like a good one"; other failures count as not failing and are reported. A commit the test
cannot run at, or whose runs the budget leaves undecided, is skipped (as `git bisect skip`). The search is a
binary search along the bad revision's first-parent line. Every run is journaled (`BisectJournal`) in the
bisect's folder, so a rerun after a kill starts no simulation it already has. docs/cli.md, "ddenv bisect".
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from pytest_ddenv import defaults
from pytest_ddenv.driver._git import (
    Commit,
    GitError,
    add_worktree,
    first_parent_line,
    remove_worktree,
    repository_root,
    resolve,
)
from pytest_ddenv.driver._git_pytest import BatchRequest, run_batch, run_seed
from pytest_ddenv.driver.artifacts import ArtifactsError, FolderLock
from pytest_ddenv.errors import DdenvError, shown
from pytest_ddenv.oracle.predicates import FailureSignature
from pytest_ddenv.oracle.verdict import ErrorInfo, FailureReference, SameFailureRule, classify_result
from pytest_ddenv.outcome import Outcome

JOURNAL_VERSION = 1
DEFAULT_GOOD_RATE = 0.05
DEFAULT_BAD_RATE = 0.6
DEFAULT_LEVEL = 0.02
DEFAULT_MAX_RUNS = 20
DEFAULT_RUN_TIMEOUT = 900.0
FIRST_BATCH = 3

Decision = Literal["good", "bad", "undecided"]


class BisectError(DdenvError):
    """`ddenv bisect` cannot start or cannot go on (a bad input, the bad revision does not fail)."""


class BadRevisionPasses(BisectError):
    """The bad revision does not fail like the reference (or its verdict is undecided, or it cannot run)."""


# -- the sequential test -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class SequentialTest:
    """Wald's SPRT of H1 "fails at `bad_rate`" against H0 "fails at `good_rate`", with error levels `level`
    both ways (calling a good commit bad, or a bad one good, each with probability about `level`).
    The log-likelihood ratio is updated run by run, in run order; the first crossing decides."""

    good_rate: float = DEFAULT_GOOD_RATE
    bad_rate: float = DEFAULT_BAD_RATE
    level: float = DEFAULT_LEVEL

    def __post_init__(self) -> None:
        if not 0 < self.good_rate < self.bad_rate < 1:
            raise BisectError(f"the rates must satisfy 0 < --good-rate < --bad-rate < 1, got {self.good_rate:g} "
                              f"and {self.bad_rate:g}")
        if not 0 < self.level < 0.5:
            raise BisectError(f"--level must be between 0 and 0.5, got {self.level:g}")

    def decide(self, fails: Sequence[bool]) -> tuple[Decision, int]:
        """The decision on these runs (True: failed the same way) and how many runs it took."""
        upper = math.log((1 - self.level) / self.level)
        step_fail = math.log(self.bad_rate / self.good_rate)
        step_pass = math.log((1 - self.bad_rate) / (1 - self.good_rate))
        ratio = 0.0
        for used, failed in enumerate(fails, start=1):
            ratio += step_fail if failed else step_pass
            if ratio >= upper:
                return "bad", used
            if ratio <= -upper:
                return "good", used
        return "undecided", len(fails)


# -- what is bisected ------------------------------------------------------------------------------------
@dataclass(frozen=True)
class BisectTarget:
    """The test, the world it runs on, the reference failure (None: the first failure at the bad revision)
    and the same-failure rule, and the seed of run 0."""

    test: str
    world: Path
    reference: FailureReference | None
    rule: SameFailureRule
    seed: int = 0

    @property
    def world_digest(self) -> str:
        return hashlib.sha256(self.world.read_bytes()).hexdigest()


def target_from_artifacts(folder: Path, seed: int | None = None) -> BisectTarget:
    """The test id, minimal world, reference failure, rule and seed of a reduction's artifacts folder."""
    summary_path = folder / "summary.json"
    if not folder.is_dir():
        raise ArtifactsError(f"{folder}: no such artifacts folder")
    if not summary_path.is_file():
        raise ArtifactsError(f"{summary_path}: missing; is {folder} a ddenv artifacts folder?")
    try:
        summary = json.loads(summary_path.read_text(encoding="utf-8"))
        test = summary["test"]
        reference_data = summary["reference_failure"]
        signature = reference_data.get("signature")
        reference = FailureReference(str(reference_data["exception_type"]), str(reference_data["location"]),
                                     None if signature is None else FailureSignature.from_dict(signature))
        rule = SameFailureRule.from_json(summary.get("same_failure")
                                         or {"tolerance": summary.get("tolerance", defaults.TOLERANCE)},
                                         f"{summary_path}: same_failure")
        recorded_seed = int(summary.get("seed") or 0)
    except (ValueError, KeyError, TypeError, AttributeError) as error:
        raise ArtifactsError(f"{summary_path}: not a reduction's summary ({type(error).__name__}: {error})") from None
    if not isinstance(test, str) or "::" not in test:
        raise ArtifactsError(f"{summary_path}: 'test' is {shown(test)}, not a pytest test id (a folder of `ddenv "
                             "reduce` names no test: give --test ID --world FILE)")
    world = folder / "minimal.yaml"
    if not world.is_file():
        raise ArtifactsError(f"{world}: missing; the artifacts folder has no minimal world")
    return BisectTarget(test, world.resolve(), reference, rule, recorded_seed if seed is None else seed)


def target_from_test(test: str, world: Path, seed: int | None = None) -> BisectTarget:
    """`--test ID --world FILE`: the reference failure is the first one at the bad revision."""
    if not world.is_file():
        raise BisectError(f"{world}: no such world file (--world)")
    if "::" not in test:
        raise BisectError(f"--test {shown(test)}: expected a pytest test id, path/to/test_file.py::test_name")
    return BisectTarget(test, world.resolve(), None, SameFailureRule(), 0 if seed is None else seed)


# -- the journal -------------------------------------------------------------------------------------------
@dataclass
class BisectJournal:
    """Every run's outcome, appended and flushed as it comes (`journal.jsonl` in the bisect's folder): a run
    is keyed by commit, world content, test id and run seed; records of another world or test are kept in the
    file but never reused. A commit the test could not run at is journaled too."""

    path: Path
    test: str
    world_digest: str
    runs: dict[tuple[str, int], dict[str, Any]] = field(default_factory=dict)
    cannot_run: dict[str, dict[str, Any]] = field(default_factory=dict)
    foreign: int = 0
    """Records of another world or test (not reused)."""

    @classmethod
    def open(cls, path: Path, test: str, world_digest: str) -> BisectJournal:
        journal = cls(path, test, world_digest)
        if path.is_file():
            for line in path.read_text(encoding="utf-8", errors="replace").splitlines():
                journal._load(line)
        return journal

    def _load(self, line: str) -> None:
        try:
            entry = json.loads(line)
        except ValueError:  # a line cut by a kill: that run was not recorded
            return
        if not isinstance(entry, dict) or entry.get("version") != JOURNAL_VERSION:
            return
        if entry.get("test") != self.test or entry.get("world_sha256") != self.world_digest:
            self.foreign += 1
            return
        if entry.get("kind") == "run" and isinstance(entry.get("record"), dict):
            self.runs[(str(entry["commit"]), int(entry["record"]["seed"]))] = entry["record"]
        elif entry.get("kind") == "cannot_run":
            self.cannot_run[str(entry["commit"])] = entry

    def append(self, entries: Sequence[Mapping[str, Any]]) -> None:
        header = {"version": JOURNAL_VERSION, "test": self.test, "world_sha256": self.world_digest}
        self.path.parent.mkdir(parents=True, exist_ok=True)
        with self.path.open("a", encoding="utf-8") as stream:
            for entry in entries:
                stream.write(json.dumps({**header, **entry}, sort_keys=True) + "\n")
            stream.flush()
            os.fsync(stream.fileno())
        for entry in entries:
            if entry["kind"] == "run":
                self.runs[(entry["commit"], entry["record"]["seed"])] = dict(entry["record"])
            else:
                self.cannot_run[entry["commit"]] = dict(entry)


# -- one commit's verdict ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class CommitVerdict:
    commit: Commit
    decision: Literal["good", "bad", "skip"]
    fails: int = 0
    """Runs that failed the same way as the reference."""
    runs: int = 0
    """Runs with a verdict (errors left out)."""
    other: int = 0
    """Runs that failed another way (counted as not failing)."""
    errors: int = 0
    started: int = 0
    """Simulations started for this commit by this bisect (not from the journal)."""
    reused: int = 0
    """Runs read from the journal."""
    reason: str = ""
    """Why the commit is skipped; an example of another failure when there were some."""

    def describe(self) -> str:
        if self.decision == "skip" and not self.runs:
            return f"{self.commit.short} skip: {self.reason}"
        text = f"{self.commit.short} {self.decision}: fails {self.fails}/{self.runs}"
        if self.other:
            text += f", {self.other} other failure{'s' if self.other != 1 else ''} ({self.reason})"
        if self.errors:
            text += f", {self.errors} error{'s' if self.errors != 1 else ''}"
        if self.decision == "skip":
            text += " (undecided within --max-runs: skipped)"
        return text

    def to_dict(self) -> dict[str, Any]:
        return {"commit": self.commit.sha, "subject": self.commit.subject, "decision": self.decision,
                "fails": self.fails, "runs": self.runs, "other": self.other, "errors": self.errors,
                "started": self.started, "reused": self.reused, "reason": self.reason or None}


@dataclass(frozen=True)
class BisectSettings:
    good: str
    bad: str
    repository: Path
    folder: Path
    test: SequentialTest = SequentialTest()
    max_runs: int = DEFAULT_MAX_RUNS
    run_timeout: float = DEFAULT_RUN_TIMEOUT


@dataclass(frozen=True)
class BisectResult:
    good: Commit
    bad: Commit
    line: tuple[Commit, ...]
    """The commits searched, oldest first (the bad revision last)."""
    first_bad: Commit | None
    candidates: tuple[Commit, ...]
    """When skips leave more than one commit: those that could be the first bad one, oldest first."""
    verdicts: tuple[CommitVerdict, ...]
    """In the order they were evaluated."""
    reference: FailureReference

    @property
    def started(self) -> int:
        return sum(verdict.started for verdict in self.verdicts)

    @property
    def reused(self) -> int:
        return sum(verdict.reused for verdict in self.verdicts)

    @property
    def bound(self) -> int:
        """The most commit evaluations without skips: ceil(log2(commits)) + 1."""
        return math.ceil(math.log2(len(self.line))) + 1 if len(self.line) > 1 else 1

    def verdict_of(self, commit: Commit) -> CommitVerdict | None:
        return next((verdict for verdict in self.verdicts if verdict.commit == commit), None)

    def answer(self) -> str:
        if self.first_bad is None:
            listed = ", ".join(commit.describe() for commit in self.candidates)
            return (f"no single first bad commit: skipped commits leave {len(self.candidates)} that could be it "
                    f"(oldest first): {listed}")
        verdict = self.verdict_of(self.first_bad)
        assert verdict is not None
        text = f"first bad: {self.first_bad.describe()} - fails {verdict.fails}/{verdict.runs} there"
        index = self.line.index(self.first_bad)
        parent = self.line[index - 1] if index > 0 else None
        parent_verdict = None if parent is None else self.verdict_of(parent)
        if parent_verdict is not None:
            return text + f", {parent_verdict.fails}/{parent_verdict.runs} at its parent"
        return text + f"; its parent is the good revision {self.good.short} (given as good, not run)"

    def lines(self) -> list[str]:
        evaluated = len(self.verdicts)
        return [self.answer(),
                (f"{self.started + self.reused} simulations ({self.started} started now, {self.reused} from the "
                 f"journal); {evaluated} of {len(self.line)} commits evaluated (at most {self.bound} without skips)"),
                f"reference failure: {self.reference.describe()}"]

    def to_dict(self) -> dict[str, Any]:
        return {"ok": self.first_bad is not None,
                "first_bad": None if self.first_bad is None else {"commit": self.first_bad.sha,
                                                                  "subject": self.first_bad.subject},
                "candidates": [commit.sha for commit in self.candidates], "answer": self.answer(),
                "good": self.good.sha, "bad": self.bad.sha, "commits": len(self.line),
                "evaluations": len(self.verdicts), "bound": self.bound, "simulations": self.started + self.reused,
                "simulations_started": self.started, "simulations_reused": self.reused,
                "reference_failure": self.reference.to_dict(),
                "verdicts": [verdict.to_dict() for verdict in self.verdicts]}


# -- the search ------------------------------------------------------------------------------------------
def bisect(target: BisectTarget, settings: BisectSettings,
           report: Callable[[CommitVerdict], None] = lambda verdict: None) -> BisectResult:
    """Find the first commit of the bad revision's first-parent line after the good one at which the test
    fails the same way (see the module docstring); `report` is told each commit's verdict as it is taken."""
    repository = repository_root(settings.repository)
    good = resolve(repository, settings.good, "good")
    bad = resolve(repository, settings.bad, "bad")
    line = first_parent_line(repository, good, bad)
    settings.folder.mkdir(parents=True, exist_ok=True)
    with FolderLock(settings.folder):
        search = _Search(target, settings, repository,
                         BisectJournal.open(settings.folder / "journal.jsonl", target.test, target.world_digest))
        bad_verdict = search.evaluate(bad)
        report(bad_verdict)
        if bad_verdict.decision != "bad":
            raise BadRevisionPasses(f"the bad revision {bad.describe()} does not fail like the reference: "
                                    f"{bad_verdict.describe()}")

        def decide(index: int) -> str:
            verdict = search.evaluate(line[index])
            report(verdict)
            return verdict.decision

        low, high = binary_search(len(line), decide)
        first_bad = line[high] if high - low == 1 else None
        candidates = () if first_bad is not None else tuple(line[low + 1:high + 1])
        assert search.reference is not None
        return BisectResult(good, bad, tuple(line), first_bad, candidates, tuple(search.verdicts), search.reference)


def binary_search(count: int, decide: Callable[[int], str]) -> tuple[int, int]:
    """(last good, first bad) of positions 0 .. count - 1, position count - 1 known bad and -1 good, asking
    `decide(index)` ("good", "bad", anything else: skipped) at most ceil(log2(count)) times without skips.
    When skips leave positions between them, every one of them (and the first bad) could be the first bad."""
    low, high, skipped = -1, count - 1, set[int]()
    while (index := _next(low, high, skipped)) is not None:
        decision = decide(index)
        if decision == "bad":
            high = index
        elif decision == "good":
            low = index
        else:
            skipped.add(index)
    return low, high


def _next(low: int, high: int, skipped: set[int]) -> int | None:
    """The commit to evaluate next: the middle one between the last good and the first bad, else the
    unskipped one nearest to it (None: none left)."""
    inside = [index for index in range(low + 1, high) if index not in skipped]
    if not inside:
        return None
    middle = (low + high) / 2
    return min(inside, key=lambda index: (abs(index - middle), index))


@dataclass
class _Search:
    target: BisectTarget
    settings: BisectSettings
    repository: Path
    journal: BisectJournal
    verdicts: list[CommitVerdict] = field(default_factory=list)
    reference: FailureReference | None = None

    def __post_init__(self) -> None:
        self.reference = self.target.reference

    def evaluate(self, commit: Commit) -> CommitVerdict:
        verdict = self._evaluate(commit)
        self.verdicts.append(verdict)
        return verdict

    def _evaluate(self, commit: Commit) -> CommitVerdict:
        settings, target = self.settings, self.target
        known = self.journal.cannot_run.get(commit.sha)
        if known is not None and (not known.get("hung") or float(known.get("timeout", 0)) >= settings.run_timeout):
            return CommitVerdict(commit, "skip", reason=f"{known['reason']} (from the journal)")
        records = list(self._journaled(commit))
        reused, started = len(records), 0
        with self._worktree(commit) as worktree:
            while True:
                decision = self._decide(records)
                if decision != "undecided" or len(records) >= settings.max_runs:
                    break
                count = min(settings.max_runs, max(FIRST_BATCH, 2 * len(records))) - len(records)
                request = BatchRequest(target.test, target.world, target.seed, len(records), count,
                                       settings.run_timeout)
                junit = settings.folder / "junit" / f"{commit.short}-{len(records)}.xml"
                junit.parent.mkdir(parents=True, exist_ok=True)
                batch = run_batch(worktree(), request, junit)
                if batch.cannot_run:
                    self.journal.append([{"kind": "cannot_run", "commit": commit.sha, "reason": batch.cannot_run,
                                          "hung": batch.hung, "timeout": settings.run_timeout}])
                    return CommitVerdict(commit, "skip", started=started + (count if batch.hung else 0),
                                         reused=reused, reason=batch.cannot_run)
                self.journal.append([{"kind": "run", "commit": commit.sha, "record": dict(record)}
                                     for record in batch.runs])
                records += batch.runs
                started += count
        return self._verdict(commit, records, decision, started, reused)

    def _journaled(self, commit: Commit) -> Iterator[Mapping[str, Any]]:
        """The journaled runs of this commit in run order, up to the first one missing."""
        index = 0
        while (record := self.journal.runs.get((commit.sha, run_seed(self.target.seed, index)))) is not None:
            yield {**record, "run": index}
            index += 1

    def _worktree(self, commit: Commit) -> _LazyWorktree:
        return _LazyWorktree(self.repository, commit, self.settings.folder / "worktrees" / commit.short)

    def _outcomes(self, records: Sequence[Mapping[str, Any]]) -> list[Outcome]:
        if self.reference is None:  # --test/--world: the first failure at the bad revision is the reference
            first = next((record for record in records if record.get("outcome") == "failed"), None)
            if first is None:
                return [Outcome.ERROR if record.get("outcome") == "error" else Outcome.PASS for record in records]
            self.reference = FailureReference.of(_error_info(first))
        return [self._classify(record) for record in records]

    def _classify(self, record: Mapping[str, Any]) -> Outcome:
        assert self.reference is not None
        if record.get("outcome") == "error":
            return Outcome.ERROR
        if record.get("outcome") == "passed":
            return Outcome.PASS
        error = _error_info(record)
        if error.signature is None and self.reference.signature is None:  # lines move between commits: the
            same = (error.type_name == self.reference.exception_type  # type and the file decide
                    and error.location.rpartition(":")[0] == self.reference.location.rpartition(":")[0])
            return Outcome.FAIL if same else Outcome.OTHER
        return classify_result(error, self.reference, self.target.rule)

    def _decide(self, records: Sequence[Mapping[str, Any]]) -> Decision:
        outcomes = [outcome for outcome in self._outcomes(records) if outcome is not Outcome.ERROR]
        return self.settings.test.decide([outcome is Outcome.FAIL for outcome in outcomes])[0]

    def _verdict(self, commit: Commit, records: Sequence[Mapping[str, Any]], decision: Decision, started: int,
                 reused: int) -> CommitVerdict:
        outcomes = self._outcomes(records)
        other = [record for record, outcome in zip(records, outcomes, strict=True) if outcome is Outcome.OTHER]
        example = ""
        if other:
            first = other[0]
            example = f"e.g. {first.get('predicate') or first.get('type')}: {first.get('message') or ''}".strip()
        counted = [outcome for outcome in outcomes if outcome is not Outcome.ERROR]
        return CommitVerdict(commit, "skip" if decision == "undecided" else decision,
                             fails=sum(outcome is Outcome.FAIL for outcome in counted), runs=len(counted),
                             other=len(other), errors=len(outcomes) - len(counted), started=started, reused=reused,
                             reason=example)


def _error_info(record: Mapping[str, Any]) -> ErrorInfo:
    signature = record.get("signature")
    return ErrorInfo(str(record.get("type") or "?"), str(record.get("message") or ""),
                     str(record.get("location") or "?"),
                     signature=None if not isinstance(signature, Mapping) else FailureSignature.from_dict(signature))


class _LazyWorktree:
    """A worktree of the commit, added on first use and removed on exit (none when every run is journaled)."""

    def __init__(self, repository: Path, commit: Commit, folder: Path) -> None:
        self.repository, self.commit, self.folder = repository, commit, folder
        self.added = False

    def __enter__(self) -> Callable[[], Path]:
        return self._get

    def _get(self) -> Path:
        if not self.added:
            remove_worktree(self.repository, self.folder)  # one left by a killed bisect
            add_worktree(self.repository, self.commit, self.folder)
            self.added = True
        return self.folder

    def __exit__(self, *exc: object) -> None:
        if self.added:
            remove_worktree(self.repository, self.folder)


__all__ = ["BadRevisionPasses", "BisectError", "BisectResult", "BisectSettings", "BisectTarget", "CommitVerdict",
           "GitError", "SequentialTest", "binary_search", "bisect", "target_from_artifacts", "target_from_test"]
