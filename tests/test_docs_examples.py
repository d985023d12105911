"""The examples in the documentation run, so the docs cannot rot.

The blocks checked here carry a `<!-- checked by tests/test_docs_examples.py::TEST -->` marker in their page;
tests/test_docs_run.py runs every other code block of docs/*.md and fails on blocks that are neither run nor
marked.
"""

from __future__ import annotations

import re
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


def test_ci_examples_are_valid_yaml_that_keep_the_artifacts() -> None:
    import yaml

    github, gitlab = (yaml.safe_load(block) for block in yaml_blocks("ci.md"))
    upload = github["jobs"]["robot-scenarios"]["steps"][-1]
    assert upload["if"] == "always()" and "ddenv-artifacts/" in upload["with"]["path"]
    assert gitlab["robot-scenarios"]["artifacts"]["when"] == "always"
