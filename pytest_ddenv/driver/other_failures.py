"""The other failures a reduction met: every probe that ended in another failure f' (outcome "other"), grouped.

A reduction classifies each probe against the failure f it reduces; a probe that fails another way (another
predicate, the same predicate elsewhere, an assert of the test) is OTHER, and the run log (`runs.jsonl`)
keeps its signature. `other_failures(logged, rule=..., reference=...)` reads those probes (the model-level
probes, the driver's confirmation and picture runs and the stages' probes, every purpose) and groups them:

- a predicate failure joins the first group whose first member it matches by the reduction's own rule
  (`oracle.SameFailureRule`, its built-in part: by default the same predicate, failure position within the
  tolerance of that member's, and touching one of the models it touched, if it touched any);
- an exception of the test (``{"exception", "location"}``: an assert, an error of the controller) joins the
  group of the same exception type at the same location.

Per group (`OtherFailure`): the signature of its first member, the number of probes that showed it, the
smallest model-level world that showed it (the stages' probes simplify shapes and attributes, so their
worlds are not sets of models) with the seed and attempt of that probe, and every seed and attempt it was
seen with, and why it is not the reference failure (`probe.why_not_reproduced`). A failure that the rule
matches with the reference failure is never listed. Largest group first, then by first probe. No pytest, no
simulation: the driver calls it on its log when it writes the summary, and `artifacts.write_other_worlds`
writes the smallest worlds of the largest groups as `other-<k>.yaml` (``--ddenv-keep-other N``), with the
command that replays each.

`original_reproduction` reads the same log for the original world's fresh runs: when they rarely fail the
same way, the report says so up front with the reason seen most (`Reproduction`).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from pytest_ddenv import defaults
from pytest_ddenv.oracle.predicates import FailureSignature
from pytest_ddenv.oracle.verdict import (
    FailureReference,
    OtherReason,
    SameFailureError,
    SameFailureRule,
    most_common_reason,
)
from pytest_ddenv.outcome import Outcome
from pytest_ddenv.reduce import events
from pytest_ddenv.scenario.probe import why_not_reproduced

MODEL_LEVEL = "models"
"""The name `OtherFailure.seen_in` gives the model-level reduction (and the driver's own runs)."""
TOUCHED_SHOWN = 2
"""Models touched that `OtherFailure.describe` names (then "and N more")."""


@dataclass(frozen=True)
class OtherFailure:
    """One other failure f' a reduction met: a group of probes with the same signature (module docstring).

    Exactly one of `signature` (a predicate fired) and `exception` (the test raised something else: its type
    and `location`) is set. `smallest_world` is None when only the stages' probes showed it."""

    signature: FailureSignature | None
    exception: str | None
    location: str | None
    probes: int
    """How many probes (runs) showed it."""
    first_probe: int
    """The position of its first probe among the log's probe records (from 0)."""
    smallest_world: tuple[str, ...] | None
    smallest_seed: int | None
    """The run seed of the probe of the smallest world (``ddenv run --seed`` replays it)."""
    smallest_attempt: int | None
    seeds: tuple[int, ...] = ()
    attempts: tuple[int, ...] = ()
    seen_in: tuple[str, ...] = ()
    """Where it was seen: "models" (the model-level reduction and the driver's runs) and the stages."""
    world_file: str | None = None
    """`other-<k>.yaml` when its smallest world was written (``--ddenv-keep-other``)."""
    replay: str | None = None
    """The command that replays its smallest world, when written."""
    why: str = ""
    """Why it is not the reference failure under the reduction's rule ("" when not known)."""

    @property
    def predicate(self) -> str | None:
        return None if self.signature is None else self.signature.predicate

    def describe(self) -> str:
        """"flipped near (3.2, 1.0) at t = 4.1 s (touching crate)", or "AssertionError at test_yard.py:12".
        The models touched tell apart two failures at one spot (the oracle's third rule)."""
        if self.signature is None:
            return f"{self.exception} at {self.location}"
        x, y, _ = self.signature.position
        touched = self.signature.touched
        touching = ", ".join(touched[:TOUCHED_SHOWN]) if touched else "no model"
        if len(touched) > TOUCHED_SHOWN:
            touching += f" and {len(touched) - TOUCHED_SHOWN} more"
        return (f"{self.signature.predicate} near ({x:.1f}, {y:.1f}) at t = {self.signature.time:.1f} s "
                f"(touching {touching})")

    def to_json(self) -> dict[str, Any]:
        """Its entry in `summary.json`'s ``other_failures``."""
        signature = (self.signature.to_dict() if self.signature is not None
                     else {"exception": self.exception, "location": self.location})
        return {
            "signature": signature,
            "description": self.describe(),
            "probes": self.probes,
            "first_probe": self.first_probe,
            "smallest_world": None if self.smallest_world is None else {
                "size": len(self.smallest_world), "models": list(self.smallest_world),
                "seed": self.smallest_seed, "attempt": self.smallest_attempt},
            "seeds": list(self.seeds),
            "attempts": list(self.attempts),
            "seen_in": list(self.seen_in),
            "world_file": self.world_file,
            "replay": self.replay,
            "why": self.why,
        }


@dataclass
class _Group:
    """An `OtherFailure` being collected."""

    signature: FailureSignature | None
    exception: tuple[str, str] | None
    first_probe: int
    probes: int = 0
    smallest: tuple[tuple[str, ...], int | None, int | None] | None = None
    seeds: set[int] = field(default_factory=set)
    attempts: set[int] = field(default_factory=set)
    seen_in: dict[str, None] = field(default_factory=dict)
    why: str = ""

    def add(self, probe: events.Probe) -> None:
        self.probes += 1
        if probe.seed is not None:
            self.seeds.add(probe.seed)
        self.attempts.add(probe.attempt)
        self.seen_in[MODEL_LEVEL if probe.stage is None else probe.stage] = None
        if probe.stage is None:  # a model-level world: a set of models
            if self.smallest is None or len(probe.candidate) < len(self.smallest[0]):
                self.smallest = (probe.candidate, probe.seed, probe.attempt)

    def frozen(self) -> OtherFailure:
        world, seed, attempt = self.smallest if self.smallest is not None else (None, None, None)
        return OtherFailure(
            signature=self.signature, exception=None if self.exception is None else self.exception[0],
            location=None if self.exception is None else self.exception[1], probes=self.probes,
            first_probe=self.first_probe, smallest_world=world, smallest_seed=seed, smallest_attempt=attempt,
            seeds=tuple(sorted(self.seeds)), attempts=tuple(sorted(self.attempts)), seen_in=tuple(self.seen_in),
            why=self.why)


def other_failures(logged: Iterable[events.Event], tolerance: float = defaults.TOLERANCE, *,
                   rule: SameFailureRule | None = None,
                   reference: FailureReference | None = None) -> tuple[OtherFailure, ...]:
    """The other failures in a run log's events (`ProbeLog.events`, `read_events`), grouped by `rule`'s
    built-in part (default: the default rule with `tolerance`), each with why it is not the `reference` failure
    (when given; a record the rule matches with it is left out); largest group first, then by first probe.
    Records without a readable signature are left out (module docstring)."""
    rule = rule or SameFailureRule(tolerance=tolerance)
    grouping = rule.built_in()
    groups: list[_Group] = []
    by_exception: dict[tuple[str, str], _Group] = {}
    position = -1
    for probe in logged:
        if not isinstance(probe, events.Probe):
            continue
        position += 1
        data = probe.signature
        if probe.result is not Outcome.OTHER or data is None:
            continue
        why = _why(data, reference, rule)
        if why is None:  # the reference failure itself under the rule
            continue
        group: _Group | None
        if "predicate" in data:
            try:
                signature = FailureSignature.from_dict(data)
            except (KeyError, TypeError, ValueError, IndexError):
                continue
            if len(signature.pose) < 3:
                continue
            group = next((g for g in groups if g.signature is not None
                          and grouping.same(signature, g.signature)), None)
            if group is None:
                group = _Group(signature, None, position, why=why)
                groups.append(group)
        elif "exception" in data:
            key = (str(data["exception"]), str(data.get("location", "")))
            group = by_exception.get(key)
            if group is None:
                group = by_exception[key] = _Group(None, key, position, why=why)
                groups.append(group)
        else:
            continue
        group.add(probe)
    ordered = sorted(groups, key=lambda g: (-g.probes, g.first_probe))
    return tuple(group.frozen() for group in ordered)


def _why(found: Mapping[str, Any], reference: FailureReference | None, rule: SameFailureRule) -> str | None:
    """Why a logged failure is not the reference failure ("" when unknown); None when the rule matches it (or
    the record cannot be read: left out either way)."""
    if reference is None:
        return ""
    try:
        reason = why_not_reproduced(found, reference, rule)
    except SameFailureError:  # a user's function that breaks on this one: the reduction said so already
        return ""
    return None if reason is None else reason.text


# -- the original world's fresh runs -------------------------------------------------------------------
FRESH_PURPOSES = ("calibration", "failure-rate")
"""The runs of the original world on fresh seeds (not the one it failed with): the deflake calibration and the
failure-rate comparison (`reduce.rate_check`)."""
RARE_BELOW = 0.5
"""The original world "rarely" fails the same way when fewer than this fraction of its fresh runs do."""
RARE_MIN_RUNS = 3
"""Fewer fresh runs than this say nothing about how often the original world fails the same way."""


@dataclass(frozen=True)
class Reproduction:
    """How rarely the original world failed the same way on fresh runs, and the reason seen most."""

    fails: int
    runs: int
    reason: str
    """"the same predicate fired at the same place but touching no model in 5 of 5 runs (the reference touched
    wall); consider same_failure='place'" ("" when no reason is known)."""

    def describe(self) -> str:
        text = f"the original world failed the same way in only {self.fails} of {self.runs} fresh runs"
        return f"{text}: {self.reason}" if self.reason else text

    def to_json(self) -> dict[str, Any]:
        return {"fails": self.fails, "runs": self.runs, "reason": self.reason, "description": self.describe()}


def original_reproduction(logged: Iterable[events.Event], original: Sequence[str],
                          reference: FailureReference, rule: SameFailureRule) -> Reproduction | None:
    """When the original world's fresh runs in a run log (`FRESH_PURPOSES`, errors left out) failed the same way
    in fewer than `RARE_BELOW` of them (at least `RARE_MIN_RUNS` runs): how often, and why the others did
    not (`probe.why_not_reproduced`, the reason seen most). None otherwise."""
    wanted = frozenset(original)
    outcomes: dict[int, tuple[str, Any]] = {}
    for probe in logged:
        if (not isinstance(probe, events.Probe) or probe.purpose not in FRESH_PURPOSES or probe.stage is not None
                or frozenset(probe.candidate) != wanted):
            continue
        if probe.result is not Outcome.ERROR:
            outcomes.setdefault(probe.attempt, (probe.outcome, probe.signature))
    runs = len(outcomes)
    fails = sum(outcome == "fail" for outcome, _ in outcomes.values())
    if runs < RARE_MIN_RUNS or fails >= RARE_BELOW * runs:
        return None
    reasons: list[OtherReason] = []
    for outcome, found in outcomes.values():
        if outcome == "fail":
            continue
        try:
            reason = why_not_reproduced(found if isinstance(found, Mapping) else None, reference, rule)
        except SameFailureError:
            reason = None
        if reason is not None:
            reasons.append(reason)
    return Reproduction(fails, runs, most_common_reason(reasons, runs))

