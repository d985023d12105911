"""Explain each culprit: for every model (and shape) of the final world, what happens without it: it
passes, fails another way (which), or still fails the same way but less often.

Read from the probes already made where possible: the 1-minimality check of the models stage (and of the
shapes stage) ran exactly "the minimal world without this element". Only what the log does not hold (an
element kept by a precondition, the precondition bypassed; a check cut short by the budget) is simulated, on
the final world, if `simulate` allows it (the reduction itself no longer pays for the precondition-kept
elements' check: `ReductionSettings.precondition_check` is off by default).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Mapping
from typing import Any

from pytest_ddenv.outcome import Outcome
from pytest_ddenv.reduce import ProbeLog, Reduction, events
from pytest_ddenv.stages.context import StageContext, scenario_models
from pytest_ddenv.stages.result import StageResult

STAGE = "explain"


def _summary(probes: Iterable[events.Probe]) -> dict[str, Any] | None:
    """Counts of the outcomes of the probes given, and the other failures seen (None: no runs)."""
    outcomes: Counter[str] = Counter()
    others: Counter[str] = Counter()
    for probe in probes:
        if probe.result is Outcome.ERROR:
            continue
        outcomes[probe.outcome] += 1
        if probe.result is Outcome.OTHER and probe.signature is not None:
            others[_failure_text(probe.signature)] += 1
    if not outcomes:
        return None
    return {"pass": outcomes["pass"], "same": outcomes["fail"], "other": outcomes["other"],
            "other_failures": [{"failure": text, "runs": count} for text, count in others.most_common()]}


def _failure_text(signature: Mapping[str, Any]) -> str:
    if "predicate" in signature:
        pose = signature.get("pose") or [0.0, 0.0]
        return f"{signature['predicate']} at ({float(pose[0]):.1f}, {float(pose[1]):.1f})"
    return f"{signature.get('exception', 'an exception')} at {signature.get('location', '?')}"


def describe(counts: Mapping[str, Any]) -> str:
    """'passes (3 of 3 runs)', 'fails another way: flipped at (4.0, 1.0) (2 of 3 runs)', ..."""
    runs = counts["pass"] + counts["same"] + counts["other"]
    if counts.get("rate_below"):
        fails, fresh = counts["rate_below"]
        return (f"still the same failure but significantly less often: {fails} of {fresh} fresh runs (the "
                "failure-rate comparison put it back)")
    if counts["same"] and (counts["pass"] or counts["other"]):
        return f"still the same failure, less often ({counts['same']} of {runs} runs)"
    if counts["same"]:
        return f"still the same failure ({counts['same']} of {runs} runs)"
    if counts["other"] and counts["other_failures"]:
        failures = ", ".join(f"{o['failure']}" for o in counts["other_failures"][:3])
        return f"fails another way: {failures} ({counts['other']} of {runs} runs)" + (
            f", passes in {counts['pass']}" if counts["pass"] else "")
    return f"passes ({counts['pass']} of {runs} runs)"


def logged_without(log: ProbeLog, world_names: Iterable[str], element: str) -> dict[str, Any] | None:
    """What the log's own stage saw for the world `world_names` without `element` (None: never run)."""
    key = frozenset(world_names) - {element}
    counts = _summary(probe for probe in log.probes("reduce") if frozenset(probe.candidate) == key)
    for event in log.own_events():
        if isinstance(event, events.RateBelow) and frozenset(event.candidate) == key:
            counts = counts or {"pass": 0, "same": 0, "other": 0, "other_failures": []}
            counts["rate_below"] = [event.fails, event.runs]
    return counts


def run(context: StageContext, models: Reduction, shapes: StageResult | None, *, simulate: bool) -> StageResult:
    """`context.base` is the final world; `models` the model-level reduction (its log is `context.log`)."""
    final = context.base
    begin = context.budget.started()
    named = scenario_models(final)
    explained: list[dict[str, Any]] = []
    elements: list[tuple[str, str, Any]] = [("model", name, None) for name in models.minimal if name in final]
    if shapes is not None and shapes.reduction is not None:
        elements += [("shape", name, shapes) for name in shapes.reduction.minimal]
    for kind, element, stage in elements:
        if kind == "model":
            counts = logged_without(context.log, models.minimal, element)
            source = "log: the model-level minimal world without it"
        else:
            counts = logged_without(context.log.view("shapes"), stage.reduction.minimal, element)
            source = "log: the shapes stage's world without it"
        if counts is None and simulate and kind == "model" and not final.model(element).keep \
                and element not in named:
            decided = context.decide(STAGE, f"without {element}", final.without([element]), stage_begin=begin)
            if decided.runs:
                counts = _summary(probe for probe in context.log.view(STAGE).probes()
                                  if probe.candidate == (f"without {element}",))
                source = "simulated: the final world without it" + (
                    " (the precondition that kept it bypassed)" if element in dict(models.precondition_kept) else "")
        entry: dict[str, Any] = {"element": element, "kind": kind, "source": source if counts else "not run"}
        if counts is not None:
            entry.update(counts)
            entry["without"] = describe(counts)
        elif kind == "model" and element in named:
            entry["without"] = "not run: the scenario names it (an arm's table or target), it is no culprit"
        elif kind == "model":
            entry["without"] = _why_not_run(models, element)
        else:
            owner = element.rsplit("#", 1)[0]
            alone = sum(1 for name in stage.reduction.minimal if name.rsplit("#", 1)[0] == owner) == 1
            entry["without"] = (f"not run: it is the only shape kept of {owner} (see without {owner})" if alone
                                else "not run (the budget ran out)")
        explained.append(entry)
    findings = [f"without {entry['element']}: {entry['without']}" for entry in explained]
    return StageResult(STAGE, final, simulations=context.budget.started() - begin, findings=findings,
                       details={"elements": explained})


def _why_not_run(models: Reduction, element: str) -> str:
    for name, reason in models.precondition_kept:
        if name == element:
            bypassed = models.without_precondition_kept
            tail = "; not simulated without it (the explain stage does, when the stages are asked for)" \
                if bypassed is None else (
                f"; with the precondition bypassed for every such model the failure reproduced in {bypassed[0]}/"
                f"{bypassed[1]} runs" if bypassed[1] else "; with the precondition bypassed for every such model the "
                "check could not run (none of its runs finished)")
            return f"not run: kept by a precondition ({reason}){tail}"
    return "not run (kept, or the budget ran out before it was checked)"
