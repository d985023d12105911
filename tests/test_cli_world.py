"""`ddenv` options for reading worlds: --model-path, --skip-unsupported, and a scenario from the command line
for worlds without one (Gazebo worlds)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from engines import installed

from pytest_ddenv.cli import main as cli
from pytest_ddenv.sim.robot import husky_urdf

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


# -- bad input: one line naming file:line, model and element; exit code 2 with --debug and --json too -----------
MESH_IN_A_FOUND_MODEL = """<?xml version="1.0"?>
<sdf version="1.7">
  <world name="w">
    <model name="wall"><static>true</static>
      <link name="l"><collision name="c"><geometry><mesh><uri>model://crate/meshes/nope.dae</uri></mesh>
      </geometry></collision></link>
    </model>
  </world>
</sdf>
"""
BAD_INPUT = {  # file name: (its text or a corpus file, what the error line holds)
    "missing_include.world": (
        ('<?xml version="1.0"?>\n<sdf version="1.7">\n  <world name="w">\n'
         "    <include><uri>model://no_such_model</uri><name>ghost</name></include>\n  </world>\n</sdf>\n"),
        ["missing_include.world:4, model ghost, field 'include/uri': cannot resolve include "
         "'model://no_such_model': model not found; searched, in order: " + str(DATA / "models")]),
    "missing_mesh.world": (MESH_IN_A_FOUND_MODEL, [
        "missing_mesh.world:5, model wall, field 'link 'l'/collision 'c'/geometry/mesh/uri': missing mesh file",
        f"model 'crate' was found at {DATA / 'models' / 'crate'}, but it has no file 'meshes/nope.dae'"]),
    "actor.world": (DATA / "corpus" / "actor.world", [
        "actor.world:11, model walker: unsupported <actor>: animated actors are not simulated", "--skip-unsupported"]),
    "malformed.world": (
        ('<?xml version="1.0"?>\n<sdf version="1.7">\n  <world name="w">\n    <model name="m"><link name="l">\n'
         "  </world>\n</sdf>\n"),
        ["malformed.world:5, model m: malformed XML: mismatched tag", "(inside <link name='l'> opened at line 4)"]),
    "bad_joint_child.world": (DATA / "corpus" / "bad_joint_child.world", [
        ("bad_joint_child.world:15, model arm, field 'joint/child': unknown frame 'fore_arm' in the <child> of joint "
         "'elbow': not a link, frame, joint or nested model of model 'arm' (there are: base, elbow, forearm)")]),
    "namespaced.world": (DATA / "corpus" / "namespaced.world", [  # loads: a Gazebo world has no scenario
        "namespaced.world: the world has no scenario", "--start X,Y[,YAW] --goal X,Y", "<ddenv:scenario>"]),
}
BAD_COMMANDS = [(name, command) for name in BAD_INPUT for command in ("check", "run")
                if (name, command) != ("namespaced.world", "check")]  # a world needs no scenario to be checked


@pytest.mark.parametrize(("name", "command"), BAD_COMMANDS, ids=lambda value: str(value))
def test_bad_input_is_one_line_and_exit_code_2(capsys: pytest.CaptureFixture[str], gazebo: Path, name: str,
                                               command: str) -> None:
    text, fragments = BAD_INPUT[name]
    if isinstance(text, Path):
        shutil.copy(text, gazebo / name)
    else:
        (gazebo / name).write_text(text)
    argv = [command, name, "--model-path", str(DATA / "models"), *(["--no-picture"] if command == "run" else [])]
    code, out, err = run(capsys, *argv)
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1, err
    assert err.startswith(f"ddenv: error: {name}") and all(fragment in err for fragment in fragments), err
    code, out, err = run(capsys, *argv, "--json")
    report = json.loads(out)
    assert code == 2 and report["ok"] is False and report["exit_code"] == 2, out
    assert report["error"] == err.strip().removeprefix("ddenv: error: ")
    code, _, err = run(capsys, "--debug", *argv)
    assert code == 2 and "Traceback" in err and all(fragment in err.strip().splitlines()[-1] for fragment in fragments)


def test_everything_not_simulated_is_said_by_check(capsys: pytest.CaptureFixture[str], gazebo: Path) -> None:
    shutil.copy(DATA / "corpus" / "everything_not_simulated.world", gazebo / "all.world")
    code, _, err = run(capsys, "check", "all.world")
    assert code == 2 and err.startswith("ddenv: error: all.world:28, model visitor: unsupported <actor>")
    code, out, _ = run(capsys, "check", "all.world", "--skip-unsupported")
    assert code == 0 and out.splitlines() == [
        "all.world: 1 model (1 reducible)",
        "not simulated: dropped visitor: unsupported <actor>: animated actors are not simulated (all.world:28)",
        "not simulated: joints: door (1 joint); each articulated model is simulated as one rigid body",
        "not simulated: plugins: libworld_stats.so (world), libdoor_opener.so (door); plugins do not run",
        "not simulated: lights: sun; lights do not take part in the simulation",
    ]
    code, out, _ = run(capsys, "check", "all.world", "--skip-unsupported", "--json")
    assert code == 0 and json.loads(out)["names"] == ["door"] and len(json.loads(out)["notes"]) == 4


UNLOADABLE_URDF = "pybullet cannot load the URDF" if installed("pybullet") else "cannot read the URDF"
"""Where pybullet is not installed, the URDF's XML is read for its joints (and MuJoCo measures it)."""
HUSKY_SIDES = "right_wheels: [front_right_wheel, rear_right_wheel], drive: skid-steer"


@pytest.mark.parametrize(("robot", "urdf_text", "field", "words"), [
    ("{urdf: HUSKY, left_wheels: [front_left_wheel, rear_left_whel], " + HUSKY_SIDES + "}", None,
     "scenario.robot.left_wheels", "the robot's URDF HUSKY has no joint named 'rear_left_whel'; its joints: "),
    ("{urdf: broken.urdf, left_wheels: [front_left_wheel], " + HUSKY_SIDES + "}", "<robot name='x'><link",
     "scenario.robot.urdf", f"{UNLOADABLE_URDF} broken.urdf"),
    ("{urdf: gone.urdf, left_wheels: [front_left_wheel], " + HUSKY_SIDES + "}", None,
     "scenario.robot.urdf", "URDF file not found: gone.urdf"),
], ids=["wrong-wheel-joint", "unloadable-urdf", "missing-urdf"])
def test_check_loads_the_robot_and_names_the_file_and_field_of_what_does_not_fit(
        capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch, robot: str,
        urdf_text: str | None, field: str, words: str) -> None:
    husky = husky_urdf()  # pybullet_data's, or without pybullet the package's copy
    monkeypatch.chdir(tmp_path)
    if urdf_text is not None:
        Path("broken.urdf").write_text(urdf_text)
    Path("robot.yaml").write_text(f"format: 1\nscenario: {{robot: {robot.replace('HUSKY', husky)}, start: {{x: 0, y: 0}}, "
                                  "goal: {x: 3, y: 0}, timeout: 5}\nmodels: []\n")
    code, out, err = run(capsys, "check", "robot.yaml")
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1, err
    assert err.startswith(f"ddenv: error: robot.yaml, field '{field}': ") and words.replace("HUSKY", husky) in err, err


def test_check_accepts_a_robot_that_fits_its_urdf(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    husky = husky_urdf()
    monkeypatch.chdir(tmp_path)
    Path("robot.yaml").write_text(f"format: 1\nscenario: {{robot: {{urdf: {husky}, left_wheels: [front_left_wheel], "
                                  f"{HUSKY_SIDES}}}, start: {{x: 0, y: 0}}, goal: {{x: 3, y: 0}}, timeout: 5}}\n"
                                  "models: []\n")
    code, out, err = run(capsys, "check", "robot.yaml")
    assert (code, out, err) == (0, "robot.yaml: 0 models (0 reducible)\n", "")
