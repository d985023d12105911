"""What a reduction adds to pytest's output, end to end (real reductions in pytest subprocesses): progress
lines that agree with the result line, no "(running)" once the models are done, a line at the start and at
the end under pytest-xdist, the failure-rate line in words, and `[[ATTACHMENT|...]]` lines in the JUnit XML
but not on the terminal (unless -v)."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET

import pytest

pytestmark = pytest.mark.slow  # real reductions in subprocesses

QUICK_HEARTBEAT = "import pytest_ddenv.driver.progress\npytest_ddenv.driver.progress.HEARTBEAT_SECONDS = 0.2\n"
"""A conftest that makes the CI log's heartbeat beat every 0.2 s of silence (30 s otherwise)."""


def seconds_of(line: str) -> int:
    return int(re.findall(r", (\d+) s\b", line)[-1])


def one_models(output: str) -> list[str]:
    """Lines that say "1 models" (not the range "6 -> 1 models")."""
    return [line for line in output.splitlines() if re.search(r"(?<!-> )\b1 models", line)]


def test_a_ci_log_shows_progress_that_agrees_with_the_result_and_no_attachment_lines(
        wall_project: pytest.Pytester) -> None:
    wall_project.makeconftest(QUICK_HEARTBEAT)
    result = wall_project.runpytest_subprocess("--ddenv-reduce", "-o", "junit_logging=system-out",
                                               "--junitxml=junit.xml", "-p", "no:cacheprovider")
    result.assert_outcomes(failed=1)
    output = result.stdout.str()
    lines = [line for line in output.splitlines() if line.startswith("ddenv: ")][1:]  # after the header's
    said = [line for line in lines if not line.endswith(("(running)", "(finishing)"))]  # without the heartbeats
    assert said[0].startswith("ddenv: confirming the failure: run 1 of up to 2, "), lines
    (done,) = [index for index, line in enumerate(lines) if line.endswith("(models done)")]
    assert lines[done].startswith("ddenv: reducing test_reaches_goal: 1 model, "), lines
    final = lines[-1]
    assert final.startswith("ddenv: test_scenario.py::test_reaches_goal: 6 -> 1 models (83%), "), lines
    assert all(line.endswith("(finishing)") for line in lines[done + 1:-1]), lines
    assert not any(line.endswith("(running)") for line in lines[done:]), lines
    assert seconds_of(final) >= max(map(seconds_of, lines[:-1])), "one clock for the progress and the result"
    assert one_models(output) == [] and "(1/2)" not in output
    # the rate line in words, the statistics in summary.json (and under -v)
    result.stdout.fnmatch_lines(["minimal world fails 5/5 fresh runs: not significantly less often than the "
                                 "original (its 5 fresh runs could not change that; its rate: 57-100 % at 95 % "
                                 "confidence)"])
    assert "Fisher" not in output
    # the attachments: in the JUnit XML only
    assert "[[ATTACHMENT|" not in output, output
    system_out = "".join(e.text or "" for e in ET.parse(wall_project.path / "junit.xml").iter("system-out"))
    assert system_out.count("[[ATTACHMENT|") >= 5 and "minimal.yaml]]" in system_out, system_out


def test_verbose_shows_the_attachments_and_the_rate_statistics(wall_project: pytest.Pytester) -> None:
    result = wall_project.runpytest_subprocess("--ddenv-reduce", "-v", "-p", "no:cacheprovider")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines([
        "*Captured stdout call*", "[[][[]ATTACHMENT|*minimal.yaml[]][]]",
        "minimal world fails 5/5 fresh runs: not significantly less often than the original (its 5 fresh runs "
        "could not change that; its rate: 57-100 % at 95 % confidence)",
        "rate check (one-sided Fisher exact test): p = 1, level 0.0167 per look, decision 'holds' on 5/5 vs 0/0 "
        "fresh runs",
    ])
    result.stdout.fnmatch_lines(["    probe *: 1 model -> fail"])
    assert one_models(result.stdout.str()) == []


def test_each_xdist_worker_says_when_its_reduction_starts_and_ends(wall_project: pytest.Pytester) -> None:
    wall_project.makepyfile(test_second=wall_project.path.joinpath("test_scenario.py").read_text().replace(
        "def test_reaches_goal", "def test_reaches_goal_again"))
    result = wall_project.runpytest_subprocess("-n", "2", "--ddenv-reduce", "-p", "no:cacheprovider")
    result.assert_outcomes(failed=2)
    lines = [line for line in result.stderr.lines if "ddenv: " in line]
    starts = sorted(re.sub(r"^\[gw[01]\] ", "", line) for line in lines if "ddenv: reducing" in line)
    assert starts == ["ddenv: reducing test_scenario.py::test_reaches_goal",
                      "ddenv: reducing test_second.py::test_reaches_goal_again"], lines
    ends = sorted(re.sub(r"^\[gw[01]\] ", "", line) for line in lines if "ddenv: reducing" not in line)
    assert [end.split(": 6 -> 1 models (83%), ")[0] for end in ends] == [
        "ddenv: test_scenario.py::test_reaches_goal", "ddenv: test_second.py::test_reaches_goal_again"], lines
    assert all(re.match(r"^\[gw[01]\] ddenv: ", line) for line in lines), lines
