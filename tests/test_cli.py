"""The `ddenv` command: every subcommand, its text and JSON output, and its exit codes (incl. bad input).

The worlds are tiny: the robot drives from (0, 0) to (4, 0) into a wall at x = 2 (stuck fires at ~3 s
simulated, ~0.2 s wall); four distractors stand far away. `ddenv reduce` must find exactly the wall.
"""

from __future__ import annotations

import json
import pickle
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from engines import engine_flag

from pytest_ddenv import __version__
from pytest_ddenv.cli import main as cli
from pytest_ddenv.driver.progress import Heartbeat, ProgressLine
from pytest_ddenv.driver.scenario_job import ScenarioJob
from pytest_ddenv.world import World

STUCK = "stuck:window=2.0,min_progress=0.2"
DISTRACTORS = """
- {name: crate_a, pose: [1.0, 4.0, 0.25, 0, 0, 0.3], box: [0.5, 0.5, 0.5]}
- {name: crate_b, pose: [3.0, -4.0, 0.25, 0, 0, 0], box: [0.5, 0.5, 0.5]}
- {name: barrel, pose: [-2.0, 3.0, 0.4, 0, 0, 0], cylinder: {radius: 0.3, length: 0.8}, static: false, mass: 20}
- {name: ice, pose: [5.5, -3.0, 0.01, 0, 0, 0], box: [1.0, 1.0, 0.02], mu: 0.1}
"""
HEADER = """format: 1
name: {name}
scenario: {{robot: husky, start: {{x: 0.0, y: 0.0, yaw: 0.0}}, goal: {{x: 4.0, y: 0.0}}, timeout: 20.0}}
models:
"""
WALL = "- {name: wall, pose: [2.0, 0.0, 0.5, 0, 0, 0], box: [0.3, 4.0, 1.0]}\n"


@pytest.fixture(scope="module")
def worlds(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("worlds")
    files = {
        "wall": HEADER.format(name="wall") + WALL + DISTRACTORS.lstrip("\n"),
        "open": HEADER.format(name="open") + DISTRACTORS.lstrip("\n"),
        "no_scenario": "format: 1\nmodels:\n" + WALL,
        "broken": "format: 1\nmodels:\n- {name: wall, box: [1, 1]}\n",
    }
    for name, text in files.items():
        (folder / f"{name}.yaml").write_text(text)
    return {name: folder / f"{name}.yaml" for name in files}


@pytest.fixture(scope="module")
def reduced(worlds: dict[str, Path], tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """One real `ddenv reduce --json` of the wall world, shared by the reduce and replay tests."""
    out = tmp_path_factory.mktemp("reduce") / "artifacts"
    stdout, stderr = _capture(["reduce", str(worlds["wall"]), "-p", STUCK, "--deflake", "1", "--out", str(out),
                               "--json"])
    return {"out": out, "json": json.loads(stdout[1]), "code": stdout[0], "stderr": stderr}


def _capture(argv: list[str]) -> tuple[tuple[int, str], str]:
    """Run cli.main in-process, capturing stdout and stderr without pytest's capsys (module fixtures)."""
    import contextlib
    import io

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = cli.main(argv)
    return (code, out.getvalue()), err.getvalue()


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = cli.main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def assert_one_line_error(err: str, *fragments: str) -> None:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("ddenv: error: "), err
    for fragment in fragments:
        assert fragment in lines[0], err
    assert "Traceback" not in err


# -- the command itself ---------------------------------------------------------------------------------
def test_version_help_and_no_command(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "--version")
    assert code == 0 and __version__ in out
    code, out, _ = run(capsys)
    assert code == 0 and "reduce" in out and "replay" in out and "convert" in out
    code, out, _ = run(capsys, "reduce", "--help")
    assert code == 0 and "--predicate" in out and "--workers" in out


@pytest.mark.parametrize(
    ("argv", "fragment"),
    [
        (["frobnicate"], "invalid choice"),
        (["run"], "the following arguments are required: world"),
        (["run", "w.yaml", "--seed", "-1"], "expected an integer >= 0"),
        (["run", "w.yaml", "--timeout", "0"], "expected a positive, finite number, got '0'"),
        (["reduce", str(Path(__file__).parents[1] / "worlds" / "ditch.yaml")],
         "the following arguments are required for a mobile robot's world: --predicate/-p"),
        (["reduce", "w.yaml", "-p", "stuck", "--partition", "nope"], "invalid choice: 'nope'"),
    ],
)
def test_usage_errors_are_one_line_and_exit_2(capsys: pytest.CaptureFixture[str], argv: list[str],
                                              fragment: str) -> None:
    code, out, err = run(capsys, *argv)
    assert code == 2 and out == ""
    assert_one_line_error(err, fragment)


@pytest.mark.pybullet
def test_reduce_on_an_arm_world_checks_the_arm_defaults_without_predicate(
        capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """`ddenv reduce` of an arm's world with no `--predicate`: the arm's default predicates find the hand
    hitting the tall box, and the reduction keeps it (with the table and cube the scenario names)."""
    monkeypatch.chdir(tmp_path)
    world = Path(__file__).parent / "data" / "arm_blocked.yaml"
    code, out, _ = run(capsys, "--json", "reduce", str(world), "--media", "none", "--workers", "1")
    assert code == 0, out
    summary = json.loads(out)
    assert summary["reference_failure"]["signature"]["predicate"] == "arm_collision"
    assert [p["name"] for p in summary["predicates"]] == ["arm_collision", "grasp_failed", "object_dropped",
                                                         "knocked_over", "not_placed"]
    assert sorted(summary["minimal_models"]) == ["cube", "table", "tall_box"]


def test_debug_shows_the_traceback_and_keeps_the_exit_code(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(capsys, "--debug", "--json", "check", "missing.yaml")
    assert code == 2 and "Traceback (most recent call last)" in err and "UsageError" in err
    assert err.strip().splitlines()[-1] == "ddenv: error: missing.yaml: no such world file"
    assert json.loads(out) == {"ok": False, "error": "missing.yaml: no such world file", "exit_code": 2}


def test_internal_errors_exit_3(capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    def crash(arguments: Any) -> int:
        raise RuntimeError("boom")

    monkeypatch.setitem(cli._HANDLERS, "check", crash)
    code, _, err = run(capsys, "check", "x.yaml")
    assert code == 3
    assert_one_line_error(err, "internal error: RuntimeError: boom", "--debug")


# -- check -----------------------------------------------------------------------------------------------
def test_check(capsys: pytest.CaptureFixture[str], worlds: dict[str, Path]) -> None:
    code, out, _ = run(capsys, "check", str(worlds["wall"]))
    assert code == 0 and "5 models (5 reducible)" in out
    code, out, _ = run(capsys, "check", str(worlds["wall"]), "--json")
    assert code == 0 and json.loads(out)["names"][0] == "wall"


def test_check_bad_world(capsys: pytest.CaptureFixture[str], worlds: dict[str, Path]) -> None:
    code, out, err = run(capsys, "check", str(worlds["broken"]), "--json")
    assert code == 2
    assert_one_line_error(err, "broken.yaml")
    assert json.loads(out)["ok"] is False
    code, _, err = run(capsys, "check", str(worlds["broken"].parent))
    assert code == 2
    assert_one_line_error(err, "is a folder")


# -- predicates ------------------------------------------------------------------------------------------
def test_predicate_syntax() -> None:
    assert cli.parse_predicate("stuck").params == {}
    spec = cli.parse_predicate("stuck:window=2.5,min_progress=0")
    assert (spec.name, dict(spec.params)) == ("stuck", {"window": 2.5, "min_progress": 0})
    spec = cli.parse_predicate("collided:models=[wall, barrel],min_force=2")
    assert dict(spec.params) == {"models": ["wall", "barrel"], "min_force": 2}
    assert cli.parse_predicate("fell:min_z=none").params == {"min_z": None}


@pytest.mark.parametrize(
    ("text", "fragment"),
    [
        ("stcuk", "unknown failure predicate 'stcuk'; valid predicates"),
        ("stuck:windw=5", "has no parameter 'windw'"),
        ("stuck:window=-1", "expected a number > 0"),
        ("stuck:window", "expected key=value"),
        ("high_centered:max_wheel_load=2", "fraction"),
    ],
)
def test_bad_predicates_exit_2(capsys: pytest.CaptureFixture[str], worlds: dict[str, Path], text: str,
                               fragment: str) -> None:
    code, _, err = run(capsys, "run", str(worlds["wall"]), "-p", text, "--no-picture")
    assert code == 2
    assert_one_line_error(err, f"--predicate {text!r}", fragment)


# -- run, show -------------------------------------------------------------------------------------------
def test_run_a_failing_scenario(capsys: pytest.CaptureFixture[str], worlds: dict[str, Path],
                                tmp_path: Path, physics_engine: str) -> None:
    picture, record = tmp_path / "wall.png", tmp_path / "runs.jsonl"
    code, out, _ = run(capsys, "run", str(worlds["wall"]), "-p", STUCK, "-o", str(picture), "--record", str(record),
                       *engine_flag(physics_engine))
    assert code == 1
    assert "FAILED (stuck at t = " in out and "touching wall" in out
    assert picture.stat().st_size > 10_000
    code, out, _ = run(capsys, "show", str(worlds["wall"]), "--runs", str(record), "-o", str(tmp_path / "s.png"),
                       "--json")
    assert code == 0 and json.loads(out)["runs"] == 1
    assert (tmp_path / "s.png").stat().st_size > 10_000


def test_run_json_and_a_passing_scenario(capsys: pytest.CaptureFixture[str], worlds: dict[str, Path],
                                         physics_engine: str) -> None:
    engine = engine_flag(physics_engine)
    code, out, _ = run(capsys, "run", str(worlds["wall"]), "-p", STUCK, "--no-picture", "--json", "--seed", "3", *engine)
    data = json.loads(out)
    assert code == 1 and data["outcome"] == "failed" and data["seed"] == 3
    assert data["failure"]["predicate"] == "stuck" and "wall" in data["touched"]
    code, out, _ = run(capsys, "run", str(worlds["open"]), "-p", STUCK, "--no-picture", "--json", *engine)
    data = json.loads(out)
    assert code == 0 and data["outcome"] == "reached_goal" and data["ok"] is True


def test_run_needs_a_scenario(capsys: pytest.CaptureFixture[str], worlds: dict[str, Path]) -> None:
    code, _, err = run(capsys, "run", str(worlds["no_scenario"]))
    assert code == 2
    assert_one_line_error(err, "the world has no scenario", "--start X,Y[,YAW] --goal X,Y")


def test_show_default_picture_and_bad_runs_files(capsys: pytest.CaptureFixture[str], worlds: dict[str, Path],
                                                 tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    code, _, _ = run(capsys, "show", str(worlds["wall"]))
    assert code == 0 and (tmp_path / "wall.png").exists()
    (tmp_path / "bad.jsonl").write_text("{not json\n")
    (tmp_path / "empty.jsonl").write_text("{}\n")
    for name, fragment in (("bad.jsonl", "bad.jsonl:1: not a JSON line"), ("empty.jsonl", "no runs"),
                           ("missing.jsonl", "no such runs file")):
        code, _, err = run(capsys, "show", str(worlds["wall"]), "--runs", name)
        assert code == 2
        assert_one_line_error(err, fragment)


# -- reduce ----------------------------------------------------------------------------------------------
@pytest.mark.slow  # a reduction in worker processes (ddenv reduce's default workers): the full tier only
def test_reduce_finds_exactly_the_wall(reduced: dict[str, Any]) -> None:
    data, out = reduced["json"], reduced["out"]
    assert reduced["code"] == 0, reduced["stderr"]
    assert data["minimal_models"] == ["wall"] and data["one_minimal"] is True
    assert data["predicates"] == [{"name": "stuck", "params": {"window": 2.0, "min_progress": 0.2}}]
    assert data["replay"].startswith("ddenv replay ")
    for name in ("minimal.yaml", "runs.jsonl", "summary.json", "reduction.png", "progress.png"):
        assert (out / name).stat().st_size > 0, name
    assert World.load(out / "minimal.yaml").names == ("wall",)
    assert "models |" in reduced["stderr"] and "probes" in reduced["stderr"]  # the progress lines
    records = [json.loads(line) for line in (out / "runs.jsonl").read_text().splitlines()]
    probes = [record for record in records if record["event"] == "probe"]
    assert len(probes) == data["simulations"]  # every simulation has its line: the original's run too
    assert [(p["purpose"], p["attempt"], p["outcome"]) for p in probes[:1]] == [("confirmation", 0, "fail")]


def test_reduce_a_world_that_does_not_fail(capsys: pytest.CaptureFixture[str], worlds: dict[str, Path],
                                           tmp_path: Path) -> None:
    code, _, err = run(capsys, "reduce", str(worlds["open"]), "-p", STUCK, "--out", str(tmp_path), "-q")
    assert code == 1
    assert "does not fail with seed 0" in err and "nothing to reduce" in err
    assert not (tmp_path / "summary.json").exists()


@pytest.mark.parametrize(
    ("extra", "fragment"),
    [(["--deflake", "often"], "--deflake: expected an integer >= 0 and <= 100 or one of adaptive"),
     (["--keep", "walll"], "--keep: no model named 'walll'"),
     (["--n-partitions", "1"], "--n-partitions: expected an integer >= 2, got '1'")],
)
def test_reduce_bad_options(capsys: pytest.CaptureFixture[str], worlds: dict[str, Path], extra: list[str],
                            fragment: str) -> None:
    code, _, err = run(capsys, "reduce", str(worlds["wall"]), "-p", STUCK, *extra)
    assert code == 2
    assert_one_line_error(err, fragment)


def test_the_reduce_job_can_be_sent_to_worker_processes(worlds: dict[str, Path]) -> None:
    world = World.load(worlds["wall"])
    job = ScenarioJob((cli.parse_predicate(STUCK),))
    handle = pickle.loads(pickle.dumps(job)).handler()
    failed = handle(world.select(["wall"]), 0).error
    assert failed is not None and failed.signature is not None and failed.signature.predicate == "stuck"
    assert handle(world.select(["crate_a"]), 0).error is None


# -- replay ----------------------------------------------------------------------------------------------
@pytest.mark.slow  # a reduction in worker processes (ddenv reduce's default workers): the full tier only
def test_replay_reproduces(capsys: pytest.CaptureFixture[str], reduced: dict[str, Any]) -> None:
    code, out, _ = run(capsys, "replay", str(reduced["out"]), "--runs", "2")
    assert code == 0 and "reproduced: 2/2 fresh seeds failed the same way (100 %, 95% interval 34-100 %)" in out
    code, out, _ = run(capsys, "replay", str(reduced["out"]), "--runs", "2", "--recorded")
    assert code == 0 and "recorded failing seeds" in out
    code, out, _ = run(capsys, "replay", str(reduced["out"]), "--runs", "1", "--json")
    data = json.loads(out)
    assert code == 0 and data["ok"] and data["models"] == ["wall"] and data["runs"][0]["outcome"] == "fail"


@pytest.mark.slow  # a reduction in worker processes (ddenv reduce's default workers): the full tier only
def test_replay_that_does_not_reproduce(capsys: pytest.CaptureFixture[str], reduced: dict[str, Any],
                                        worlds: dict[str, Path], tmp_path: Path) -> None:
    copy = tmp_path / "artifacts"
    shutil.copytree(reduced["out"], copy)
    shutil.copy(worlds["open"], copy / "minimal.yaml")  # the wall is gone: the robot reaches the goal
    code, out, _ = run(capsys, "replay", str(copy), "--runs", "1")
    assert code == 1 and "NOT reproduced: 0/1 fresh seeds" in out


def test_replay_bad_folders(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    code, _, err = run(capsys, "replay", str(tmp_path / "nowhere"))
    assert code == 2
    assert_one_line_error(err, "no such artifacts folder")
    code, _, err = run(capsys, "replay", str(tmp_path))
    assert code == 2
    assert_one_line_error(err, "summary.json: missing")
    (tmp_path / "summary.json").write_text("[1, 2")
    code, _, err = run(capsys, "replay", str(tmp_path))
    assert code == 2
    assert_one_line_error(err, "not valid JSON")


# -- convert ---------------------------------------------------------------------------------------------
def test_convert_round_trip(capsys: pytest.CaptureFixture[str], worlds: dict[str, Path], tmp_path: Path) -> None:
    sdf, back = tmp_path / "wall.sdf", tmp_path / "back.yaml"
    code, out, _ = run(capsys, "convert", str(worlds["wall"]), str(sdf))
    assert code == 0 and "5 models" in out and "<sdf" in sdf.read_text()
    code, out, _ = run(capsys, "convert", str(sdf), str(back), "--json")
    assert code == 0 and json.loads(out)["models"] == 5
    assert World.load(back).names == World.load(worlds["wall"]).names


@pytest.mark.parametrize(
    ("source", "target", "fragment"),
    [("wall.yaml", "out.txt", "unknown output format '.txt'"), ("missing.yaml", "out.sdf", "no such world file"),
     ("wall.yaml", "wall.yaml", "would overwrite the input")],
)
def test_convert_bad_input(capsys: pytest.CaptureFixture[str], worlds: dict[str, Path], source: str, target: str,
                           fragment: str) -> None:
    folder = worlds["wall"].parent
    code, _, err = run(capsys, "convert", str(folder / source), str(folder / target))
    assert code == 2
    assert_one_line_error(err, fragment)


# -- the installed command ---------------------------------------------------------------------------------
def test_subprocess_smoke(worlds: dict[str, Path]) -> None:
    done = subprocess.run(
        [sys.executable, "-m", "pytest_ddenv.cli", "run", str(worlds["wall"]), "-p", STUCK, "--no-picture", "--json"],
        check=False, capture_output=True, text=True, timeout=120,
    )
    assert done.returncode == 1, done.stderr
    assert json.loads(done.stdout)["failure"]["predicate"] == "stuck"
    done = subprocess.run([sys.executable, "-m", "pytest_ddenv.cli", "check", "missing.yaml"],
                          check=False, capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and done.stderr.strip().startswith("ddenv: error:") and done.stdout == ""


def test_the_failure_rate_line_compares_with_the_original_and_warns() -> None:
    from dataclasses import replace

    from pytest_ddenv.driver.report_text import failure_rate_line
    from pytest_ddenv.reduce import Rate, reduce

    solid = reduce(("a", "b"), lambda candidate, attempt: _observation("a" in candidate), deflake="auto",
                   failure_rate_runs=4)
    assert solid.rate_check is not None and solid.rate_check.decision == "holds"
    assert failure_rate_line(solid) == ("minimal world fails 4/4 fresh runs: not significantly less often than the "
                                        "original (3/3 fresh runs; 1 more could not change that; its rate: 51-100 % at 95 % "
                                        "confidence)")
    full = replace(solid, rate_check=replace(solid.rate_check, original=Rate(4, 4), skipped=0))
    assert failure_rate_line(full) == ("minimal world fails as often as the original: 4/4 vs 4/4 fresh runs (its "
                                      "rate: 51-100 % at 95 % confidence)")
    below = replace(solid, rate_check=replace(solid.rate_check, reduced=Rate(0, 4), decision="below"),
                    rate_backoffs=3)
    assert failure_rate_line(below).endswith("(warning: significantly less often, after 3 back-offs)")
    stopped = replace(solid, rate_check=replace(solid.rate_check, reduced=Rate(2, 2), decision="continue"))
    assert "undecided, the budget stopped the rate comparison" in failure_rate_line(stopped)
    unchecked = replace(solid, rate_check=None, failure_rate=(1, 5))
    assert failure_rate_line(unchecked) == (
        "minimal world fails 1/5 fresh runs (original world: 3/3) (warning: it rarely reproduces the failure)")


def _observation(failed: bool) -> Any:
    from pytest_ddenv.reduce import Outcome, ProbeObservation

    return ProbeObservation(Outcome.FAIL if failed else Outcome.PASS)


# -- progress in CI logs ---------------------------------------------------------------------------------
class _Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def _event(kind: str, size: int, probes: int, elapsed: float) -> Any:
    from pytest_ddenv.reduce import ProgressEvent

    return ProgressEvent(kind=kind, size=size, probes=probes, granularity=2, elapsed=elapsed)


def test_progress_without_a_terminal_prints_each_step_and_a_line_when_silent_too_long() -> None:
    import io

    stream = io.StringIO()  # not a terminal
    progress = ProgressLine(stream, heartbeat=3600.0)
    clock = _Clock()
    progress.heartbeat.close()  # driven by hand below: no thread
    progress.heartbeat = Heartbeat(progress._beat, 30.0, clock=clock)
    progress.update(_event("start", 6, 0, 0.0))
    for probes in range(1, 4):
        progress.update(_event("probe", 6, probes, probes))
    clock.now = 3.0
    progress.update(_event("step", 3, 3, 3.0))
    clock.now = 31.0  # 28 s after the step's line: not yet
    progress.update(_event("probe", 3, 4, 31.0))
    clock.now = 34.0  # 31 s: this probe's line is the heartbeat
    progress.update(_event("probe", 3, 5, 34.0))
    progress.update(_event("end", 2, 6, 35.0))
    progress.close()
    lines = stream.getvalue().splitlines()
    assert [line.rsplit("| ", 1)[1] for line in lines] == ["start", "step", "probe", "models done"]
    assert "6 -> 3 models | 3 probes" in lines[1] and "| 5 probes | 00:34" in lines[2]


def test_the_heartbeat_writes_while_nothing_else_does() -> None:
    import threading

    beats = threading.Event()
    heartbeat = Heartbeat(beats.set, interval=0.01)
    heartbeat.start()
    try:
        assert beats.wait(timeout=60.0)  # a hang guard, not a timing assertion
    finally:
        heartbeat.close()


def test_a_quiet_or_terminal_progress_has_no_heartbeat_thread() -> None:
    import io

    quiet = ProgressLine(io.StringIO(), quiet=True)
    assert quiet.heartbeat._thread is None
    quiet.close()


def test_a_closed_pipe_ends_the_command_quietly(tmp_path: Path) -> None:
    """`ddenv ... | head`: the reader goes away before the output is written; no traceback on stderr."""
    world = Path(__file__).resolve().parent.parent / "worlds" / "ditch.yaml"
    process = subprocess.Popen([sys.executable, "-m", "pytest_ddenv.cli", "check", str(world), "--json"],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=tmp_path)
    assert process.stdout is not None and process.stderr is not None
    process.stdout.close()  # before the command has written anything (it is still importing)
    error = process.stderr.read().decode()
    assert process.wait(timeout=120) == 1
    assert "Traceback" not in error and "Broken pipe" not in error


# -- --skip-unsupported: one warning naming what was dropped ------------------------------------------------
ACTOR_WORLD = """<?xml version="1.0"?>
<sdf version="1.6">
  <world name="actor_wall">
    <model name="ground_plane">
      <static>true</static>
      <link name="l"><collision name="c"><geometry><plane><normal>0 0 1</normal><size>100 100</size></plane>
      </geometry></collision></link>
    </model>
    <model name="wall">
      <static>true</static>
      <pose>2 0 0.5 0 0 0</pose>
      <link name="l"><collision name="c"><geometry><box><size>0.3 4 1</size></box></geometry></collision></link>
    </model>
    <model name="crate">
      <static>true</static>
      <pose>-3 4 0.25 0 0 0</pose>
      <link name="l"><collision name="c"><geometry><box><size>0.5 0.5 0.5</size></box></geometry></collision></link>
    </model>
    <actor name="walker">
      <skin><filename>walk.dae</filename></skin>
    </actor>
  </world>
</sdf>
"""
ACTOR_LINE = ACTOR_WORLD.splitlines().index('    <actor name="walker">') + 1
SCENARIO = ["--start", "0,0", "--goal", "4,0", "--timeout", "10"]


@pytest.mark.parametrize(
    "command",
    [
        ["run", "{world}", *SCENARIO, "-p", STUCK, "--no-picture"],
        ["convert", "{world}", "{tmp}/out.yaml"],
        ["show", "{world}", "-o", "{tmp}/world.png"],
        ["reduce", "{world}", *SCENARIO, "-p", STUCK, "--deflake", "1", "--workers", "1", "--quiet",
         "--media", "none", "--out", "{tmp}/artifacts"],
    ],
    ids=["run", "convert", "show", "reduce"],
)
def test_skip_unsupported_warns_once_naming_each_dropped_model(capsys: pytest.CaptureFixture[str],
                                                               tmp_path: Path, command: list[str]) -> None:
    world = tmp_path / "actor_wall.world"
    world.write_text(ACTOR_WORLD)
    argv = [part.format(world=world, tmp=tmp_path) for part in command]
    code, out, err = run(capsys, *argv, "--skip-unsupported")
    assert code in (cli.EXIT_OK, cli.EXIT_FAILED), err
    warnings = [line for line in err.splitlines() if line.startswith("ddenv: warning: ")]
    expected = (f"ddenv: warning: {world}: skip_unsupported dropped 1 model that cannot be simulated: "
                f"walker: unsupported <actor>: animated actors are not simulated ({world}:{ACTOR_LINE})")
    assert warnings == [expected], err
    code, out, err = run(capsys, *argv, "--skip-unsupported", "--json")
    data = json.loads(out)
    assert [line.split(":")[0] for line in data["dropped"]] == ["walker"]
    assert "ddenv: warning:" in err and "walker" in err
    code, out, err = run(capsys, *argv)  # without skipping the world is refused, as before
    assert code == cli.EXIT_USAGE and "unsupported <actor>" in err and "warning" not in err
