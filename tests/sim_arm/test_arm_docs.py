"""The arm's examples in docs/world-format.md and docs/writing-tests.md are the real thing and run."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from pytest_ddenv import World

SMOKE = Path(__file__).resolve().parents[1] / "data" / "arm_smoke.yaml"

DOCS = Path(__file__).resolve().parents[2] / "docs"


def blocks(page: str, fence: str, language: str, containing: str) -> list[str]:
    text = (DOCS / page).read_text(encoding="utf-8")
    found = re.findall(rf"{fence}{language}\n(.*?){fence}", text, flags=re.DOTALL)
    return [block for block in found if containing in block]


def test_the_yaml_example_is_the_smoke_world() -> None:
    (example,) = blocks("world-format.md", "~~~", "yaml", "name: arm_smoke")
    assert World.from_yaml(example) == World.from_yaml(SMOKE.read_text(encoding="utf-8"))


def test_the_sdf_example_is_the_same_scenario(tmp_path: Path) -> None:
    (example,) = blocks("world-format.md", "```", "xml", "arm_smoke")
    element = re.compile(r"<ddenv:scenario.*?</ddenv:scenario>", flags=re.DOTALL)
    (scenario,) = element.findall(example)
    smoke = World.load(SMOKE)
    path = tmp_path / "arm_smoke.sdf"
    path.write_text(element.sub(lambda _: scenario, smoke.to_sdf()), encoding="utf-8")
    assert World.load(path).scenario == smoke.scenario


@pytest.mark.slow
@pytest.mark.pybullet
def test_the_arm_examples_pass(pytester: pytest.Pytester) -> None:
    examples = blocks("writing-tests.md", "```", "python", "arm_smoke.yaml")
    assert len(examples) == 2
    pytester.makefile(".yaml", arm_smoke=SMOKE.read_text(encoding="utf-8"))
    pytester.makepyfile(**{f"test_example_{index}": example for index, example in enumerate(examples)})
    pytester.runpytest_subprocess().assert_outcomes(passed=2)
