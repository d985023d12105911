"""`ddenv reduce scene.xml`: a real reduction of an MJCF scene (the Husky stopped by a wall among bystanders, in
MuJoCo) writes `minimal.xml`, the user's file with the removed bodies cut out, which MuJoCo loads and which is the
minimal world."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

mujoco = pytest.importorskip("mujoco", reason='reading MJCF needs mujoco: pip install "pytest-ddenv[mujoco]"')

from pytest_ddenv.cli.main import main  # noqa: E402
from pytest_ddenv.mjcf import load_mjcf  # noqa: E402
from pytest_ddenv.world import World  # noqa: E402

pytestmark = pytest.mark.slow

SCENE = Path(__file__).resolve().parents[1] / "data" / "mjcf" / "wall_in_the_way.xml"
REDUCE = ["-p", "stuck:window=2", "--same-failure", "place", "--workers", "1", "--media", "none", "--quiet"]


def cut_lines(original: str, minimal: str) -> list[str]:
    """The lines of `original` that `minimal` lacks; every line it keeps is in `minimal`, in order, as written."""
    kept = minimal.splitlines(keepends=True)
    removed, position = [], 0
    for line in original.splitlines(keepends=True):
        if position < len(kept) and kept[position] == line:
            position += 1
        else:
            removed.append(line.strip())
    assert position == len(kept), "minimal.xml has a line the original does not"
    return removed


def test_reduce_writes_the_scene_cut_down_to_the_wall(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "artifacts"
    assert main(["reduce", str(SCENE), *REDUCE, "--out", str(out)]) == 0
    assert capsys.readouterr().out.startswith(f"{SCENE}: 4 -> 1 models (75.0% removed), 1-minimal")
    summary = json.loads((out / "summary.json").read_text())
    assert summary["minimal_models"] == ["wall"]
    assert summary["minimal_xml"] == f"cut from {SCENE}"
    assert summary["files"]["minimal_xml"] == str(out / "minimal.xml")
    minimal_text = (out / "minimal.xml").read_text()
    assert cut_lines(SCENE.read_text(), minimal_text) == [
        '<body name="crate_left" pos="1 3 0.25">', '<geom type="box" size="0.25 0.25 0.25"/>', "</body>",
        '<body name="crate_right" pos="1 -3 0.25">', '<geom type="box" size="0.25 0.25 0.25"/>', "</body>",
        '<body name="post" pos="-2 2 0.5">', '<geom type="cylinder" size="0.1 0.5"/>', "</body>"]
    spec = mujoco.MjSpec.from_file(str(out / "minimal.xml"))  # MuJoCo loads it where it is
    spec.compile()
    assert [body.name for body in spec.worldbody.bodies] == ["wall"]
    assert load_mjcf(out / "minimal.xml") == World.load(SCENE).select(["wall"])
    assert World.load(out / "minimal.yaml").names == ("wall",)


def test_a_scenario_from_the_command_line_is_written_into_minimal_xml(tmp_path: Path) -> None:
    scene = tmp_path / "no_scenario.xml"
    text = SCENE.read_text()
    scene.write_text(text[:text.index("  <custom>")] + "</mujoco>\n")
    assert World.load(scene).scenario is None
    out = tmp_path / "artifacts"
    assert main(["reduce", str(scene), "--start", "0,0", "--goal", "5,0", "--timeout", "12", *REDUCE,
                 "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["minimal_models"] == ["wall"]
    assert summary["minimal_xml"] == (f"cut from {scene}; its ddenv:scenario written from the reduction's scenario "
                                      "(not the file's)")
    minimal = load_mjcf(out / "minimal.xml")
    assert minimal.names == ("wall",)
    assert minimal.scenario is not None and minimal.scenario.goal == (5.0, 0.0, None)
    assert minimal.scenario.timeout == 12.0


def test_a_pytest_scenario_test_on_an_mjcf_scene_is_reduced_to_a_cut_minimal_xml(pytester: pytest.Pytester) -> None:
    pytester.makefile(".xml", scene=SCENE.read_text())
    pytester.makepyfile(
        """
        import pytest

        @pytest.mark.ddenv(world="scene.xml")
        @pytest.mark.robot_failure("stuck", window=2.0)
        def test_reaches_the_goal(robot_world):
            robot_world.run()
        """
    )
    result = pytester.runpytest_subprocess("--ddenv-reduce", "--ddenv-workers", "1", "--ddenv-media", "none")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*test_reaches_the_goal: 4 -> 1 models*"])
    artifacts = next((pytester.path / "ddenv-artifacts").iterdir())
    summary = json.loads((artifacts / "summary.json").read_text())
    assert summary["engine"]["name"] == "mujoco"  # an MJCF scene runs in MuJoCo unless told otherwise
    assert summary["minimal_models"] == ["wall"] and summary["minimal_xml"].startswith("cut from ")
    assert load_mjcf(artifacts / "minimal.xml").names == ("wall",)
