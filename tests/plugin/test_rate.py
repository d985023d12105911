"""`--ddenv-rate N`: a robot test run N times on its run seeds and judged by its failure rate (real pytest
sessions in subprocesses, real simulations). The scenario: the robot drives 3 m across an open field and the
test asserts it ends left of the straight line; where it ends depends on the seed through the simulation's
noise, so some seeds fail and some pass."""

from __future__ import annotations

import html
import json
import textwrap
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from pytest_ddenv.reduce.rates import Rate, wilson_interval
from pytest_ddenv.scenario.robot_world import ATTEMPT_SEED_STRIDE

OPEN_WORLD = (Path(__file__).resolve().parents[1] / "data" / "open.yaml").read_text(encoding="utf-8")

DRIFT_TEST = textwrap.dedent(
    """\
    import pytest

    @pytest.mark.ddenv(world="open.yaml"{marker})
    def test_drift(robot_world):
        run = robot_world.run()
        assert run.positions[-1][1] > 0, "the robot ended right of the straight line"
    """
)


@pytest.fixture
def drift_project(pytester: pytest.Pytester) -> pytest.Pytester:
    pytester.makefile(".yaml", open=OPEN_WORLD)
    pytester.makepyfile(test_drift=DRIFT_TEST.format(marker=""))
    return pytester


def case_of(junit: Path) -> ET.Element:
    (case,) = ET.parse(junit).getroot().iter("testcase")
    return case


def properties(junit: Path) -> dict[str, str]:
    return {prop.get("name", ""): prop.get("value", "") for prop in case_of(junit).iter("property")}


def runs_of(props: dict[str, str]) -> list[dict]:
    return [json.loads(props[f"ddenv_run_{index}"]) for index in range(int(props["ddenv_rate_runs"])
                                                                         + int(props["ddenv_rate_errors"]))]


def alone(project: pytest.Pytester, seed: int) -> str:
    """The outcome of the test run once with `seed` (`--ddenv-seed`), as pytest says it."""
    outcomes = project.runpytest_subprocess("--ddenv-seed", str(seed), "-p", "no:cacheprovider").parseoutcomes()
    return "failed" if outcomes.get("failed") else "passed"


@pytest.mark.slow
def test_the_rate_is_that_of_its_seeds_run_alone(drift_project: pytest.Pytester) -> None:
    expected = [alone(drift_project, index * ATTEMPT_SEED_STRIDE) for index in range(5)]
    assert "failed" in expected, "the scenario fails on some of these seeds (else this test shows little)"
    result = drift_project.runpytest_subprocess("--ddenv-rate", "5", "--ddenv-workers", "2", "--junitxml=junit.xml")
    props = properties(drift_project.path / "junit.xml")
    runs = runs_of(props)
    assert [run["outcome"] for run in runs] == expected
    assert [run["seed"] for run in runs] == [index * ATTEMPT_SEED_STRIDE for index in range(5)]
    failures = expected.count("failed")
    low, high = wilson_interval(Rate(failures, 5), 0.95)
    assert props["ddenv_rate_runs"] == "5" and props["ddenv_rate_failures"] == str(failures)
    assert props["ddenv_rate_errors"] == "0" and props["ddenv_rate_interval"] == f"{low:.3f},{high:.3f}"
    assert props["ddenv_rate_verdict"] == "failed", "with the default max_failure_rate 0 any failure fails it"
    result.assert_outcomes(failed=1)
    headline = f"failed {failures} of 5 runs, {100 * failures / 5:.0f} % [{100 * low:.0f} %, {100 * high:.0f} %]"
    shown = headline.replace("[", "[[]")  # fnmatch: a literal "["
    result.stdout.fnmatch_lines(["*FailureRateExceeded: ddenv failure rate: " + shown,
                                 "*ddenv failure rates*", f"test_drift.py::test_drift: failed: {shown}"])
    for run in runs:
        if run["outcome"] == "failed":
            assert run["type"] == "AssertionError" and run["location"] == "test_drift.py:6"
            assert run["message"] == "the robot ended right of the straight line"
            assert run["predicate"] is None and run["signature"] is None
            result.stdout.fnmatch_lines([f"*run {run['run']} (seed {run['seed']}): failed: AssertionError: the robot*"])


@pytest.mark.slow
def test_the_verdict_is_the_same_in_two_sessions_and_under_xdist(drift_project: pytest.Pytester) -> None:
    drift_project.runpytest_subprocess("--ddenv-rate", "4", "--ddenv-seed", "7", "--junitxml=first.xml")
    drift_project.runpytest_subprocess("--ddenv-rate", "4", "--ddenv-seed", "7", "--junitxml=second.xml")
    xdist = drift_project.runpytest_subprocess("--ddenv-rate", "4", "--ddenv-seed", "7", "-n", "2",
                                               "--junitxml=xdist.xml", "-o", "junit_logging=system-out")
    first = properties(drift_project.path / "first.xml")
    assert [run["seed"] for run in runs_of(first)] == [7 + index * ATTEMPT_SEED_STRIDE for index in range(4)]
    assert properties(drift_project.path / "second.xml") == first
    assert properties(drift_project.path / "xdist.xml") == first, "the records survive the trip to the controller"
    xdist.stdout.fnmatch_lines(["*ddenv failure rates*", "test_drift.py::test_drift: *: failed * of 4 runs*"])
    (system_out,) = case_of(drift_project.path / "xdist.xml").findall("system-out")  # pytest's, with the runs
    assert f"run 3 (seed {7 + 3 * ATTEMPT_SEED_STRIDE}): " in (system_out.text or "")


@pytest.mark.slow
def test_a_passing_verdict_with_failed_runs_records_flaky_failures(drift_project: pytest.Pytester) -> None:
    drift_project.makepyfile(test_drift=DRIFT_TEST.format(marker=", rate=4, max_failure_rate=0.9"))
    result = drift_project.runpytest_subprocess("--ddenv-workers", "2", "--junitxml=junit.xml", "-rA",
                                                "--html=report.html", "--self-contained-html")
    props = properties(drift_project.path / "junit.xml")
    failed = [run for run in runs_of(props) if run["outcome"] == "failed"]
    assert failed, "some of the seeds fail"
    assert props["ddenv_rate_verdict"] == "passed"
    result.assert_outcomes(passed=1)  # even when run 0 itself failed: the rate is the verdict
    case = case_of(drift_project.path / "junit.xml")
    assert case.find("failure") is None
    flaky = case.findall("flakyFailure")
    assert [(element.get("type"), element.get("message")) for element in flaky] == \
        [("AssertionError", "the robot ended right of the straight line")] * len(failed)
    assert [element.findtext("system-out") for element in flaky] == \
        [f"ddenv run {run['run']}, seed {run['seed']}" for run in failed]
    assert all("test_drift.py" in (element.findtext("stackTrace") or "") for element in flaky)
    listing = case.findtext("system-out") or ""
    assert listing.startswith("ddenv failure rate: failed ") and "run 3 (seed 3000009)" in listing
    result.stdout.fnmatch_lines(["*ddenv failure rate*", "*not significantly above the allowed 90 %*",
                                 "run 0 (seed 0): *"])
    page = html.unescape((drift_project.path / "report.html").read_text())
    assert "ddenv-rate" in page and "<th>seed</th>" in page and "not significantly above the allowed 90 %" in page


@pytest.mark.slow
def test_a_failing_verdict_reduces_the_first_failing_run_and_names_its_seed(drift_project: pytest.Pytester) -> None:
    drift_project.runpytest_subprocess("--ddenv-rate", "4", "--junitxml=rate.xml")
    first = next(run for run in runs_of(properties(drift_project.path / "rate.xml")) if run["outcome"] == "failed")
    result = drift_project.runpytest_subprocess("--ddenv-rate", "4", "--ddenv-reduce", "--ddenv-media", "none",
                                                "--ddenv-workers", "2")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines([f"reduced run {first['run']} of the failure-rate runs (seed {first['seed']})"])
    (folder,) = (drift_project.path / "ddenv-artifacts").iterdir()
    assert folder.name.startswith(f"test_drift.py__test_drift-seed{first['seed']}-")
    log = [json.loads(line) for line in (folder / "runs.jsonl").read_text().splitlines()]
    seeds = {record["seed"] for record in log if record.get("event") == "probe"}
    assert first["seed"] in seeds, "the reduction's runs use the failing run's seed"


def test_a_rate_on_a_test_without_robot_world_is_a_warning(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(
        """
        import pytest

        @pytest.mark.ddenv(rate=3)
        def test_plain():
            pass
        """
    )
    result = pytester.runpytest_subprocess()
    result.assert_outcomes(passed=1, warnings=1)
    result.stdout.fnmatch_lines(["*test_plain: ddenv rate=3 ignored: the test does not use robot_world*"])


@pytest.mark.parametrize(("option", "value", "message"), [
    ("--ddenv-rate", "0", "--ddenv-rate: expected an integer >= 1 and <= 10000, got '0'"),
    ("--ddenv-rate", "10001", "--ddenv-rate: expected an integer >= 1 and <= 10000, got '10001'"),
    ("--ddenv-max-failure-rate", "1", "--ddenv-max-failure-rate: expected a number >= 0 and < 1"),
    ("--ddenv-max-failure-rate", "nan", "--ddenv-max-failure-rate: expected a number >= 0 and < 1"),
])
def test_bad_rate_options_are_usage_errors(pytester: pytest.Pytester, option: str, value: str, message: str) -> None:
    result = pytester.runpytest_subprocess(option, value)
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines([f"*{message}*"])


def test_a_bad_rate_marker_names_the_test_and_the_argument(drift_project: pytest.Pytester) -> None:
    drift_project.makepyfile(test_drift=DRIFT_TEST.format(marker=", rate=2.5"))
    result = drift_project.runpytest_subprocess()
    assert result.ret != pytest.ExitCode.OK
    result.stderr.fnmatch_lines(["*test_drift*ddenv(rate=...): expected an integer >= 1 and <= 10000, got 2.5*"])
