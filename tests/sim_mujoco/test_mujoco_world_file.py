"""Choosing MuJoCo in a world file (`physics: {engine: mujoco}`): read, written back, refused with one clear
error when the engine is unknown or not installed, and run end to end by `robot_world` and its reduction."""

from __future__ import annotations

import dataclasses
import json
import sys
import textwrap
from pathlib import Path

import pytest

pytest.importorskip("mujoco", reason="needs mujoco: pip install \"pytest-ddenv[mujoco]\"")

from pytest_ddenv.errors import WorldError
from pytest_ddenv.sim import Simulator
from pytest_ddenv.world import Physics, World
from pytest_ddenv.world.limits import default_engine

WALL_PATH = Path(__file__).resolve().parents[1] / "data" / "wall.yaml"
WALL = WALL_PATH.read_text(encoding="utf-8")


def wall_in(engine_line: str) -> str:
    return WALL.replace("name: wall\n", f"name: wall\n{engine_line}\n")


def test_the_engine_key_is_read_and_written_back(tmp_path: Path) -> None:
    path = tmp_path / "wall.yaml"
    path.write_text(wall_in("physics: {engine: mujoco}"))
    world = World.load(path)
    assert world.physics == Physics(engine="mujoco")
    world.save(tmp_path / "again.yaml")
    assert "engine: mujoco" in (tmp_path / "again.yaml").read_text()
    assert World.load(tmp_path / "again.yaml").physics.engine == "mujoco"
    assert World.load(WALL_PATH).physics.engine == default_engine()  # pybullet where it is installed, else mujoco


def test_an_unknown_engine_is_one_error_naming_the_file_and_field(tmp_path: Path) -> None:
    path = tmp_path / "wall.yaml"
    path.write_text(wall_in("physics: {engine: bullet}"))
    with pytest.raises(WorldError) as caught:
        World.load(path)
    message = str(caught.value)
    assert str(path) in message and "physics.engine" in message
    assert "pybullet, mujoco" in message and "'bullet'" in message


def test_mujoco_not_installed_is_one_error_with_the_install_hint(tmp_path: Path,
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "wall.yaml"
    path.write_text(wall_in("physics: {engine: mujoco}"))
    monkeypatch.setitem(sys.modules, "mujoco", None)  # what `import mujoco` sees where it is not installed
    with pytest.raises(WorldError) as caught:
        World.load(path)
    message = str(caught.value)
    assert str(path) in message and "physics.engine" in message
    assert 'the mujoco physics engine is not installed: pip install "pytest-ddenv[mujoco]"' in message


def test_a_world_made_in_python_with_an_unknown_engine_is_refused_when_run() -> None:
    world = dataclasses.replace(World.load(WALL_PATH), physics=Physics(engine="bullet"))
    with Simulator() as sim, pytest.raises(WorldError) as caught:
        sim.run(world)
    assert caught.value.field == "physics.engine" and "one of pybullet, mujoco" in str(caught.value)


def test_a_pybullet_robot_class_is_refused_by_the_mujoco_engine(tmp_path: Path) -> None:
    from pytest_ddenv.errors import ScenarioError
    from pytest_ddenv.sim import Robot, register_robot
    from pytest_ddenv.sim.robot import ROBOTS

    class Wheelbarrow(Robot):  # a robot that spawns itself in pybullet
        def spawn(self, client: int, position: tuple[float, float, float], yaw: float) -> int:
            raise AssertionError("not reached")

        wheel_links = ()
        link_names = property(lambda self: {})
        mass = 1.0

        def drive(self, linear: float, angular: float, scale_left: float = 1.0, scale_right: float = 1.0) -> None:
            pass

        def measured_velocity(self) -> tuple[float, float]:
            return 0.0, 0.0

    register_robot("wheelbarrow", Wheelbarrow)
    try:
        path = tmp_path / "wall.yaml"
        text = wall_in("physics: {engine: mujoco}").replace("scenario:\n", "scenario:\n  robot: wheelbarrow\n")
        path.write_text(text)
        with Simulator() as sim, pytest.raises(ScenarioError, match="pybullet robot") as caught:
            sim.run(World.load(path))
        assert str(path) in str(caught.value)
    finally:
        del ROBOTS["wheelbarrow"]


def test_ddenv_run_simulates_a_mujoco_world(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                             monkeypatch: pytest.MonkeyPatch) -> None:
    from pytest_ddenv.cli import main as cli

    (tmp_path / "wall.yaml").write_text(wall_in("physics: {engine: mujoco}"))
    monkeypatch.chdir(tmp_path)
    code = cli.main(["run", "wall.yaml", "--predicate", "stuck"])
    out = capsys.readouterr().out
    assert code == 1 and "wall.yaml: 6 models, seed 0: FAILED (stuck at t = " in out and "touching wall" in out
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()


def test_an_unknown_engine_is_one_ddenv_error(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                             monkeypatch: pytest.MonkeyPatch) -> None:
    from pytest_ddenv.cli import main as cli

    (tmp_path / "wall.yaml").write_text(wall_in("physics: {engine: bullet}"))
    monkeypatch.chdir(tmp_path)
    code = cli.main(["run", "wall.yaml"])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "wall.yaml" in err and "physics.engine" in err and "'bullet'" in err


SCENARIO_TEST = textwrap.dedent(
    """\
    import pytest

    @pytest.mark.ddenv(world="wall.yaml", partition="model2model", deflake=1)
    @pytest.mark.robot_failure("stuck", window=2.0, min_progress=0.2)
    def test_reaches_goal(robot_world):
        run = robot_world.run()
        assert run.engine == "mujoco"
        assert run.reached_goal
    """
)


@pytest.mark.slow
def test_a_robot_world_test_of_a_mujoco_world_fails_and_reduces_in_mujoco(pytester: pytest.Pytester) -> None:
    pytester.makefile(".yaml", wall=wall_in("physics: {engine: mujoco}"))
    pytester.makepyfile(test_scenario=SCENARIO_TEST)
    result = pytester.runpytest_subprocess("--ddenv-reduce", "--ddenv-media", "none", "-p", "no:cacheprovider")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*RobotFailure: The 'stuck' predicate fired*"])  # not the engine assertion
    (summary_path,) = Path(pytester.path, "ddenv-artifacts").glob("*/summary.json")
    summary = json.loads(summary_path.read_text())
    assert summary["minimal_models"] == ["wall"]
    minimal = World.load(summary_path.parent / "minimal.yaml")
    assert minimal.physics.engine == "mujoco" and minimal.names == ("wall",)
