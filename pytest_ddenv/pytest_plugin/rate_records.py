"""What a failure-rate verdict leaves in the reports: the "ddenv failure rate" section, the verdict as a plain
dict on the call's report (it travels through pytest-xdist), pytest-html extras, JUnit XML elements (a
`flakyFailure` per failed run of a passing verdict, the runs in `system-out`) and the terminal summary.

The JUnit properties themselves are the test's `user_properties` (`rate.py`), which pytest writes.
"""

from __future__ import annotations

import html as html_text
import xml.etree.ElementTree as ET
from typing import TYPE_CHECKING, Any

import pytest

if TYPE_CHECKING:
    from pytest_ddenv.pytest_plugin.rate_runs import RateVerdict

RATE_KEY = "ddenv_rate"
"""The call report's attribute that holds the verdict (`RateVerdict.to_json()`)."""
SECTION = "ddenv failure rate"
SUMMARY_SECTION = "ddenv failure rates"
_STDOUT_LOGGING = ("system-out", "out-err", "all")
"""The `junit_logging` values with which pytest writes a testcase's captured stdout as its `system-out`."""


def pytest_writes_stdout(config: pytest.Config, passed: bool) -> bool:
    """Whether pytest's JUnit XML writes the test's captured stdout as its `system-out` (`junit_logging`,
    `junit_log_passing_tests`)."""
    return str(config.getini("junit_logging")) in _STDOUT_LOGGING and (
        not passed or bool(config.getini("junit_log_passing_tests")))


def run_lines(record: dict[str, Any]) -> list[str]:
    """One line per run: "run 3 (seed 3000009): failed: AssertionError: ... at test_x.py:12"."""
    lines = []
    for run in record["runs"]:
        what = run["outcome"]
        if run["type"] is not None:
            what += f": {run['type']}: {run['message']} at {run['location']}"
        lines.append(f"run {run['run']} (seed {run['seed']}): {what}")
    return lines


def with_rate(item: pytest.Item, report: Any, verdict: RateVerdict) -> None:
    """The call's report with the verdict: its section, the plain record, and the pytest-html extras."""
    record = verdict.to_json()
    setattr(report, RATE_KEY, record)
    listing = "\n".join([record["headline"], *run_lines(record)]) + "\n"
    report.sections.append((SECTION, listing))
    if pytest_writes_stdout(item.config, not verdict.failed):  # the runs in its system-out, through the
        item.add_report_section("call", "stdout", f"ddenv failure rate: {listing}")  # teardown's report
    html = item.config.pluginmanager.getplugin("html")
    if html is not None and hasattr(html, "extras"):
        report.extras = [*getattr(report, "extras", []), html.extras.html(html_table(record))]


def html_table(record: dict[str, Any]) -> str:
    """The runs as a small HTML table (escaped) under the verdict's headline."""
    rows = "".join(
        "<tr>" + "".join(f"<td>{html_text.escape(str(cell))}</td>" for cell in (
            run["run"], run["seed"], run["outcome"], run["type"] or "", run["message"] or "",
            run["location"] or "")) + "</tr>"
        for run in record["runs"]
    )
    head = "".join(f"<th>{name}</th>" for name in ("run", "seed", "outcome", "type", "message", "location"))
    return (f'<div class="ddenv-rate"><p>ddenv failure rate: {html_text.escape(record["headline"])}</p>'
            f"<table><tr>{head}</tr>{rows}</table></div>")


def junit_records(config: pytest.Config, report: pytest.TestReport) -> None:
    """The verdict's elements in the testcase of the JUnit XML (`--junitxml`): a `flakyFailure` per failed run
    of a passing verdict (as Maven Surefire and pytest-rerunfailures write them), and the runs in
    `system-out` when pytest writes none itself. Called for every report, in the process that writes the XML
    (the pytest-xdist controller too)."""
    record = getattr(report, RATE_KEY, None)
    if report.when != "call" or not isinstance(record, dict):
        return
    from _pytest.junitxml import bin_xml_escape, xml_key

    xml = config.stash.get(xml_key, None)
    if xml is None:
        return
    reporter = xml.node_reporter(report)
    if record["verdict"] == "passed":
        for run in record["runs"]:
            if run["outcome"] != "failed":
                continue
            element = ET.Element("flakyFailure", message=bin_xml_escape(run["message"] or ""),
                                 type=bin_xml_escape(run["type"] or ""))
            trace = ET.SubElement(element, "stackTrace")
            trace.text = bin_xml_escape(record["tracebacks"].get(str(run["run"]), ""))
            out = ET.SubElement(element, "system-out")
            out.text = bin_xml_escape(f"ddenv run {run['run']}, seed {run['seed']}")
            reporter.append(element)
    if not pytest_writes_stdout(config, record["verdict"] == "passed"):
        out = ET.Element("system-out")
        out.text = bin_xml_escape("\n".join([f"ddenv failure rate: {record['headline']}", *run_lines(record)]))
        reporter.append(out)


class RateRecords:
    """The hooks of the records, in the process that writes the reports (registered in `pytest_configure`)."""

    def __init__(self, config: pytest.Config) -> None:
        self.config = config

    def pytest_runtest_logreport(self, report: pytest.TestReport) -> None:
        junit_records(self.config, report)

    def pytest_terminal_summary(self, terminalreporter: Any) -> None:
        terminal_summary(terminalreporter)


def terminal_summary(terminalreporter: Any) -> None:
    """The "ddenv failure rates" section: one line per test judged by its rate."""
    lines = []
    for reports in terminalreporter.stats.values():
        for report in reports:
            record = getattr(report, RATE_KEY, None)
            if isinstance(record, dict) and getattr(report, "when", None) == "call":
                lines.append(f"{report.nodeid}: {record['verdict']}: {record['headline']}")
    if lines:
        terminalreporter.section(SUMMARY_SECTION)
        for line in lines:
            terminalreporter.write_line(line)
