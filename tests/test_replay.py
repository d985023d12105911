"""`ddenv replay` (pytest_ddenv.cli.replay.replay): the minimal world re-run on fresh seeds, its failure rate with a
confidence interval next to the original world's, or the recorded failing seeds for exact reproduction."""

from __future__ import annotations

import contextlib
import io
import json
import shutil
from pathlib import Path

import pytest
from engines import ENGINE_PARAMS, engine_flag

from pytest_ddenv.cli import main as cli
from pytest_ddenv.cli.replay import FRESH_FIRST_ATTEMPT, replay
from pytest_ddenv.scenario.robot_world import ATTEMPT_SEED_STRIDE

WORLD = (Path(__file__).resolve().parent / "data" / "wall_and_crate.yaml").read_text(encoding="utf-8")


@pytest.fixture(scope="module", params=ENGINE_PARAMS)
def reduced(tmp_path_factory: pytest.TempPathFactory, request: pytest.FixtureRequest) -> Path:
    """The wall world reduced in each physics engine (minimal.yaml keeps the engine; the replay reads it)."""
    folder = tmp_path_factory.mktemp("replay")
    (folder / "wall.yaml").write_text(WORLD)
    out = folder / "artifacts"
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        code = cli.main(["reduce", str(folder / "wall.yaml"), "-p", "stuck:window=2", "--workers", "1", "--out",
                         str(out), "--quiet", *engine_flag(request.param)])
    assert code == 0
    assert json.loads((out / "summary.json").read_text())["engine"]["name"] == request.param
    return out


def test_fresh_seeds_measure_the_rate_with_an_interval(reduced: Path) -> None:
    result = replay(reduced, max_runs=4)
    assert result.fresh and result.ok and result.reproduced == 4
    assert [run.seed for run in result.runs] == [(FRESH_FIRST_ATTEMPT + i) * ATTEMPT_SEED_STRIDE for i in range(4)]
    low, high = result.interval
    assert 0.4 < low < 0.6 and high == pytest.approx(1.0)  # Wilson's 95 % interval for 4/4
    assert result.original_rate == (3, 3)  # deflake="auto"'s 3 calibration runs; the curtailed rate check needed no more
    assert result.describe() == ("reproduced: 4/4 fresh seeds failed the same way (100 %, 95% interval 51-100 %); "
                                 "the original world failed 3/3 fresh runs in the reduction")
    data = result.to_dict()
    assert data["rate"] == 1.0 and data["original_rate"] == [3, 3] and data["fresh"] is True


def test_recorded_seeds_are_replayed_exactly(reduced: Path) -> None:
    result = replay(reduced, max_runs=3, recorded=True)
    logged = [json.loads(line) for line in (reduced / "runs.jsonl").read_text().splitlines()]
    failing = [r["seed"] for r in logged if r.get("event") == "probe" and r.get("outcome") == "fail"
               and r.get("candidate") == ["wall"]]
    assert not result.fresh and result.ok and [run.seed for run in result.runs] == list(dict.fromkeys(failing))[:3]


def test_a_world_that_no_longer_fails_is_not_reproduced(reduced: Path, tmp_path: Path) -> None:
    copy = tmp_path / "artifacts"
    shutil.copytree(reduced, copy)
    (copy / "minimal.yaml").write_text(WORLD.replace("  - {name: wall, pose: [2.0, 0, 0.5], box: [0.3, 4.0, 1.0]}\n",
                                                     ""))
    result = replay(copy, max_runs=3)
    assert not result.ok and result.reproduced == 0 and result.interval[0] == 0.0
    assert result.describe().startswith("NOT reproduced: 0/3 fresh seeds")
