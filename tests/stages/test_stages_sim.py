"""The stages on real simulations, through `ddenv reduce` (one worker: in this process)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from engines import engine_flag

from pytest_ddenv.cli.main import main
from pytest_ddenv.oracle import PredicateSpec
from pytest_ddenv.scenario.robot_world import RobotFailure, RobotWorld
from pytest_ddenv.world import World

pytestmark = pytest.mark.slow  # real reductions (subprocesses, simulations): the full tier only

LONG_WALL = (Path(__file__).resolve().parents[1] / "data" / "long_wall.yaml").read_text(encoding="utf-8")
STUCK = "stuck:window=3,min_progress=0.2"


def reduce_wall(tmp_path: Path, *options: str) -> dict[str, object]:
    (tmp_path / "wall.yaml").write_text(LONG_WALL)
    code = main(["reduce", str(tmp_path / "wall.yaml"), "-p", STUCK, "--workers", "1", "--out",
                 str(tmp_path / "out"), "-q", *options])
    assert code == 0  # reduced
    return json.loads((tmp_path / "out" / "summary.json").read_text())


def test_the_start_moves_3_m_closer_and_the_time_limit_shrinks(tmp_path: Path, physics_engine: str) -> None:
    summary = reduce_wall(tmp_path, "--stages", "models,time", *engine_flag(physics_engine))
    assert summary["engine"]["name"] == physics_engine
    assert summary["minimal_models"] == ["wall"]
    staged = summary["stages"]
    time = next(result for result in staged["results"] if result["stage"] == "time")
    assert time["start"][0] >= 3.0  # the robot starts at least 3 m closer to the wall
    assert time["timeout"] < 40 and time["saved_sim_seconds_passing"] > 30
    simplified = World.load(tmp_path / "out" / "simplified.yaml")
    assert simplified.scenario is not None and simplified.scenario.start.x >= 3.0
    assert simplified.physics.engine == physics_engine
    with pytest.raises(RobotFailure):  # the shortened scenario still fails the same way
        RobotWorld(simplified, predicates=(PredicateSpec("stuck", {"window": 3.0, "min_progress": 0.2}),)).run()
    fails, runs = staged["final_failure_rate"]
    assert runs >= 5 and fails == runs


def test_models_only_is_todays_reduction(tmp_path: Path) -> None:
    summary = reduce_wall(tmp_path, "--stages", "models")
    assert "stages" not in summary and "stage_files" not in summary
    folder = tmp_path / "out"
    assert not (folder / "simplified.yaml").exists() and not (folder / "passing.yaml").exists()
    records = [json.loads(line) for line in (folder / "runs.jsonl").read_text().splitlines()]
    assert not any("stage" in record for record in records)


def test_default_stages_explain_and_find_the_passing_world_from_the_log(tmp_path: Path) -> None:
    summary = reduce_wall(tmp_path)
    staged = summary["stages"]
    assert staged["stages"] == ["models", "explain", "passing"]
    explained = next(result for result in staged["results"] if result["stage"] == "explain")
    assert explained["simulations"] == 0 and explained["elements"][0]["element"] == "wall"
    assert explained["elements"][0]["without"].startswith("passes")
    found = next(result for result in staged["results"] if result["stage"] == "passing")
    assert found["difference"] == ["without wall"] and found["source"] == "log" and found["simulations"] == 0
    assert World.load(tmp_path / "out" / "passing.yaml").names == ()


def test_a_resumed_reduction_with_stages_simulates_nothing_new(tmp_path: Path) -> None:
    first = reduce_wall(tmp_path, "--stages", "models,time")
    again = reduce_wall(tmp_path, "--stages", "models,time")
    assert again["stages"]["simulations"] == 0
    for before, after in zip(first["stages"]["results"], again["stages"]["results"], strict=True):
        assert after["findings"] == before["findings"] and after.get("start") == before.get("start")
    assert (tmp_path / "out" / "simplified.yaml").exists()


def test_an_unknown_stage_is_one_clear_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "wall.yaml").write_text(LONG_WALL)
    assert main(["reduce", str(tmp_path / "wall.yaml"), "-p", STUCK, "--stages", "models,shape"]) == 2
    assert "unknown stage 'shape'; valid stages: models, shapes, attributes, time, explain, passing" in capsys.readouterr().err


def test_max_probes_covers_the_stages(tmp_path: Path) -> None:
    summary = reduce_wall(tmp_path, "--stages", "all", "--max-probes", "25")
    staged = summary["stages"]
    model_level = summary["this_run"]["simulations"] - staged["simulations"] - 1  # minus the original run
    assert staged["budget"] <= 25 - model_level  # what the model level left
    assert staged["simulations"] <= staged["budget"]
    assert summary["this_run"]["simulations"] <= 25 + 1  # the budget, and `ddenv reduce`'s own original run
    time = next(result for result in staged["results"] if result["stage"] == "time")
    assert time["incomplete"] == "budget: no probes left"
