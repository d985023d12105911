"""`ddenv replay`: re-run the minimal world of an artifacts folder and check that it still fails the same way.

A scenario run here is what the simplest scenario test does (`robot_world.run()` with failure predicates and
a controller): the same seeds (`RobotWorld`), the same `RobotFailure`, the same oracle and the same-failure rule
the reduction recorded (`oracle.SameFailureRule`); each run that failed otherwise says why. No pytest import.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pytest_ddenv import defaults
from pytest_ddenv.driver.artifacts import ArtifactsError
from pytest_ddenv.driver.scenario_job import run_scenario
from pytest_ddenv.errors import ControllerTimeout, raised_by_ddenv, shown
from pytest_ddenv.oracle.predicates import PredicateSpec
from pytest_ddenv.reduce import Outcome, events
from pytest_ddenv.reduce.log import read_events
from pytest_ddenv.reduce.rates import Rate, wilson_interval
from pytest_ddenv.reduce.records import json_value, read_regular
from pytest_ddenv.scenario.robot_world import DEFAULT_MAX_WALL_TIME, RobotFailure
from pytest_ddenv.validation import expected
from pytest_ddenv.world.model import World

if TYPE_CHECKING:  # pragma: no cover
    from pytest_ddenv.oracle.predicates import FailureSignature
    from pytest_ddenv.oracle.verdict import FailureReference, SameFailureRule
    from pytest_ddenv.sim import ControllerLike, Run

SUMMARY_LIMIT = 64 * 1024 * 1024
"""Bytes of a `summary.json` read back (one written by a reduction is a few kilobytes)."""
REFERENCE_LOCATION = "ddenv"
"""The `FailureReference.location` of a failure found by running a world's scenario (no test file)."""


ArtifactError = ArtifactsError
"""The old name of `ArtifactsError` (an artifacts folder is missing a file or holds something that cannot be
replayed), kept for one release."""


def predicates_to_json(predicates: Sequence[PredicateSpec]) -> list[dict[str, Any]]:
    """Predicates as recorded in summary.json: [{"name": ..., "params": {...}}, ...]."""
    return [spec.to_json() for spec in predicates]


def predicates_from_json(data: Any) -> tuple[PredicateSpec, ...]:
    """The inverse of `predicates_to_json`, validated by building each predicate. A predicate the test gave
    as an object is found by its name among the registered ones (`ddenv --import` the module registering it)."""
    from pytest_ddenv.oracle.predicates import PREDICATES, predicate_spec

    if not isinstance(data, list):
        raise ArtifactsError(expected("a list of {name, params}", data, "'predicates'"))
    specs = []
    for item in data:
        if not isinstance(item, Mapping) or not isinstance(item.get("name"), str) \
                or not isinstance(item.get("params") or {}, Mapping):
            raise ArtifactsError(expected("{name, params} for each predicate", item, "'predicates'"))
        if item["name"] not in PREDICATES:
            given = f" (the test gave it as {shown(item['object'])})" if "object" in item else ""
            raise ArtifactsError(
                f"predicate {shown(item['name'])}{given} is not registered here: pass --import MODULE (a module that "
                "calls pytest_ddenv.register_predicate), or --predicate, or replay with pytest (summary.json's "
                "'replay' command)"
            )
        specs.append(predicate_spec(item["name"], dict(item.get("params") or {})))
    return tuple(specs)


def reference_of(run: Run) -> FailureReference:
    """The failure a reduction of this run's world must reproduce."""
    from pytest_ddenv.oracle.verdict import FailureReference

    if run.failure is None:
        raise ValueError("the run did not fail")
    return FailureReference(RobotFailure.__qualname__, REFERENCE_LOCATION, run.failure)


# -- replay -------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ReplayRun:
    seed: int
    outcome: Outcome
    failure: FailureSignature | None
    raised: str = ""
    """What the run raised instead of finishing (a controller's exception), if anything."""
    run: Run | None = field(default=None, compare=False, repr=False)
    """The run itself (None when it raised)."""
    why: str = ""
    """Why a run whose failure is "other" is not the reference failure under the rule (`oracle.why_other`)."""


FRESH_FIRST_ATTEMPT = 1000
"""Fresh replay runs use attempts 1000, 1001, ...: seeds no reduction probe used (its attempts are small)."""
CONFIDENCE = 0.95


@dataclass(frozen=True)
class ReplayResult:
    """What re-running a minimal world showed: `runs` on fresh seeds (or the recorded failing ones), and the
    original world's failure rate as the reduction measured it (None if it did not)."""

    directory: Path
    world: World
    reference: FailureSignature
    predicates: tuple[PredicateSpec, ...]
    rule: SameFailureRule
    runs: tuple[ReplayRun, ...]
    fresh: bool = True
    original_rate: tuple[int, int] | None = None

    @property
    def tolerance(self) -> float:
        return self.rule.tolerance

    @property
    def reproduced(self) -> int:
        return sum(1 for run in self.runs if run.outcome is Outcome.FAIL)

    @property
    def errors(self) -> int:
        """Runs that ended in an error of the run (stopped by the wall-clock cap): counted in no rate."""
        return sum(1 for run in self.runs if run.outcome is Outcome.ERROR)

    @property
    def judged(self) -> int:
        """Runs that count in the failure rate: every run but the errors."""
        return len(self.runs) - self.errors

    @property
    def interval(self) -> tuple[float, float]:
        """The failure rate's 95 % confidence interval (Wilson score), from the replayed runs (errors left out)."""
        return wilson_interval(Rate(self.reproduced, self.judged), CONFIDENCE)

    @property
    def ok(self) -> bool:
        """The failure reproduced: in at least one fresh run, or in every recorded failing seed (a run that
        ended in an error, past the wall-clock cap, is not one that reproduced it)."""
        if not self.runs:
            return False
        return self.reproduced > 0 if self.fresh else self.reproduced == len(self.runs)

    def describe(self) -> str:
        """"reproduced: 7/10 fresh seeds failed the same way (70 %, 95% interval 40-89 %); the original world
        failed 5/5 fresh runs in the reduction"."""
        total = self.judged
        kind = "fresh seeds" if self.fresh else "recorded failing seeds"
        low, high = self.interval
        text = (f"{'reproduced' if self.ok else 'NOT reproduced'}: {self.reproduced}/{total} {kind} failed the same "
                f"way ({100 * self.reproduced / max(total, 1):.0f} %, {CONFIDENCE:.0%} interval "
                f"{100 * low:.0f}-{100 * high:.0f} %)")
        if self.errors:
            text += (f"; {self.errors} more run(s) went past the wall-clock cap (--run-timeout): errors, in no "
                     "rate")
        if self.original_rate is not None:
            text += (f"; the original world failed {self.original_rate[0]}/{self.original_rate[1]} fresh runs "
                     "in the reduction")
        if 2 * self.reproduced < total:
            reason = self.most_common_reason()
            text += f"; {reason}" if reason else ""
        return text

    def most_common_reason(self) -> str:
        """Why the runs that failed otherwise did (the reason seen most, `oracle.most_common_reason`)."""
        from pytest_ddenv.oracle.verdict import OtherReason, most_common_reason, why_other

        reasons = []
        for run in self.runs:
            if run.outcome is Outcome.PASS:
                reasons.append(OtherReason("the run passed", "the run passed (no failure)"))
            elif run.outcome is Outcome.OTHER and run.failure is not None:
                reason = why_other(run.failure, self.reference, self.rule)
                reasons += [reason] if reason is not None else []
            elif run.outcome is Outcome.OTHER:
                reasons.append(OtherReason(f"the run raised {run.raised}", "the run raised an exception"))
        return most_common_reason(reasons, len(self.runs))

    def to_dict(self) -> dict[str, Any]:
        low, high = self.interval
        return {
            "artifacts": str(self.directory),
            "models": list(self.world.names),
            "reference_failure": self.reference.to_dict(),
            "predicates": predicates_to_json(self.predicates),
            "tolerance": self.tolerance,
            "same_failure": self.rule.to_json(),
            "fresh": self.fresh,
            "runs": [
                {"seed": run.seed, "outcome": run.outcome.value,
                 "failure": None if run.failure is None else run.failure.to_dict(), "raised": run.raised or None,
                 "why": run.why or None}
                for run in self.runs
            ],
            "reproduced": self.reproduced,
            "errors": self.errors,
            "rate": self.reproduced / self.judged if self.judged else None,
            "interval": [low, high],
            "original_rate": None if self.original_rate is None else list(self.original_rate),
            "ok": self.ok,
        }


def read_artifacts(directory: Path) -> tuple[dict[str, Any], World]:
    """summary.json and minimal.yaml of an artifacts folder (ArtifactsError when missing or invalid)."""
    summary_path, minimal_path = directory / "summary.json", directory / "minimal.yaml"
    if not directory.is_dir():
        raise ArtifactsError(f"{directory}: no such artifacts folder")
    try:
        summary = json_value(read_regular(summary_path, SUMMARY_LIMIT).decode("utf-8", errors="replace"))
    except FileNotFoundError:
        raise ArtifactsError(f"{summary_path}: missing; is {directory} a ddenv artifacts folder?") from None
    except OSError as error:
        raise ArtifactsError(f"{summary_path}: cannot be read: {error.strerror or error}") from None
    except ValueError as error:
        raise ArtifactsError(f"{summary_path}: not valid JSON ({error})") from None
    if not isinstance(summary, dict):
        raise ArtifactsError(f"{summary_path}: expected a JSON object")
    if not minimal_path.is_file():
        raise ArtifactsError(f"{minimal_path}: missing; the reduction did not write its minimal world")
    return summary, World.load(minimal_path)


def summary_field(summary: Mapping[str, Any], name: str, where: Path, what: str, valid: Callable[[Any], bool],
                  default: Any) -> Any:
    """`summary[name]` when it is `what` (`valid`), `default` when absent; ArtifactsError naming the file and the
    field when it is something else (a summary damaged or edited since the reduction wrote it)."""
    if name not in summary:
        return default
    value = summary[name]
    if not valid(value):
        raise ArtifactsError(expected(what, value, f"{where}, field '{name}'"))
    return value


def _seed(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and 0 <= value < 2**63


def _positive_or_none(value: Any) -> bool:
    return value is None or (isinstance(value, (int, float)) and not isinstance(value, bool)
                             and 0 < value < float("inf"))


def _rate_or_none(value: Any) -> bool:
    return value is None or (isinstance(value, Mapping) and all(_seed(value.get(key)) for key in ("fails", "runs")))


def recorded_signature(summary: Mapping[str, Any], where: Path) -> FailureSignature:
    from pytest_ddenv.oracle.predicates import FailureSignature

    reference = summary_field(summary, "reference_failure", where, "an object {exception_type, location, signature}",
                              lambda value: isinstance(value, Mapping), {})
    signature = reference.get("signature")
    if not isinstance(signature, Mapping):
        raise ArtifactsError(f"{where}: the reference failure has no predicate signature (the test failed "
                            "with an exception, not a failure predicate); replay it with the 'replay' command "
                            "in summary.json instead")
    try:
        return FailureSignature.from_dict(signature)
    except (KeyError, TypeError, ValueError) as error:
        raise ArtifactsError(f"{where}: invalid reference failure signature ({error})") from None


def recorded_predicates(summary: Mapping[str, Any], reference: FailureSignature) -> tuple[PredicateSpec, ...]:
    """The predicates recorded in the summary, else the reference's predicate with default parameters."""
    if "predicates" in summary:
        return predicates_from_json(summary["predicates"])
    return (PredicateSpec(reference.predicate, {}),)


def recorded_seeds(log: Path, minimal: Sequence[str], fallback: int) -> list[int]:
    """Seeds of the logged runs of the minimal world that failed the same way, else [fallback]."""
    wanted = sorted(minimal)
    seeds: list[int] = []
    for probe in read_events(log):
        if (isinstance(probe, events.Probe) and probe.result is Outcome.FAIL and probe.stage is None
                and sorted(probe.candidate) == wanted and probe.seed is not None and probe.seed not in seeds):
            seeds.append(probe.seed)
    return seeds or [fallback]


def recorded_rule(summary: Mapping[str, Any], where: Path) -> SameFailureRule:
    """The same-failure rule the reduction recorded (`same_failure`), else the default rule with its tolerance
    (a summary written before rules were recorded). A user's function is imported now (`ArtifactsError`)."""
    from pytest_ddenv.oracle.verdict import SameFailureError, SameFailureRule

    try:
        if "same_failure" in summary:
            return SameFailureRule.from_json(summary["same_failure"], f"{where}: same_failure")
        return SameFailureRule(tolerance=float(summary.get("tolerance", defaults.TOLERANCE)))
    except (SameFailureError, TypeError, ValueError) as error:
        raise ArtifactsError(str(error)) from None


def replay(directory: str | Path, *, predicates: Sequence[PredicateSpec] | None = None, max_runs: int = 10,
           tolerance: float | None = None, timeout: float | None = None,
           controller: ControllerLike | None = None, recorded: bool = False,
           same_failure: str | None = None, engine: str | None = None,
           run_timeout: float | None = DEFAULT_MAX_WALL_TIME) -> ReplayResult:
    """Re-run the minimal world of an artifacts folder `max_runs` times on fresh seeds, which no probe of the
    reduction used, and measure how often it fails the same way, by the recorded same-failure rule (or
    `same_failure`, a match for every predicate, and `tolerance`); with `recorded`, re-run instead the seeds
    on which the reduction saw it fail (exact reproduction: each should fail again). `engine`: simulate in
    this physics engine instead of the one `minimal.yaml` names. `run_timeout`: wall-clock seconds each run
    may take (None: no cap); a run past it is an error (`Outcome.ERROR`), in no rate."""
    from dataclasses import replace

    from pytest_ddenv.oracle.verdict import classify, same_failure_match, why_other
    from pytest_ddenv.scenario.robot_world import ATTEMPT_SEED_STRIDE

    folder = Path(directory)
    summary, world = read_artifacts(folder)
    world = world if engine is None else world.with_engine(engine)
    reference = recorded_signature(summary, folder / "summary.json")
    chosen = tuple(predicates) if predicates else recorded_predicates(summary, reference)
    rule = recorded_rule(summary, folder / "summary.json")
    if same_failure is not None:
        rule = replace(rule, match=same_failure_match(same_failure, "same_failure"), predicates=())
    if tolerance is not None:
        rule = replace(rule, tolerance=tolerance)
    where = folder / "summary.json"
    sim_timeout = timeout if timeout is not None else summary_field(summary, "timeout", where, "a number > 0 or null",
                                                                     _positive_or_none, None)
    seed = summary_field(summary, "scenario_seed", where, "an integer >= 0", _seed,
                         summary_field(summary, "seed", where, "an integer >= 0", _seed, 0))
    if recorded:
        seeds = recorded_seeds(folder / "runs.jsonl", world.names, seed)[:max_runs]
    else:
        seeds = [seed + (FRESH_FIRST_ATTEMPT + index) * ATTEMPT_SEED_STRIDE for index in range(max_runs)]
    results = []
    for run_seed in seeds:
        try:
            run = run_scenario(world, chosen, seed=run_seed, timeout=sim_timeout, controller=controller,
                               max_wall_time=run_timeout)
        except ControllerTimeout as error:  # the wall-clock cap: an error of the run, never a verdict
            results.append(ReplayRun(run_seed, Outcome.ERROR, None, f"{type(error).__name__}: {error}"))
            continue
        except Exception as error:
            if raised_by_ddenv(error):
                raise
            results.append(ReplayRun(run_seed, Outcome.OTHER, None, f"{type(error).__name__}: {error}"))
            continue
        outcome = classify(run, reference, rule)
        reason = why_other(run.failure, reference, rule) if outcome is Outcome.OTHER and run.failure else None
        results.append(ReplayRun(run_seed, outcome, run.failure, run=run, why="" if reason is None else reason.text))
    original = summary_field(summary, "original_failure_rate", where, "{fails, runs} (integers >= 0) or null",
                             _rate_or_none, None)
    original_rate = None if original is None else (original["fails"], original["runs"])
    return ReplayResult(folder, world, reference, chosen, rule, tuple(results), fresh=not recorded,
                        original_rate=original_rate)
