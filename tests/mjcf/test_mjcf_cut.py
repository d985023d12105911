"""The surgical export of an MJCF scene: the removed top-level bodies cut out of the user's text and nothing else
changed; elements naming something in a removed body cut too and said; read back by MuJoCo and equal to the
minimal world, else regenerated with the reason."""

from __future__ import annotations

import dataclasses
import difflib
from pathlib import Path

import pytest

mujoco = pytest.importorskip("mujoco", reason='reading MJCF needs mujoco: pip install "pytest-ddenv[mujoco]"')

from pytest_ddenv.cli.main import main  # noqa: E402
from pytest_ddenv.mjcf import cut_bodies, load_mjcf, minimal_xml  # noqa: E402
from pytest_ddenv.mjcf._reader import read_scene  # noqa: E402
from pytest_ddenv.world import Pose, World  # noqa: E402

CORPUS = Path(__file__).resolve().parents[1] / "data" / "mjcf"


def removed_lines(before: bytes, after: bytes) -> list[str]:
    """The lines `after` lacks, and nothing else differs (every other line byte-identical)."""
    diff = list(difflib.ndiff(before.decode().splitlines(keepends=True), after.decode().splitlines(keepends=True)))
    assert not [line for line in diff if line.startswith(("+ ", "? "))]
    return [line[2:].strip() for line in diff if line.startswith("- ")]


def top_level_bodies(data: bytes, like: Path) -> list[str]:
    spec = mujoco.MjSpec.from_string(data.decode(), include={
        "parts/bystanders.xml": (CORPUS / "parts" / "bystanders.xml").read_bytes()})
    spec.modelfiledir = str(like.parent)
    spec.compile()
    return [body.name for body in spec.worldbody.bodies]


def test_removed_bodies_are_cut_and_nothing_else_changes() -> None:
    source = CORPUS / "every_geom.xml"
    cut = cut_bodies(source, ["crate", "cabinet"])
    assert removed_lines(source.read_bytes(), cut.data) == [
        '<body name="crate" pos="3 1 0.25" euler="0 0 30">', '<geom class="crate"/>', "</body>",
        '<body name="cabinet" pos="-4 3 0.5">', '<geom type="box" size="0.3 0.4 0.5"/>',
        '<geom type="box" size="0.05 0.05 0.05" contype="0" conaffinity="0" rgba="1 1 1 1"/>',
        '<body name="door" pos="0.31 0 0">', '<joint name="door_hinge" type="hinge" axis="0 0 1" range="-90 0"/>',
        '<geom type="box" size="0.01 0.4 0.5" pos="0 0.4 0"/>', "</body>", "</body>"]
    assert cut.also_cut == () and not cut.scenario_written
    assert top_level_bodies(cut.data, source) == ["barrel", "bench", "post", "ball", "pipe", "rock", "ramp",
                                                  "bumps", "tile"]


def test_the_minimal_xml_equals_the_minimal_world_and_says_where_its_paths_resolve() -> None:
    source = CORPUS / "every_geom.xml"
    world = load_mjcf(source)
    minimal = world.without(["crate", "ball", "rock"])
    data, how = minimal_xml(source, minimal, ["crate", "ball", "rock"])
    assert read_scene(source, data) == minimal
    assert how.startswith(f"cut from {source}; its relative paths (assets, rock.obj, wedge.stl, bumps.png, "
                          "parts/bystanders.xml) are relative to the original's folder")
    assert "copy minimal.xml beside the original to open it" in how


def test_elements_naming_a_removed_body_are_cut_too_and_said() -> None:
    source = CORPUS / "not_simulated.xml"
    world = load_mjcf(source)
    data, how = minimal_xml(source, world.without(["arm_base"]), ["arm_base"])
    assert set(removed_lines(source.read_bytes(), data)) > set([
        '<motor name="shoulder_motor" joint="shoulder" gear="10"/>', '<jointpos name="shoulder_angle" joint="shoulder"/>',
        '<touch name="tip_touch" site="tip"/>', '<joint name="lock" joint1="shoulder" joint2="rail"/>',
        '<exclude name="no_self" body1="arm_base" body2="arm_link"/>',
        '<fixed name="coupling"><joint joint="shoulder" coef="1"/><joint joint="rail" coef="-1"/></fixed>'])
    assert "also cut, as they name something in a removed body: <fixed coupling>, <joint lock>, <exclude no_self>, " \
           "<motor shoulder_motor>, <jointpos shoulder_angle>, <touch tip_touch>" in how
    reread = read_scene(source, data)
    assert reread.names == ("slider", "crate")
    assert [note for note in reread.notes if note.startswith("actuators")] == [
        "actuators: rail_drive; the scene's actuators are not driven (the robot comes from the scenario)"]


NAMESAKES = """<mujoco>
  <worldbody>
    <geom type="plane" size="10 10 0.1"/>
    <body name="wall" pos="2 0 0.5">
      <geom name="probe" type="box" size="0.1 1 0.5"/>
    </body>
    <body name="crate" pos="-2 0 0.25">
      <freejoint name="probe"/>
      <geom type="box" size="0.25 0.25 0.25"/>
    </body>
  </worldbody>
  <sensor>
    <framepos name="wall_place" objtype="geom" objname="probe"/>
    <jointpos name="crate_slide" joint="probe"/>
  </sensor>
</mujoco>
"""


def test_only_the_elements_naming_a_removed_body_in_their_own_namespace_are_cut(tmp_path: Path) -> None:
    source = tmp_path / "namesakes.xml"  # a geom of the kept wall and the removed crate's joint share a name
    source.write_text(NAMESAKES, encoding="utf-8")
    cut = cut_bodies(source, ["crate"])
    assert cut.also_cut == ("<jointpos crate_slide>",)
    assert b'<framepos name="wall_place" objtype="geom" objname="probe"/>' in cut.data
    assert top_level_bodies(cut.data, source) == ["wall"]


def test_a_scenario_given_for_the_reduction_is_written_into_the_file() -> None:
    source = CORPUS / "wall_in_the_way.xml"
    world = load_mjcf(source)
    assert world.scenario is not None
    given = dataclasses.replace(world.scenario, start=Pose(x=-1.0, y=0.5, yaw=0.25), timeout=20.0)
    minimal = dataclasses.replace(world.select(["wall"]), scenario=given)
    data, how = minimal_xml(source, minimal, ["crate_left", "crate_right", "post"])
    assert how.startswith(f"cut from {source}; its ddenv:scenario written from the reduction's scenario")
    assert read_scene(source, data) == minimal
    assert 'data="robot=husky start=-1.0,0.5,0.25 goal=5.0,0.0 timeout=20.0 tolerance=0.5"' in data.decode()


def test_a_body_in_an_included_file_is_regenerated_with_the_reason() -> None:
    source = CORPUS / "every_geom.xml"
    minimal = load_mjcf(source).without(["barrel", "post"])
    data, how = minimal_xml(source, minimal, ["barrel", "post"])
    assert how.startswith("regenerated: body barrel is in the included file")
    reread = read_scene(source, data)
    assert reread.names == minimal.names and reread != minimal  # MuJoCo's writer rounds: 0.5235986 for 30 degrees
    assert reread.model("crate").pose.yaw == pytest.approx(minimal.model("crate").pose.yaw, abs=1e-6)
    assert b"<include" not in data  # MuJoCo's own writer spliced the included file in


def test_ddenv_check_names_the_models_and_what_is_not_simulated(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", str(CORPUS / "not_simulated.xml")]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == f"{CORPUS / 'not_simulated.xml'}: 3 models (3 reducible)"
    assert out[1:4] == [
        "not simulated: joints: arm_base (1 joint), slider (1 joint); each articulated body tree is simulated as one "
        "rigid body",
        "not simulated: actuators: shoulder_motor, rail_drive; the scene's actuators are not driven (the robot comes "
        "from the scenario)",
        "not simulated: sensors: shoulder_angle, tip_touch; sensors in the scene do not run (the robot's come from "
        "the scenario)"]


def test_world_load_reads_mjcf_by_its_suffix(tmp_path: Path) -> None:
    copy = tmp_path / "scene.mjcf"
    copy.write_bytes((CORPUS / "wall_in_the_way.xml").read_bytes())
    assert World.load(copy).names == ("crate_left", "wall", "crate_right", "post")
