"""Bad MJCF input: one error naming the file, the line and the field; `ddenv check` exits with 2. Reading is
bounded as the SDF reader's is."""

from __future__ import annotations

from pathlib import Path

import pytest

pytest.importorskip("mujoco", reason='reading MJCF needs mujoco: pip install "pytest-ddenv[mujoco]"')

from pytest_ddenv import mjcf  # noqa: E402
from pytest_ddenv.cli.main import main  # noqa: E402
from pytest_ddenv.errors import ScenarioError, WorldError  # noqa: E402
from pytest_ddenv.world import World  # noqa: E402

CORPUS = Path(__file__).resolve().parents[1] / "data" / "mjcf"

BAD = {  # file: (the file the error names, line, field, what it says)
    "bad_malformed.xml": ("bad_malformed.xml", 5, None, "malformed XML: mismatched tag"),
    "bad_missing_include.xml": ("bad_missing_include.xml", 5, "include/@file", "included file not found"),
    "bad_missing_mesh.xml": ("bad_missing_mesh.xml", 4, "mesh/@file", "mesh file not found: 'boulder.stl'"),
    "bad_scenario_value.xml": ("bad_scenario_value.xml", 6, "custom/text[ddenv:scenario] start",
                               "expected X,Y or X,Y,YAW, got '0,zero'"),
    "bad_scenario_key.xml": ("bad_scenario_key.xml", 6, "custom/text[ddenv:scenario] time_out",
                             "unknown key 'time_out'"),
    "bad_ellipsoid.xml": ("bad_ellipsoid.xml", 4, "geom/@type", "unsupported geom type ellipsoid"),
    "bad_no_geom.xml": ("bad_no_geom.xml", 4, "body/geom", "the body has no geom"),
    "bad_no_body.xml": ("bad_no_body.xml", 2, "worldbody", "the scene has no body"),
    "bad_unnamed_body.xml": ("bad_unnamed_body.xml", 4, "body/@name", "a top-level body needs a name"),
    "bad_attribute.xml": ("bad_attribute.xml", 4, "geom", "MuJoCo says: bad format in attribute 'size'"),
    "bad_unknown_element.xml": ("bad_unknown_element.xml", 5, "bx", "MuJoCo says: Schema violation"),
    "bad_doctype.xml": ("bad_doctype.xml", 2, None, "document type declarations (<!DOCTYPE>) are not allowed"),
    "bad_in_include.xml": ("parts/bad_part.xml", 5, "geom", "MuJoCo says: bad format in attribute 'size'"),
}


def test_every_bad_file_is_in_the_table() -> None:
    assert sorted(BAD) == sorted(path.name for path in CORPUS.glob("bad_*.xml"))


@pytest.mark.parametrize("name", sorted(BAD))
def test_a_bad_file_is_one_error_naming_file_line_and_field(name: str) -> None:
    file, line, field, says = BAD[name]
    with pytest.raises(WorldError) as raised:
        World.load(CORPUS / name)
    error = raised.value
    assert (Path(error.source or "").resolve(), error.line, error.field) == ((CORPUS / file).resolve(), line, field)
    assert says in error.reason
    assert "\n" not in str(error)
    assert f"{file}:{line}" in str(error)
    if name.startswith("bad_scenario"):
        assert isinstance(error, ScenarioError)


@pytest.mark.parametrize("name", sorted(BAD))
def test_ddenv_check_exits_with_2_and_one_line(name: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", str(CORPUS / name)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("ddenv: error: ") and f":{BAD[name][1]}" in err[0]


def test_bodies_nested_too_deep_are_refused_before_mujoco(tmp_path: Path) -> None:
    depth = mjcf.MAX_NESTING + 1
    scene = tmp_path / "deep.xml"
    scene.write_text("<mujoco><worldbody>" + "".join(f'<body name="b{i}"><geom size="0.1"/>' for i in range(depth))
                     + "</body>" * depth + "</worldbody></mujoco>")
    with pytest.raises(WorldError, match=f"bodies nested more than {mjcf.MAX_NESTING} deep") as raised:
        World.load(scene)
    assert raised.value.line == 1 and raised.value.model == f"b{mjcf.MAX_NESTING}"


def test_too_many_bodies_are_refused(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("pytest_ddenv.mjcf._files.MAX_BODIES", 3)
    scene = tmp_path / "many.xml"
    scene.write_text("<mujoco><worldbody>\n" + "".join(f'<body name="b{i}"><geom size="0.1"/></body>\n'
                                                       for i in range(4)) + "</worldbody></mujoco>")
    with pytest.raises(WorldError, match="more than 3 <body> elements") as raised:
        World.load(scene)
    assert raised.value.line == 5


def test_an_include_cycle_is_refused(tmp_path: Path) -> None:
    (tmp_path / "a.xml").write_text('<mujoco><include file="b.xml"/></mujoco>')
    (tmp_path / "b.xml").write_text('<mujoco>\n<include file="a.xml"/></mujoco>')
    with pytest.raises(WorldError, match="included more than once") as raised:
        World.load(tmp_path / "a.xml")
    assert (Path(raised.value.source or "").name, raised.value.line) == ("b.xml", 2)


def test_without_mujoco_the_error_says_what_to_install(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(__import__("sys").modules, "mujoco", None)  # import mujoco raises ImportError
    with pytest.raises(WorldError, match=r'needs MuJoCo: pip install "pytest-ddenv\[mujoco\]"'):
        World.load(CORPUS / "wall_in_the_way.xml")


@pytest.mark.parametrize("command", ["run", "reduce"])
def test_ddenv_run_and_reduce_exit_with_2_on_a_bad_scene(command: str, tmp_path: Path,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    assert main([command, str(CORPUS / "bad_missing_mesh.xml"), "--start", "0,0", "--goal", "1,0",
                 *(["-p", "stuck", "--out", str(tmp_path)] if command == "reduce" else [])]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"ddenv: error: {CORPUS / 'bad_missing_mesh.xml'}:4, field 'mesh/@file': mesh file not found: "
                   f"'boulder.stl' (looked for {CORPUS / 'assets' / 'boulder.stl'}; MuJoCo reads it from the "
                   "compiler's meshdir or assetdir, relative to the main file's folder)"]


def test_ddenv_convert_reads_a_scene_and_refuses_to_write_mjcf(tmp_path: Path,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    scene = CORPUS / "wall_in_the_way.xml"
    assert main(["convert", str(scene), str(tmp_path / "scene.yaml")]) == 0
    assert World.load(tmp_path / "scene.yaml").names == World.load(scene).names
    assert main(["convert", str(tmp_path / "scene.yaml"), str(tmp_path / "back.xml")]) == 2
    assert "unknown output format '.xml'" in capsys.readouterr().err


def test_a_file_over_the_size_limit_is_refused_unread(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("pytest_ddenv.sdf._xml.MAX_FILE_BYTES", 100)
    scene = tmp_path / "big.xml"
    scene.write_text("<mujoco><worldbody>" + "<!-- padding -->" * 10 + "</worldbody></mujoco>")
    with pytest.raises(WorldError) as raised:
        World.load(scene)
    assert "100" in str(raised.value) and raised.value.source == str(scene)
