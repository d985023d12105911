"""What sits on top of the simulation, on MuJoCo worlds: a reduction with the stages after the models, its
pictures, `recording.rrd` and animations; the gym environment; a Hypothesis-drawn world. Real MuJoCo
simulations of small worlds."""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("mujoco", reason="the MuJoCo engine is the mujoco extra: pip install 'pytest-ddenv[mujoco]'")

from hypothesis import HealthCheck, given, settings

from pytest_ddenv.cli.main import main
from pytest_ddenv.media.animate import HEIGHT, WIDTH
from pytest_ddenv.oracle import PredicateSpec
from pytest_ddenv.scenario.robot_world import RobotFailure, RobotWorld
from pytest_ddenv.sim import simulate
from pytest_ddenv.strategies import scenarios, worlds
from pytest_ddenv.world import Physics, World

STUCK = "stuck:window=2,min_progress=0.2"
CHECK_ENV_NOTES = ("infinity", "Not able to test alternative render modes", "symmetric and normalized")
"""What gymnasium's check_env may warn about (as in tests/test_gym_env.py)."""
WALL_OF_TWO_SHAPES = """\
format: 1
name: wall
physics: {engine: mujoco}
scenario:
  start: {x: 0.0, y: 0.0, yaw: 0.0}
  goal: {x: 4.0, y: 0.0}
  timeout: 20
models:
  - {name: far_box, pose: [-4, 4, 0.25], box: [0.5, 0.5, 0.5]}
  - name: wall
    pose: [2.03, 0.02, 0.5, 0, 0, 0.03]
    mu: 0.8
    restitution: 0.2
    shapes:
      - {box: [0.3, 4.0, 1.0]}
      - {box: [0.3, 0.3, 1.0], pose: [0, 5, 0, 0, 0, 0]}
  - {name: crate, pose: [-3, -3, 0.25], box: [0.5, 0.5, 0.5], mass: 5}
  - {name: ball, pose: [-3, 0, 0.2], sphere: {radius: 0.2}}
"""
"""The robot drives into the wall (stuck at x 1.35 m); the wall's second shape, its friction, restitution and
the far models play no part. The same failure is matched by place: MuJoCo lists the robot's contacts with the
wall only while the bumper presses on it, so the model it touches at the failure tick varies between runs."""


def reduce_in_mujoco(tmp_path: Path, *options: str) -> dict[str, Any]:
    (tmp_path / "wall.yaml").write_text(WALL_OF_TWO_SHAPES)
    code = main(["reduce", str(tmp_path / "wall.yaml"), "-p", STUCK, "--workers", "1", "--same-failure", "place",
                 "--out", str(tmp_path / "out"), "-q", *options])
    assert code == 0  # reduced
    summary: dict[str, Any] = json.loads((tmp_path / "out" / "summary.json").read_text())
    return summary


def stage(summary: dict[str, Any], name: str) -> dict[str, Any]:
    return next(result for result in summary["stages"]["results"] if result["stage"] == name)


@pytest.mark.slow
def test_a_mujoco_reduction_with_shapes_and_attributes_writes_its_worlds_pictures_recording_and_animations(
        tmp_path: Path) -> None:
    rr = pytest.importorskip("rerun")
    summary = reduce_in_mujoco(tmp_path, "--stages", "shapes,attributes", "--media", "all")
    out = tmp_path / "out"
    assert summary["engine"]["name"] == "mujoco" and summary["minimal_models"] == ["wall"]
    assert stage(summary, "shapes")["kept"] == ["wall#0"]
    attributes = stage(summary, "attributes")
    assert "wall: restitution 0.2 -> 0 (the failure holds)" in attributes["findings"]
    simplified = World.load(out / "simplified.yaml")
    assert simplified.physics.engine == "mujoco" and len(simplified.models[0].shapes) == 1
    assert simplified.models[0].restitution == 0
    with pytest.raises(RobotFailure):  # the simplified world still fails in MuJoCo
        RobotWorld(simplified, predicates=(PredicateSpec("stuck", {"window": 2.0, "min_progress": 0.2}),)).run()
    import imageio.v3 as iio

    for picture in ("reduction.png", "progress.png", "simplified.png"):
        image = iio.imread(out / picture)
        assert image.ndim == 3 and min(image.shape[:2]) > 100 and image.std() > 10, picture
    for animation in ("original.gif", "minimal.gif"):
        frames = iio.imread(out / animation, index=None)
        assert len(frames) > 2 and frames[0].shape == (HEIGHT, WIDTH, 3), animation
    from rerun.chunk import RrdReader

    chunks = list(RrdReader(out / "recording.rrd").stream().to_chunks())
    entities = {chunk.entity_path for chunk in chunks}
    for label in ("original", "minimal"):
        assert "/" + rr.escape_entity_path_part(label) + "/robot" in entities, sorted(entities)
    logged = [text for chunk in chunks if chunk.entity_path == "/minimal/log"
              for texts in chunk.to_record_batch().column("TextLog:text").to_pylist() for text in texts]
    assert logged[0].startswith("wall: 1 models, robot husky, seed ") and ", mujoco " in logged[0], logged
    assert set(summary["media"]["files"]) >= {"original.gif", "minimal.gif", "recording.rrd"}


@pytest.mark.slow
def test_an_attribute_stage_left_without_probes_says_what_it_did_not_decide(tmp_path: Path) -> None:
    summary = reduce_in_mujoco(tmp_path, "--stages", "attributes", "--media", "none", "--max-probes", "12")
    attributes = stage(summary, "attributes")
    assert attributes["incomplete"] == "budget: no probes left" and attributes["simulations"] == 0
    assert "nothing to simplify" not in attributes["findings"]
    assert "wall: friction mu = 0.8 -> mu = 1 not decided (budget: no probes left)" in attributes["findings"]
    assert {entry["attribute"] for entry in attributes["undecided"]} >= {"friction", "restitution"}


def test_the_gym_environment_steps_a_mujoco_world_to_its_failure() -> None:
    gymnasium = pytest.importorskip("gymnasium")
    from gymnasium.utils.env_checker import check_env

    world = World.from_yaml(WALL_OF_TWO_SHAPES, source="wall.yaml")
    robot_world = RobotWorld(world, predicates=(PredicateSpec("stuck", {"window": 2.0, "min_progress": 0.2}),))
    env = robot_world.make_env()
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            check_env(env, skip_render_check=True)
        assert all(any(note in str(w.message) for note in CHECK_ENV_NOTES) for w in caught), caught
        assert isinstance(env.observation_space, gymnasium.spaces.Dict)
        env.reset(seed=1)
        rewards = []
        while True:
            _, reward, terminated, truncated, info = env.step(np.array([1.0, 0.0]))
            rewards.append(float(reward))
            if terminated or truncated:
                break
    finally:
        env.close()
    assert terminated and info["failure"]["predicate"] == "stuck" and not info["reached_goal"]
    run = info["run"]
    assert run.engine == "mujoco" and run.pybullet_version == "" and run.engine_version
    assert 1.2 < run.poses[-1][0] < 1.5  # at the wall
    assert sum(rewards) == pytest.approx(math.dist((0.0, 0.0), (4.0, 0.0)) - info["goal_distance"] - 10.0, abs=0.1)
    with pytest.raises(RobotFailure):
        robot_world.check()


@given(world=worlds(scenarios(start=((-1.0, -1.0), (1.0, 1.0)), goal=((3.0, -1.0), (5.0, 1.0))), count=(1, 4),
                    region=((-3.0, -3.0), (6.0, 3.0)), physics=Physics(engine="mujoco")))
@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow])
def test_a_hypothesis_drawn_world_simulates_in_mujoco(world: World) -> None:
    assert World.from_yaml(world.to_yaml()).physics.engine == "mujoco"
    run = simulate(world, seed=0, timeout=1.0)
    assert run.engine == "mujoco" and run.sim_time == pytest.approx(1.0, abs=0.06)
    assert np.all(np.isfinite(run.poses)) and set(run.first_touch) <= set(world.names)
    assert abs(float(run.poses[-1][3])) < 0.5 and abs(float(run.poses[-1][4])) < 0.5  # on its wheels


@pytest.mark.slow
def test_a_hypothesis_test_run_in_mujoco_by_the_option_is_reduced_there(pytester: pytest.Pytester) -> None:
    """`--ddenv-engine mujoco` runs each drawn world in MuJoCo (`robot_world.rebound` switches its engine), and
    the falsifying example is still found among the @given arguments and reduced in MuJoCo."""
    pytester.makepyfile(test_generated=generated_test())
    result = pytester.runpytest_subprocess("--ddenv-reduce", "--ddenv-engine", "mujoco", "--ddenv-media", "none",
                                           "--ddenv-workers", "1", "-p", "no:cacheprovider")
    result.assert_outcomes(failed=1)
    assert "no reduction" not in result.stdout.str()
    (folder,) = (pytester.path / "ddenv-artifacts").iterdir()
    summary = json.loads((folder / "summary.json").read_text())
    assert summary["engine"]["name"] == "mujoco" and summary["hypothesis"]["world_argument"] == "world"
    minimal = World.load(folder / "minimal.yaml")
    assert minimal.physics.engine == "mujoco"
    assert 1 <= len(minimal) == summary["minimal_size"] < summary["original_size"]


EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "test_generated_worlds.py"
RUN_LINE = "    robot_world.rebound(world).run()\n"


def generated_test() -> str:
    """examples/test_generated_worlds.py, checking the engine its runs simulate in."""
    text = EXAMPLE.read_text(encoding="utf-8")
    assert text.count(RUN_LINE) == 1, f"{EXAMPLE} no longer runs its drawn world with {RUN_LINE.strip()!r}"
    return text.replace(RUN_LINE, '    run = robot_world.rebound(world).run()\n    assert run.engine == "mujoco"\n')
