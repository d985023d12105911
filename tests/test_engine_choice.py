"""Choosing the physics engine: `ddenv(engine=...)`, `--ddenv-engine` (and `ddenv_engine`), `ddenv run|reduce|replay
--engine`, over the world file's `physics.engine`, over the default (pybullet where it is installed, otherwise
mujoco). Real pybullet and MuJoCo runs; pytester and subprocesses for the front ends."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from pytest_ddenv.cli import main as cli
from pytest_ddenv.driver.markers import MarkerError, parse_ddenv_marker
from pytest_ddenv.world import World

pytestmark = [pytest.mark.pybullet, pytest.mark.mujoco]  # compares the two engines (tests/engines.py)

WALL_PATH = Path(__file__).resolve().parent / "data" / "wall.yaml"
WALL = WALL_PATH.read_text(encoding="utf-8")
WALL_IN_MUJOCO = WALL.replace("name: wall\n", "name: wall\nphysics: {engine: mujoco}\n")
INSTALL_HINT = 'the mujoco physics engine is not installed: pip install "pytest-ddenv[mujoco]"'
BLOCK_PYBULLET = 'import sys; sys.modules["pybullet"] = None; sys.modules["pybullet_data"] = None\n'
"""What `import pybullet` sees where it is not installed (Python >= 3.12: no wheel)."""

ENGINES_TEST = textwrap.dedent(
    """\
    import pytest

    def ran(robot_world, name):
        run = robot_world.run(timeout=0.5)
        print(f"ENGINE {name} {run.engine}")

    @pytest.mark.ddenv(world="wall.yaml")
    def test_unnamed(robot_world):
        ran(robot_world, "unnamed")

    @pytest.mark.ddenv(world="wall_mujoco.yaml")
    def test_world_file(robot_world):
        ran(robot_world, "world-file")

    @pytest.mark.ddenv(world="wall.yaml", engine="mujoco")
    def test_marker(robot_world):
        ran(robot_world, "marker")

    @pytest.mark.ddenv(world="wall_mujoco.yaml", engine="pybullet")
    def test_marker_over_world_file(robot_world):
        ran(robot_world, "marker-over-file")
    """
)


def _engines_project(pytester: pytest.Pytester) -> pytest.Pytester:
    pytester.makefile(".yaml", wall=WALL, wall_mujoco=WALL_IN_MUJOCO)
    pytester.makepyfile(test_engines=ENGINES_TEST)
    return pytester


def _engines_ran(result: pytest.RunResult) -> dict[str, str]:
    return dict(re.findall(r"ENGINE (\S+) (\S+)", result.stdout.str()))


def test_the_marker_then_the_world_file_then_the_default_choose_the_engine(pytester: pytest.Pytester) -> None:
    result = _engines_project(pytester).runpytest_subprocess("-s", "-p", "no:cacheprovider")
    result.assert_outcomes(passed=4)
    assert _engines_ran(result) == {"unnamed": "pybullet", "world-file": "mujoco", "marker": "mujoco",
                                    "marker-over-file": "pybullet"}


@pytest.mark.parametrize("how", ["option", "ini"])
def test_the_option_or_its_ini_key_chooses_the_engine_over_the_marker(pytester: pytest.Pytester, how: str) -> None:
    _engines_project(pytester)
    if how == "ini":
        pytester.makeini("[pytest]\nddenv_engine = pybullet\n")
        result = pytester.runpytest_subprocess("-s", "-p", "no:cacheprovider")
    else:
        result = pytester.runpytest_subprocess("-s", "-p", "no:cacheprovider", "--ddenv-engine", "mujoco")
    result.assert_outcomes(passed=4)
    chosen = "pybullet" if how == "ini" else "mujoco"
    assert _engines_ran(result) == dict.fromkeys(["unnamed", "world-file", "marker", "marker-over-file"], chosen)


GIVEN_TEST = textwrap.dedent(
    """\
    from hypothesis import HealthCheck, given, settings

    from pytest_ddenv.strategies import worlds

    @settings(max_examples=2, deadline=None, database=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
    @given(world=worlds(count=(1, 2)))
    def test_drawn(robot_world, world):
        print("ENGINE drawn", robot_world.rebound(world).run(timeout=0.2).engine)
    """
)


def test_the_worlds_a_given_test_draws_run_in_the_chosen_engine(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(test_given=GIVEN_TEST)
    result = pytester.runpytest_subprocess("-s", "-p", "no:cacheprovider", "--ddenv-engine", "mujoco")
    result.assert_outcomes(passed=1)
    assert set(re.findall(r"ENGINE drawn (\S+)", result.stdout.str())) == {"mujoco"}


def test_an_unknown_engine_is_one_usage_error_naming_the_option(pytester: pytest.Pytester) -> None:
    result = _engines_project(pytester).runpytest_subprocess("--ddenv-engine", "bullet", "-p", "no:cacheprovider")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines(["*--ddenv-engine: expected one of pybullet, mujoco, got 'bullet'*"])


def test_an_unknown_engine_in_the_marker_is_one_error_naming_the_argument() -> None:
    with pytest.raises(MarkerError, match=r"ddenv\(engine=\.\.\.\): expected one of pybullet, mujoco, got 'Mujoco'"):
        parse_ddenv_marker((), {"engine": "Mujoco"})
    assert parse_ddenv_marker((), {"engine": "mujoco"}).engine == "mujoco"


def test_a_missing_engine_package_is_one_error_with_the_install_hint(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "mujoco", None)  # what `import mujoco` sees where it is not installed
    with pytest.raises(MarkerError) as caught:
        parse_ddenv_marker((), {"engine": "mujoco"})
    assert str(caught.value) == f"ddenv(engine=...): {INSTALL_HINT}"


@pytest.mark.parametrize("command", ["run", "reduce", "replay"])
def test_each_ddenv_command_refuses_an_unknown_engine_naming_the_flag(command: str,
                                                                       capsys: pytest.CaptureFixture[str]) -> None:
    words = {"run": ["run", "w.yaml"], "reduce": ["reduce", "w.yaml", "-p", "stuck"], "replay": ["replay", "dir"]}
    with pytest.raises(cli._ArgumentError, match=r"argument --engine: expected one of pybullet, mujoco, got 'ode'"):
        cli.build_parser().parse_args([*words[command], "--engine", "ode"])


def test_ddenv_run_without_mujoco_installed_says_how_to_install_it(tmp_path: Path) -> None:
    (tmp_path / "wall.yaml").write_text(WALL)
    code = ('import sys; sys.modules["mujoco"] = None\nfrom pytest_ddenv.cli.main import main\n'
            'sys.exit(main(["run", "wall.yaml", "--engine", "mujoco", "--no-picture"]))')
    done = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert done.returncode == 2, done.stderr
    assert f"argument --engine: {INSTALL_HINT}" in done.stderr and len(done.stderr.strip().splitlines()) <= 2


@pytest.mark.parametrize(("world", "flag", "engine"), [(WALL, "mujoco", "mujoco"), (WALL_IN_MUJOCO, None, "mujoco"),
                                                      (WALL_IN_MUJOCO, "pybullet", "pybullet")])
def test_ddenv_run_simulates_in_the_engine_of_its_flag_else_of_the_world(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch,
        world: str, flag: str | None, engine: str) -> None:
    (tmp_path / "wall.yaml").write_text(world)
    monkeypatch.chdir(tmp_path)
    code = cli.main(["run", "wall.yaml", "--predicate", "stuck", "--no-picture",
                     *(["--engine", flag] if flag else [])])
    out = capsys.readouterr().out
    assert code == 1 and "FAILED (stuck at t = " in out
    assert f" s wall ({engine} " in out


def test_without_pybullet_the_plugin_imports_and_runs_a_world_in_mujoco(tmp_path: Path) -> None:
    """A fresh interpreter where `import pybullet` fails, as on Python >= 3.12: the plugin, the facade and the
    command import (no module imported at start-up imports pybullet), a world that names no engine runs in
    MuJoCo, and a robot_world test passes under pytest."""
    (tmp_path / "wall.yaml").write_text(WALL)
    (tmp_path / "test_wall.py").write_text(textwrap.dedent(
        """\
        import pytest

        @pytest.mark.ddenv(world="wall.yaml")
        def test_stops_at_the_wall(robot_world):
            run = robot_world.run(timeout=3.0)
            assert run.engine == "mujoco" and not run.reached_goal
        """))
    code = BLOCK_PYBULLET + textwrap.dedent(
        """\
        import pytest
        import pytest_ddenv, pytest_ddenv.pytest_plugin.hooks, pytest_ddenv.cli.main, pytest_ddenv.driver.run
        from pytest_ddenv.world import World
        assert World.load("wall.yaml").physics.engine == "mujoco"
        code = pytest.main(["test_wall.py", "-q", "-p", "no:cacheprovider"])
        loaded = sorted(name for name, module in sys.modules.items() if module is not None and "pybullet" in name)
        print("LOADED", loaded)
        sys.exit(int(code))
        """)
    done = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "1 passed" in done.stdout and "LOADED []" in done.stdout


SCENARIO_TEST = textwrap.dedent(
    """\
    import pytest

    @pytest.mark.ddenv(world="wall.yaml", partition="model2model", deflake=1)
    @pytest.mark.robot_failure("stuck", window=2.0, min_progress=0.2)
    def test_reaches_goal(robot_world):
        assert robot_world.run().reached_goal
    """
)


@pytest.mark.slow
def test_switching_the_engine_never_resumes_the_other_engines_verdicts(pytester: pytest.Pytester) -> None:
    pytester.makefile(".yaml", wall=WALL)
    pytester.makepyfile(test_scenario=SCENARIO_TEST)
    arguments = ["--ddenv-reduce", "--ddenv-media", "none", "--ddenv-workers", "2", "-p", "no:cacheprovider"]
    first = pytester.runpytest_subprocess(*arguments)
    first.assert_outcomes(failed=1)
    (folder,) = Path(pytester.path, "ddenv-artifacts").iterdir()
    assert json.loads((folder / "summary.json").read_text())["engine"]["name"] == "pybullet"
    first.stdout.fnmatch_lines(["*physics engine: pybullet 3.*"])

    again = pytester.runpytest_subprocess(*arguments, "--ddenv-engine", "mujoco")
    again.assert_outcomes(failed=1)
    moved = ("*the run log of another problem (the physics engine changed: pybullet 3.* -> mujoco *) was kept as "
             "runs.previous-1.jsonl*")
    again.stdout.fnmatch_lines([moved, "*physics engine: mujoco *"])
    assert "the world changed" not in again.stdout.str() and "settings changed" not in again.stdout.str()
    summary = json.loads((folder / "summary.json").read_text())
    assert summary["engine"]["name"] == "mujoco" and summary["resumed_probes"] == 0
    assert summary["replay"].endswith("minimal.yaml --ddenv-engine mujoco")
    assert summary["minimal_models"] == ["wall"]
    assert World.load(folder / "minimal.yaml").physics.engine == "mujoco"
    header = json.loads((folder / "runs.jsonl").read_text().splitlines()[0])
    assert header["parts"]["engine"].startswith("mujoco ")

    replayed = subprocess.run([sys.executable, "-m", "pytest_ddenv", "replay", str(folder), "--runs", "1",
                               "--engine", "pybullet", "-p", "stuck:window=2,min_progress=0.2"],
                              cwd=pytester.path, capture_output=True, text=True, timeout=600)
    assert replayed.returncode == 0, replayed.stdout + replayed.stderr
    assert "minimal world of 1 models in pybullet" in replayed.stdout


def test_the_problem_names_the_engine_and_a_log_from_before_engines_were_named_is_pybullets() -> None:
    from dataclasses import replace

    from pytest_ddenv.driver.code_identity import CodeIdentity
    from pytest_ddenv.driver.problem import ENGINE_PART, problem_of

    world = World.load(WALL_PATH)
    in_pybullet = problem_of(world, {}, "", CodeIdentity())
    in_mujoco = problem_of(world.with_engine("mujoco"), {}, "", CodeIdentity())
    assert in_pybullet.fingerprint != in_mujoco.fingerprint
    assert {key: value for key, value in in_pybullet.parts.items() if key != ENGINE_PART} == \
        {key: value for key, value in in_mujoco.parts.items() if key != ENGINE_PART}  # only the engine differs
    assert in_mujoco.differences(in_pybullet.header()) == [
        f"the physics engine changed: {in_pybullet.parts[ENGINE_PART]} -> {in_mujoco.parts[ENGINE_PART]}"]
    older = in_pybullet.header()
    older = replace(older, parts={key: value for key, value in older.parts.items() if key != ENGINE_PART})
    assert in_pybullet.differences(older) == []
    assert in_mujoco.differences(older) == [f"the physics engine changed: pybullet -> {in_mujoco.parts[ENGINE_PART]}"]
