"""The examples in the documentation run, so the docs cannot rot.

The blocks checked here carry a `<!-- checked by tests/test_docs_examples.py::TEST -->` marker in their page;
tests/test_docs_run.py runs every other code block of docs/*.md and fails on blocks that are neither run nor
marked.
"""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

from pytest_ddenv import World

pytestmark = pytest.mark.slow  # real reductions (subprocesses, simulations): the full tier only

DOCS = Path(__file__).resolve().parent.parent / "docs"


def yaml_blocks(page: str) -> list[str]:
    return re.findall(r"```yaml\n(.*?)```", (DOCS / page).read_text(), flags=re.DOTALL)


def python_blocks(page: str) -> list[str]:
    return re.findall(r"```python\n(.*?)```", (DOCS / page).read_text(), flags=re.DOTALL)


WRITING_TESTS_EXAMPLES = [block for block in python_blocks("writing-tests.md") if "wall.yaml" in block]


@pytest.mark.parametrize(
    ("index", "failure"),
    [(0, "*RobotFailure: The 'stuck' predicate fired*touching wall*"),  # the first example
     (1, "*RobotFailure: The 'stuck' predicate fired*touching wall*"),  # a controller of your own
     (2, "*RobotFailure: The 'stuck' predicate fired*touching wall*"),  # a policy through gymnasium
     (3, "*RobotFailure: The 'pressed' predicate fired*pressed against wall*")],  # predicates of your own
)
def test_writing_tests_examples_fail_and_are_reduced(pytester: pytest.Pytester, index: int, failure: str) -> None:
    from plugin.conftest import WALL_WORLD

    assert len(WRITING_TESTS_EXAMPLES) == 4
    pytester.makefile(".yaml", wall=WALL_WORLD)
    pytester.makepyfile(test_example=WRITING_TESTS_EXAMPLES[index])
    result = pytester.runpytest_subprocess("--ddenv-reduce")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines([failure, "*6 -> 1 models*"])


def test_world_format_example_loads_and_round_trips() -> None:
    (example,) = yaml_blocks("world-format.md")
    world = World.from_yaml(example, source="docs/world-format.md")
    assert world.names == ("near_plateau", "far_plateau", "barrel", "cinder_block", "ball", "start_pad")
    assert world.reducible_names[-1] == "ball" and world.model("start_pad").keep
    assert world.model("cinder_block").dynamic and world.model("barrel").static
    assert World.from_yaml(world.to_yaml()) == world


def test_every_docs_page_linked_from_the_index_exists() -> None:
    links = re.findall(r"\]\(([^)#]+\.md)\)", (DOCS / "index.md").read_text())
    assert links
    missing = [link for link in links if not (DOCS / link).resolve().is_file()]
    assert not missing, f"docs/index.md links to missing pages: {missing}"


def ci_pytest_command(lines: list[str]) -> list[str]:
    """The arguments of the one pytest command of a CI job's steps or script, with the CI's variables
    (`${{ github.run_number }}`, `$CI_PIPELINE_IID`) given a value."""
    (command,) = [line for line in lines if line.startswith("pytest ")]
    return shlex.split(re.sub(r"\$\{\{[^}]*\}\}|\$[A-Z_]+", "7", command))[1:]


def checked_ci_command(pytester: pytest.Pytester, arguments: list[str]) -> tuple[str, str, tuple[object, object]]:
    """Parse a CI job's pytest command as pytest and the plugin do (every option exists and its value is
    accepted): the artifacts folder it writes (relative, with a trailing slash), its JUnit file, and its
    (rate, max_failure_rate)."""
    from pytest_ddenv.pytest_plugin.options import read_options

    config = pytester.parseconfig(*arguments)
    options = read_options(config)
    assert options.reduce and options.max_seconds == 900
    assert config.getini("junit_logging") == "system-out"
    artifacts = f"{options.artifacts.relative_to(pytester.path).as_posix()}/"
    return artifacts, config.option.xmlpath, (options.rate, options.max_failure_rate)


def test_ci_examples_are_valid_yaml_that_keep_the_artifacts(pytester: pytest.Pytester) -> None:
    import yaml

    github, gitlab = (yaml.safe_load(block) for block in yaml_blocks("ci.md"))
    rates = []
    for job in github["jobs"].values():
        steps = job["steps"]
        artifacts, junit, rate = checked_ci_command(pytester, ci_pytest_command([s.get("run", "") for s in steps]))
        rates.append(rate)
        (report,) = [s for s in steps if s.get("uses", "").startswith("mikepenz/action-junit-report@")]
        assert report["if"] == "always()" and report["with"]["report_paths"] == junit
        assert job["permissions"]["checks"] == "write"  # the report is a check run
        upload = steps[-1]
        assert upload["uses"].startswith("actions/upload-artifact@") and upload["if"] == "always()"
        assert upload["with"]["path"].split() == [artifacts, junit]
    for job in gitlab.values():
        artifacts, junit, rate = checked_ci_command(pytester, ci_pytest_command(job["script"]))
        rates.append(rate)
        assert job["artifacts"]["when"] == "always" and job["artifacts"]["paths"] == [artifacts, junit]
        assert job["artifacts"]["reports"]["junit"] == junit
    # on each page: a job on every push (the rates of the tests' markers) and a nightly one with --ddenv-rate
    assert rates == [(None, None), (50, 0.1)] * 2
