"""`ddenv reduce` in the loop a user lives in: reduce, edit the `--import`ed controller, reduce again -> the
answer for the edited controller, never the earlier run's verdicts; and a failure that happens with no
models at all is not "reduced" (real processes, real simulations)."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from pytest_ddenv.driver.artifacts import artifact_dir_name

pytestmark = pytest.mark.slow  # real reductions in subprocesses

TWO_WALLS = (Path(__file__).parent / "data" / "two_walls.yaml").read_text()

STEER = textwrap.dedent(
    """\
    import math

    from pytest_ddenv import Command

    SIDE = 1.0  # +1: around the left wall, -1: around the right one


    def around(observation):
        x, y, yaw = observation.pose
        wx, wy = (4.0, SIDE * 1.5) if x < 3.5 else (6.0, 0.0)
        bearing = math.atan2(wy - y, wx - x) - yaw
        bearing = math.atan2(math.sin(bearing), math.cos(bearing))
        return Command(linear=0.6, angular=max(-1.0, min(1.0, 2.0 * bearing)))


    def broken(observation):
        return (0.5, 0.0)  # not a Command: fails in every world
    """
)


def ddenv_reduce(folder: Path, controller: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "pytest_ddenv.cli", "reduce", "walls.yaml", "--import", "code/steer.py",
         "--controller", f"code/steer.py:{controller}", "--predicate", "stuck:window=2,min_progress=0.2",
         "--priority", "sequential", "--deflake", "1", "--media", "none", "--workers", "2"],
        cwd=folder, capture_output=True, text=True, timeout=600, check=False)


@pytest.fixture
def project(tmp_path: Path) -> Path:
    (tmp_path / "walls.yaml").write_text(TWO_WALLS)
    (tmp_path / "code").mkdir()
    (tmp_path / "code" / "steer.py").write_text(STEER)
    return tmp_path


def summary(folder: Path) -> dict:
    return json.loads((folder / "ddenv-artifacts" / artifact_dir_name("walls", 0) / "summary.json").read_text())


def test_an_edited_imported_controller_gives_the_new_answer(project: Path) -> None:
    first = ddenv_reduce(project, "around")
    assert first.returncode == 0, first.stderr
    assert summary(project)["minimal_models"] == ["left_wall"]
    steer = project / "code" / "steer.py"
    steer.write_text(steer.read_text().replace("SIDE = 1.0", "SIDE = -1.0"))
    second = ddenv_reduce(project, "around")
    assert second.returncode == 0, second.stderr
    after = summary(project)
    assert after["minimal_models"] == ["right_wall"] and after["resumed_runs"] == 0
    assert "the code under test changed: code/steer.py (edited)" in second.stdout + second.stderr
    assert "in earlier runs" not in second.stdout
    third = ddenv_reduce(project, "around")  # nothing edited: every probe is in the log
    assert third.returncode == 0, third.stderr
    again = summary(project)
    assert again["minimal_models"] == ["right_wall"] and again["resumed_runs"] == 1
    total, own = again["simulations"], again["this_run"]["simulations"]
    assert 0 < own < total, "this run made only its own few runs (confirmation, pictures)"
    assert f"simulations run: {total}, {own} in this run (" in third.stdout, third.stdout


def test_a_failure_without_any_model_is_not_reduced(project: Path) -> None:
    done = ddenv_reduce(project, "broken")
    assert done.returncode == 1, done.stdout
    assert "the failure does not depend on the world: it also happens with no models" in done.stderr
    assert summary(project)["status"] == "world-independent"
    assert not (project / "ddenv-artifacts" / artifact_dir_name("walls", 0) / "minimal.yaml").exists()


def test_an_edited_script_the_controller_runs_as_a_program_gives_the_new_answer(project: Path) -> None:
    steer = project / "code" / "steer.py"  # SIDE comes from a script beside it, run, never imported
    steer.write_text(steer.read_text().replace("SIDE = 1.0", (
        "import subprocess, sys\nfrom pathlib import Path\n"
        "SIDE = float(subprocess.run([sys.executable, str(Path(__file__).with_name('side.py'))],\n"
        "                            capture_output=True, text=True, check=True).stdout)")))
    side = project / "code" / "side.py"
    side.write_text("print(1.0)\n")
    first = ddenv_reduce(project, "around")
    assert first.returncode == 0, first.stderr
    assert summary(project)["minimal_models"] == ["left_wall"]
    side.write_text("print(-1.0)\n")
    second = ddenv_reduce(project, "around")
    assert second.returncode == 0, second.stderr
    after = summary(project)
    assert after["minimal_models"] == ["right_wall"] and after["resumed_runs"] == 0
    assert "the code under test changed: code/side.py" in second.stdout + second.stderr
