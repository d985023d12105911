"""The text of a reduction's result, the same in the pytest report and in `ddenv reduce`'s output."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from pytest_ddenv.driver.report import Cost, ReductionReport
from pytest_ddenv.reduce.rates import VERDICT_CONFIDENCE, Rate, wilson_interval
from pytest_ddenv.reduce.types import Reduction

LINE_LIMIT = 2000
"""Characters of one line of an error message shown (a list of 5000 searched folders is not read by anyone)."""


def clip_lines(text: str, limit: int = LINE_LIMIT) -> str:
    """`text` with every line longer than `limit` characters cut in its middle, saying how much was left out."""
    lines = []
    for line in text.split("\n"):
        if len(line) > limit:
            head, tail = line[:limit * 2 // 3], line[-(limit // 3):]
            line = f"{head} ... ({len(line) - len(head) - len(tail)} characters left out) ... {tail}"
        lines.append(line)
    return "\n".join(lines)


def status_of(reduction: Reduction) -> str:
    return "1-minimal" if reduction.one_minimal else f"incomplete ({reduction.incomplete_reason})"


def listing(names: Sequence[str], limit: int = 12) -> str:
    if not names:
        return "(none)"
    shown = ", ".join(names[:limit])
    return shown if len(names) <= limit else f"{shown}, ... and {len(names) - limit} more (see summary.json)"


def result_lines(report: ReductionReport) -> list[str]:
    """From the minimal world to the notes: what was kept and why, what it cost, how often it fails."""
    reduction = report.reduction
    removed = report.removed_models
    earlier = f" ({reduction.resumed_probes} in earlier runs)" if reduction.resumed_probes else ""
    return [
        *reproduction_lines(report),
        f"minimal world: {', '.join(reduction.minimal) or '(no models)'}",
        *needed_lines(reduction),
        *([] if reduction.first_cut is None else [reduction.first_cut.describe()]),
        f"removed ({len(removed)}): {listing(removed)}",
        probes_line(reduction, earlier),
        simulations_line(report.cost),
        f"schemas: {reduction.partition} + {reduction.priority}, deflake={reduction.deflake}",
        *([f"physics engine: {report.engine}"] if report.engine else []),
        *same_failure_lines(report),
        failure_rate_line(reduction),
        *rule_lines(reduction),
        *stage_lines(report),
        *([] if report.cross_engine is None else report.cross_engine.lines()),
        *other_failure_lines(report),
        *(f"note: {text}" for text in report.notes),
        *(f"not simulated: {text}" for text in report.world_notes),
    ]


def simulations_line(cost: Cost) -> str:
    """Every simulation the reduction started, with this run's share when a resumed log holds earlier ones."""
    this_run = f", {cost.this_run_simulations} in this run" if cost.resumed_runs else ""
    return (f"simulations run: {cost.simulations}{this_run} (confirmation, fresh-run, speculative and picture runs "
            f"included; {cost.cpu_seconds:.1f} s of worker CPU)")


def probes_line(reduction: Reduction, earlier: str) -> str:
    """The probes: "decided" only when none errored (an error is no verdict: with errors they were "run")."""
    how = "decided" if not reduction.errors else "run"
    errors = f"{reduction.errors} errors" + (" (no verdict from them)" if reduction.errors else "")
    return (f"probes: {reduction.probes} {how}{earlier}, {reduction.cache_hits} from cache, {reduction.skipped} "
            f"skipped, {errors}; {reduction.wall_time:.1f} s")


def reproduction_lines(report: ReductionReport) -> list[str]:
    """Up front, when the original world's fresh runs rarely failed the same way: how often and why not."""
    if report.reproduction is None:
        return []
    return [f"warning: {report.reproduction.describe()}"]


def same_failure_lines(report: ReductionReport) -> list[str]:
    """The rule that said which failures are the reference failure, as it applies to the reference."""
    from pytest_ddenv.oracle.predicates import FailureSignature

    reference = report.reference_failure
    signature = reference.get("signature")
    if isinstance(signature, dict):
        return [f"same failure: {report.rule.describe(FailureSignature.from_dict(signature))}"]
    if "exception_type" in reference:
        location = reference.get("location", "?")
        return [f"same failure: {reference['exception_type']} raised at {location} (the same type at the same line)"]
    return []


OTHER_FAILURES_SHOWN = 5


def other_failure_lines(report: ReductionReport, limit: int = OTHER_FAILURES_SHOWN) -> list[str]:
    """One line per other failure the probes met (`pytest_ddenv.driver.other_failures`), the largest groups first."""
    lines = []
    for failure in report.other_failures[:limit]:
        seen = f"seen in {failure.probes} probe{'s' if failure.probes != 1 else ''}"
        if failure.smallest_world is None:
            where = "only in the stages' worlds"
        else:
            size = len(failure.smallest_world)
            where = f"smallest world {size} model{'s' if size != 1 else ''}"
            if failure.world_file is not None:
                where += f" ({Path(failure.world_file).name})"
        lines.append(f"other failure: {failure.describe()}, {seen}, {where}")
        if failure.why:
            lines.append(f"  not the failure: {failure.why}")
    more = len(report.other_failures) - limit
    if more > 0:
        lines.append(f"and {more} more other failure{'s' if more != 1 else ''} (see summary.json)")
    return lines


def interval_text(rate: Rate) -> str:
    """The minimal world's failure rate as its runs bound it ("its rate: 57-100 % at 95 % confidence" for 5/5):
    a comparison that holds on a few runs says no more than that."""
    low, high = wilson_interval(rate, VERDICT_CONFIDENCE)
    return f"its rate: {round(100 * low)}-{round(100 * high)} % at {round(100 * VERDICT_CONFIDENCE)} % confidence"


def failure_rate_line(reduction: Reduction) -> str:
    """How often the minimal world fails on fresh runs, compared with the original world (rates.py), with a
    warning when it is significantly lower, when the budget stopped the comparison, or when it rarely fails."""
    fails, runs = reduction.failure_rate
    check = reduction.rate_check
    if runs == 0:
        stopped = (reduction.incomplete_reason or "").startswith("budget") or (
            check is not None and check.decision == "continue")
        return f"minimal world's failure rate: not measured{' (the budget ran out)' if stopped else ''}"
    if check is not None and check.decision == "continue":
        return (f"minimal world fails {check.reduced} fresh runs vs the original's {check.original}: undecided, "
                "the budget stopped the rate comparison (warning: the rate is not checked)")
    if check is not None and check.skipped and check.decision == "holds":  # the original's runs were not needed
        made = (f"{check.original} fresh runs; {check.skipped} more" if check.original.runs
                else f"its {check.skipped} fresh runs")
        return (f"minimal world fails {check.reduced} fresh runs: not significantly less often than the original "
                f"({made} could not change that; {interval_text(check.reduced)})")
    if check is not None:  # in words; the test's statistics are in summary.json (rate_check) and under -v
        runs_text = f"{check.reduced} vs {check.original} fresh runs"
        if check.decision == "below":
            return (f"minimal world fails less often than the original: {runs_text} (warning: significantly less "
                    f"often, after {reduction.rate_backoffs} back-offs)")
        bound = interval_text(check.reduced)
        if check.reduced.value < check.original.value:
            return f"minimal world fails about as often as the original: {runs_text} (fewer, within chance; {bound})"
        if check.reduced.value > check.original.value:
            return f"minimal world fails at least as often as the original: {runs_text} ({bound})"
        return f"minimal world fails as often as the original: {runs_text} ({bound})"
    line = f"minimal world fails {fails}/{runs} fresh runs"
    original = reduction.original_failure_rate
    if original is not None:
        line += f" (original world: {original[0]}/{original[1]})"
    if fails * 2 < runs:
        line += " (warning: it rarely reproduces the failure)"
    return line


RULE_MISSES = 0.1
"""`rule_lines`: a fixed deflake rule that rejects a candidate failing as often as the original world at least
this often gets a note."""


def rule_lines(reduction: Reduction, misses: float = RULE_MISSES) -> list[str]:
    """A fixed deflake rule (`deflake=N`: a candidate reproduces f when any of N + 1 runs fails) on a failure the
    original world reproduced in only some of its fresh runs: how often the rule rejects a candidate that fails
    exactly as often as the original, when that is `misses` or more (such rejections keep models the failure
    does not need). `auto` sizes the rule from the original's rate: no note."""
    original = reduction.original_failure_rate
    if isinstance(reduction.deflake, bool) or not isinstance(reduction.deflake, int) or original is None:
        return []
    fails, runs = original
    if runs < 3 or fails in (0, runs):  # never failing: the warning up front (`reproduction_lines`) says so
        return []
    tries = reduction.deflake + 1
    missed = (1.0 - fails / runs) ** tries
    if missed < misses:
        return []
    plural = "s" if tries != 1 else ""
    return [(f"note: the original world failed {fails} of {runs} fresh runs, and deflake={reduction.deflake} "
             f"judges a candidate on {tries} run{plural} (any failing): a candidate that fails as often as the "
             f"original is rejected about {round(100 * missed)} % of the time, so the minimal world may keep "
             "models the failure does not need; deflake=auto (the default) sizes the rule from the original's "
             "rate")]


def needed_lines(reduction: Reduction) -> list[str]:
    """"needed for the failure" apart from "kept by a precondition" (and the check without the latter), or from
    the models kept out of the candidates (`keep`, an arm's table and target)."""
    if not reduction.precondition_kept:
        named = ", ".join(name for name in reduction.kept if name in reduction.minimal)
        needed = ", ".join(reduction.needed) or "(no models)"
        return [f"needed for the failure: {needed}; kept, not candidates: {named}"] if named else []
    kept = ", ".join(f"{name} ({reason})" for name, reason in reduction.precondition_kept)
    lines = [f"needed for the failure: {', '.join(reduction.needed) or '(no models)'}",
             f"kept by a precondition, not shown needed: {kept}"]
    if reduction.without_precondition_kept is None:
        lines.append("without them: not checked (the explain stage simulates each one's removal when the stages "
                     "are asked for)")
    else:
        fails, runs = reduction.without_precondition_kept
        lines.append(f"without them (precondition bypassed) the failure reproduced in {fails}/{runs} runs" if runs
                     else "without them (precondition bypassed) the check could not run (none of its runs finished)")
    return lines


def stage_lines(report: ReductionReport) -> list[str]:
    """What the stages after the models found (`--ddenv-stages`), one line per finding."""
    staged = report.stages
    if staged is None:
        return []
    lines: list[str] = []
    for result in staged.results:
        cost = f"{result.simulations} simulations" + (f", incomplete ({result.incomplete})" if result.incomplete
                                                      else "")
        lines.append(f"stage {result.stage} ({cost}):")
        lines += [f"  {finding}" for finding in result.findings]
    if staged.final_rate is not None:
        fails, runs = staged.final_rate
        line = f"simplified world fails {fails}/{runs} fresh runs"
        if staged.minimal_rate:
            line += f" (minimal world: {staged.minimal_rate[0]}/{staged.minimal_rate[1]})"
        if staged.final_errors:
            line += f" (warning: {staged.final_errors} more runs errored)"
        if staged.rate_below:
            line += " (warning: significantly less often than the minimal world)"
        lines.append(line)
    if report.stage_files:
        lines.append("stage worlds: " + ", ".join(Path(path).name for path in report.stage_files.values()))
    return lines
