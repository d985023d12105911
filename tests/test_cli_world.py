"""`ddenv` options for reading worlds: --model-path, --skip-unsupported, and a scenario from the command line
for worlds without one (Gazebo worlds)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from pytest_ddenv import cli

DATA = Path(__file__).resolve().parent / "data" / "sdf"
SCENARIO = "format: 1\nscenario: {robot: husky, start: {x: 0, y: 0, yaw: 0}, goal: {x: 5, y: 0}, timeout: 4}\n"


@pytest.fixture
def gazebo(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """features.world (no scenario, `model://` includes in tests/data/sdf/models) copied to a folder."""
    shutil.copy(DATA / "features.world", tmp_path / "features.world")
    shutil.copytree(DATA / "meshes", tmp_path / "meshes")
    (tmp_path / "scenario.yaml").write_text(SCENARIO)
    (tmp_path / "models.yaml").write_text("format: 1\nmodels: []\n")
    for variable in ("GAZEBO_MODEL_PATH", "GZ_SIM_RESOURCE_PATH", "IGN_GAZEBO_RESOURCE_PATH", "SDF_PATH"):
        monkeypatch.delenv(variable, raising=False)
    monkeypatch.chdir(tmp_path)
    return tmp_path


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = cli.main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_model_path_finds_the_includes(capsys: pytest.CaptureFixture[str], gazebo: Path) -> None:
    code, _, err = run(capsys, "check", "features.world")
    assert code == 2 and "cannot resolve include 'model://crate'" in err
    code, out, _ = run(capsys, "check", "features.world", "--model-path", str(DATA / "models"), "--json")
    assert code == 0 and json.loads(out)["models"] == 7


def test_a_missing_model_path_folder_is_named(capsys: pytest.CaptureFixture[str], gazebo: Path) -> None:
    code, _, err = run(capsys, "check", "features.world", "--model-path", "no/such/folder")
    assert code == 2 and "--model-path: no such folder: no/such/folder" in err


def test_a_world_without_scenario_says_how_to_add_one(capsys: pytest.CaptureFixture[str], gazebo: Path) -> None:
    code, _, err = run(capsys, "run", "features.world", "--model-path", str(DATA / "models"), "--no-picture")
    assert code == 2
    assert "the world has no scenario" in err and "--start X,Y[,YAW] --goal X,Y" in err and "--scenario" in err
    assert "<ddenv:scenario>" in err and len(err.strip().splitlines()) == 1


@pytest.mark.parametrize(
    "scenario",
    [["--start", "0,0", "--goal", "5,0", "--timeout", "4"], ["--scenario", "scenario.yaml"],
     ["--scenario", "scenario.yaml", "--goal", "5,0,0.2"]],
)
def test_a_scenario_from_the_command_line(capsys: pytest.CaptureFixture[str], gazebo: Path,
                                          scenario: list[str]) -> None:
    code, out, err = run(capsys, "run", "features.world", "--model-path", str(DATA / "models"), *scenario,
                         "--no-picture", "--json")
    assert code in (0, 1), err
    assert json.loads(out)["sim_time"] <= 4.0 + 1e-9


@pytest.mark.parametrize(
    ("option", "fragment"),
    [
        (["--start", "0,zero", "--goal", "5,0"], "--start: expected X,Y[,YAW] (numbers separated by commas), got '0,zero'"),
        (["--start", "0,0"], "--start alone is not enough: give --start and --goal"),
        (["--goal", "1,2,3,4", "--start", "0,0"], "--goal: expected X,Y[,Z]"),
        (["--scenario", "nothing.yaml"], "--scenario nothing.yaml: no such file"),
        (["--scenario", "models.yaml"], "--scenario models.yaml: the file has no 'scenario:' block"),
    ],
)
def test_bad_scenario_options_are_one_line(capsys: pytest.CaptureFixture[str], gazebo: Path, option: list[str],
                                           fragment: str) -> None:
    code, _, err = run(capsys, "run", "features.world", "--model-path", str(DATA / "models"), *option,
                       "--no-picture")
    assert code == 2 and fragment in err, err
    assert len(err.strip().splitlines()) == 1


def test_a_gazebo_world_is_reduced_with_a_command_line_scenario(capsys: pytest.CaptureFixture[str],
                                                                gazebo: Path) -> None:
    code, out, err = run(capsys, "reduce", "features.world", "--model-path", str(DATA / "models"), "--start=-4,5",
                         "--goal", "4,5", "--timeout", "15", "-p", "stuck:window=2", "--workers", "1", "--json",
                         "--quiet", "--out", "art")
    summary = json.loads(out)
    assert code == 0 and summary["minimal_models"] == ["outer"], err  # the static pair of boxes across the path
    assert "--start=-4,5 --goal=4,5 --timeout=15.0" in summary["command"]  # pastes back into a shell
    minimal = (gazebo / "art" / "minimal.yaml").read_text()
    assert "goal: {x: 4.0, y: 5.0}" in minimal and "timeout: 15.0" in minimal  # replayable as it is


def test_an_unsupported_element_is_one_line_or_skipped_with_a_note(capsys: pytest.CaptureFixture[str]) -> None:
    world = str(DATA / "corpus" / "actor.world")
    code, out, err = run(capsys, "check", world, "--json")
    assert code == 2 and json.loads(out)["exit_code"] == 2
    line = err.strip().splitlines()[-1]
    assert line.startswith(f"ddenv: error: {world}:") and "unsupported <actor>" in line and "--skip-unsupported" in line
    code, out, err = run(capsys, "check", world, "--skip-unsupported", "--json")
    data = json.loads(out)
    assert code == 0 and any(note.startswith("dropped ") and "<actor>" in note for note in data["notes"]), err
    code, _, err = run(capsys, "--debug", "check", world)
    assert code == 2 and "Traceback" in err and "unsupported <actor>" in err.strip().splitlines()[-1]
