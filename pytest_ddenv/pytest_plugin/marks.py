"""The markers of collected tests, checked when collection ends (`ddenv(...)`, `robot_failure(...)`), and a
predicate given alone to `robot_failure(...)`, which pytest takes for the thing to mark: found while collecting,
told as one usage error naming the test."""

from __future__ import annotations

import inspect
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Any

import pytest

from pytest_ddenv.driver.markers import ReductionSpec
from pytest_ddenv.errors import DdenvError

if TYPE_CHECKING:
    from pytest_ddenv.oracle.predicates import PredicateSpec

_spec_key = pytest.StashKey[tuple[ReductionSpec, "tuple[PredicateSpec, ...]"]]()
_misplaced_key = pytest.StashKey[dict[tuple[str, str], str]]()
"""Usage errors for predicates given alone to robot_failure(...), by (module node id, predicate name)."""


def spec_of(item: pytest.Item) -> tuple[ReductionSpec, tuple[PredicateSpec, ...]]:
    """The test's `ddenv(...)` settings and `robot_failure(...)` predicates, as checked at collection."""
    return item.stash.get(_spec_key, (ReductionSpec(), ()))


def misplaced_item(collector: pytest.Module | pytest.Class, name: str, obj: object) -> list[Any] | None:
    """A predicate class or function given alone to `robot_failure(...)` was marked instead of the test (and
    the test lost): remember the usage error, raised once collection is over."""
    from pytest_ddenv.driver.markers import marked_predicate

    holder = marked_predicate(obj)
    if holder is None or (inspect.isfunction(obj) and collector.funcnamefilter(name) and obj.__name__ == name):
        return None  # nothing marked by mistake, or a test marked with a bare robot_failure (checked later)
    test = name if collector.funcnamefilter(name) and name != getattr(holder, "__name__", name) else None
    _record_misplaced(collector, holder, test)
    return []


def misplaced_report(collector: pytest.Collector, report: pytest.CollectReport) -> pytest.CollectReport:
    """A test module that failed to import because a predicate given alone to `robot_failure(...)` was called
    with the test as its state: the usage error instead of the predicate's traceback."""
    excinfo = getattr(getattr(report, "call", None), "excinfo", None)
    if report.failed and isinstance(collector, pytest.Module) and excinfo is not None:
        found = _predicate_called_as_decorator(excinfo.value.__traceback__)
        if found is not None:
            holder, line = found
            report.longrepr = _record_misplaced(collector, holder, None, line)
    return report


def _predicate_called_as_decorator(trace: TracebackType | None) -> tuple[object, int] | None:
    """The predicate marked by mistake that the failed import of a test module ran into, and the module's line."""
    from pytest_ddenv.driver.markers import marked_predicate

    while trace is not None:
        frame = trace.tb_frame
        if frame.f_code.co_name == "<module>":
            called = trace.tb_next.tb_frame if trace.tb_next is not None else None
            places = [frame.f_globals] + ([called.f_globals] if called is not None else [])
            for holder in (value for place in places for value in list(place.values())):
                if holder is not None and marked_predicate(holder) is holder:
                    return holder, trace.tb_lineno
        trace = trace.tb_next
    return None


def _record_misplaced(collector: pytest.Collector, holder: object, test: str | None, line: int | None = None) -> str:
    """The usage error for `holder` given alone to robot_failure(...) in `collector`'s module, naming the test
    (`test`, else the function defined after `line`, else the one the module's source marks with it)."""
    from pytest_ddenv.driver.markers import defined_after, find_marked_test, misplaced_predicate_message

    name = str(getattr(holder, "__name__", holder))
    lines = _source_lines(collector.path)
    if test is None and line is not None:
        test = defined_after(lines, line)
    if test is None:
        found = find_marked_test(lines, name)
        test = found[0] if found else None
    module = collector.nodeid.split("::")[0]
    text = f"{module}::{test if test else '(a test)'}: {misplaced_predicate_message(holder)}"
    known = collector.config.stash.setdefault(_misplaced_key, {})
    if (module, name) not in known or test:
        known[(module, name)] = text
    return known[(module, name)]


def _source_lines(path: Path) -> list[str]:
    try:
        return path.read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError:
        return []


def check_markers(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Validate the markers of every collected robot test now, not in the middle of a run."""
    from pytest_ddenv.driver.markers import parse_ddenv_marker, parse_failure_markers

    misplaced = config.stash.get(_misplaced_key, {})
    if misplaced:
        raise pytest.UsageError(*misplaced.values())
    for item in items:
        ddenv_marker = item.get_closest_marker("ddenv")
        failure_markers = list(item.iter_markers("robot_failure"))
        if ddenv_marker is None and not failure_markers:
            continue
        try:
            spec = parse_ddenv_marker(ddenv_marker.args, ddenv_marker.kwargs) if ddenv_marker else ReductionSpec()
            predicates = parse_failure_markers([(m.args, m.kwargs) for m in reversed(failure_markers)])
        except DdenvError as error:
            raise pytest.UsageError(f"{item.nodeid}: {error}") from None
        item.stash[_spec_key] = (spec, predicates)
