"""The examples that `pytest examples --ddenv-reduce` reduces, beyond the paper's three scenarios: each fails
on purpose and is reduced to its culprits (real simulations, real subprocesses)."""

from __future__ import annotations

import importlib.util
import json
import re
import shutil
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples"


def reduce_example(pytester: pytest.Pytester, *parts: str) -> dict:
    """Copy an example (file or folder) and the shipped worlds into a fresh project, reduce it, return the
    summary."""
    for part in parts:
        source = EXAMPLES / part
        target = pytester.path / part
        if source.is_dir():
            shutil.copytree(source, target)
        else:
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy(source, target)
    shutil.copytree(ROOT / "worlds", pytester.path / "worlds")
    result = pytester.runpytest_subprocess("--ddenv-reduce", parts[0])
    result.assert_outcomes(failed=1)
    (summary,) = Path(pytester.path, "ddenv-artifacts").glob("*/summary.json")
    return json.loads(summary.read_text())


@pytest.mark.slow
def test_own_simulator_example_is_reduced_to_its_two_culprits(pytester: pytest.Pytester) -> None:
    summary = reduce_example(pytester, "own_simulator")
    assert summary["minimal_models"] == ["crate_in_aisle", "pallet_stack"] and summary["one_minimal"]
    assert summary["reference_failure"]["signature"]["predicate"] == "reported"
    documented = re.search(r"```python\n(@pytest\.mark\.ddenv\(world=\"warehouse\.yaml\".*?)```",
                           (ROOT / "docs" / "writing-tests.md").read_text(), flags=re.DOTALL)
    assert documented and documented.group(1) in (EXAMPLES / "own_simulator" / "test_own_simulator.py").read_text()


@pytest.mark.slow
def test_controller_example_is_reduced_to_the_cul_de_sac(pytester: pytest.Pytester) -> None:
    summary = reduce_example(pytester, "test_my_controller.py")
    assert summary["minimal_models"] == ["back_wall", "left_wall", "right_wall"]
    assert summary["reference_failure"]["signature"]["predicate"] == "no_progress"


@pytest.mark.slow
def test_gym_policy_example_is_reduced_to_the_ditch(pytester: pytest.Pytester) -> None:
    if importlib.util.find_spec("gymnasium") is None:  # not imported here: see tests/conftest.py
        pytest.skip("gymnasium is not installed")
    summary = reduce_example(pytester, "test_policy_gym.py")
    assert summary["minimal_models"] == ["asphalt_plane", "asphalt_plane_clone"]


@pytest.mark.slow
def test_urdf_robot_example_is_reduced_to_the_dock(pytester: pytest.Pytester) -> None:
    summary = reduce_example(pytester, "robots")
    assert summary["minimal_models"] == ["loading_dock"] and summary["one_minimal"]


@pytest.mark.slow
def test_generated_worlds_example_finds_a_collision_and_reduces_it_to_the_model_hit(pytester: pytest.Pytester) -> None:
    """Hypothesis (derandomized, at most 30 examples) finds a yard where the robot hits a model; ddenv reduces
    the falsifying world to that model, which fails again on fresh runs, and records the reproduction."""
    summary = reduce_example(pytester, "test_generated_worlds.py")
    signature = summary["reference_failure"]["signature"]
    assert signature["predicate"] == "collided" and len(signature["touched"]) >= 1
    assert summary["minimal_models"] == [signature["touched"][0]] and summary["one_minimal"]
    assert summary["original_size"] >= 6 and summary["failure_rate"]["fails"] >= 4
    assert summary["hypothesis"]["world_argument"] == "world" and summary["hypothesis"]["arguments"] == {}
    documented = (ROOT / "docs" / "generating-worlds.md").read_text()
    assert "def test_husky_crosses_a_cluttered_yard_without_collision" in documented
