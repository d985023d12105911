"""Issue 28, the SDF part: what the SDF reader accepted silently and the YAML reader refuses, and the bounds
that hold by construction.

* The `ddenv:` elements are read as strictly as the YAML world's `scenario:` block: a start or goal without
  its x or y (a goal read as x = 0 sat on the start: `ddenv run` said "reached the goal at t = 0.00 s"), an
  unknown attribute or element, a second goal or a second scenario are errors naming file:line and field.
* A second `<world>`, a `<state>` insertion of a model the world already has, a `<physics>` step that is not
  a positive number: errors, not ignored.
* An include tree of bounded depth but wide (8 includes per level) is refused by its total number of
  includes and of models, before it is read whole.
"""

from __future__ import annotations

import json
import resource
from pathlib import Path

import pytest

from pytest_ddenv.cli import main as cli
from pytest_ddenv import sdf
from pytest_ddenv.errors import ScenarioError, WorldError
from pytest_ddenv.sdf import load_sdf, parse_sdf

NS = f'xmlns:ddenv="{sdf.DDENV_NS}"'
BOX = '<collision name="c"><geometry><box><size>1 1 1</size></box></geometry></collision>'
WALL = f'<model name="wall"><static>true</static><pose>3 0 0.5 0 0 0</pose><link name="l">{BOX}</link></model>'


@pytest.fixture(autouse=True)
def no_model_path_from_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    for variable in sdf.MODEL_PATH_VARIABLES:
        monkeypatch.delenv(variable, raising=False)


def scenario_world(scenario: str, more: str = "") -> str:
    return (f'<sdf version="1.7" {NS}>\n<world name="w"><include><uri>model://ground_plane</uri></include>\n'
            f"{scenario}\n{more}{WALL}\n</world>\n</sdf>\n")


def scenario(start: str = 'x="0" y="0"', goal: str = 'x="6" y="0"', attributes: str = 'timeout="10"',
             inside: str = "") -> str:
    return (f'<ddenv:scenario robot="husky" {attributes}>\n<ddenv:start {start}/>\n<ddenv:goal {goal}/>\n{inside}'
            "</ddenv:scenario>")


# -- 1. the ddenv:scenario is read as strictly as YAML's scenario ------------------------------------------------
@pytest.mark.parametrize(
    ("text", "field", "line", "message"),
    ids=["goal-without-x", "goal-without-y", "start-without-x", "start-without-y", "goal-typo", "start-typo",
         "scenario-typo", "second-goal", "second-start", "second-scenario", "unknown-child"],
    argvalues=[
        (scenario_world(scenario(goal='y="0"')), "ddenv:goal/@x", 5, "missing; give the goal as x=\"..\" y=\"..\""),
        (scenario_world(scenario(goal='x="6"')), "ddenv:goal/@y", 5, "missing"),
        (scenario_world(scenario(start='y="0"')), "ddenv:start/@x", 4, "missing"),
        (scenario_world(scenario(start='x="0" yaw="1"')), "ddenv:start/@y", 4, "missing"),
        (scenario_world(scenario(goal='x="6" y="0" tolerance="1"')), "ddenv:goal/@tolerance", 5,
         "unknown attribute 'tolerance'; expected one of: x, y, z"),
        (scenario_world(scenario(start='x="0" y="0" theta="1"')), "ddenv:start/@theta", 4,
         "unknown attribute 'theta'; expected one of: x, y, z, yaw"),
        (scenario_world(scenario(attributes='timeout="10" time_out="20"')), "ddenv:scenario/@time_out", 3,
         "unknown attribute 'time_out'; expected one of: robot, timeout, goal_tolerance"),
        (scenario_world(scenario(inside='<ddenv:goal x="9" y="9"/>\n')), "ddenv:goal", 6,
         "a second ddenv:goal (the first is at line 5); a scenario has one"),
        (scenario_world(scenario(inside='<ddenv:start x="9" y="9"/>\n')), "ddenv:start", 6,
         "a second ddenv:start (the first is at line 4); a scenario has one"),
        (scenario_world(scenario(), scenario(goal='x="1" y="1"') + "\n"), "ddenv:scenario", 7,
         "a second ddenv:scenario (the first is at line 3); a world has one"),
        (scenario_world(scenario(inside='<ddenv:waypoint x="2" y="2"/>\n')), "ddenv:waypoint", 6,
         "unknown element ddenv:waypoint in ddenv:scenario; expected: start, goal, robot_description"),
    ],
)
def test_a_scenario_that_yaml_would_refuse_is_refused_naming_its_line_and_field(
    text: str, field: str, line: int, message: str
) -> None:
    with pytest.raises(ScenarioError) as caught:
        parse_sdf(text, source="yard.world")
    error = caught.value
    assert (error.source, error.line, error.field) == ("yard.world", line, field), str(error)
    assert message in str(error)


@pytest.mark.parametrize(
    ("more", "field", "message"),
    ids=["world-element", "model-element", "physics-attribute", "tag-attribute"],
    argvalues=[
        ('<ddenv:scenaro robot="husky"/>\n', "ddenv:scenaro",
         "unknown element ddenv:scenaro in the world; expected: scenario, physics"),
        ('<model name="crate"><ddenv:kept>true</ddenv:kept><link name="l">' + BOX + "</link></model>\n",
         "ddenv:kept", "unknown element ddenv:kept in model 'crate'; expected: keep, tag"),
        ('<ddenv:physics timestep="0.01" solver_iteration="50"/>\n', "ddenv:physics/@solver_iteration",
         "unknown attribute 'solver_iteration'; expected one of: timestep, solver_iterations"),
        ('<model name="crate"><ddenv:tag name="a" kind="int">1</ddenv:tag><link name="l">' + BOX + "</link></model>\n",
         "ddenv:tag/@kind", "unknown attribute 'kind'; expected one of: name, type"),
    ],
)
def test_other_ddenv_typos_are_refused(more: str, field: str, message: str) -> None:
    with pytest.raises(WorldError) as caught:
        parse_sdf(scenario_world(scenario(), more), source="yard.world")
    assert caught.value.field == field and caught.value.line == 7 and message in str(caught.value), str(caught.value)


def test_the_written_scenario_still_reads_back() -> None:
    text = scenario_world(scenario(start='x="-1" y="0.5" z="0.1" yaw="0.25"', goal='x="7" y="0" z="0.2"',
                                   attributes='timeout="12" goal_tolerance="0.4"'))
    world = parse_sdf(text, source="yard.world")
    assert world.scenario is not None and world.scenario.goal == (7.0, 0.0, 0.2)
    assert (world.scenario.start.x, world.scenario.start.z, world.scenario.timeout) == (-1.0, 0.1, 12.0)


def test_ddenv_run_of_a_goal_without_x_is_an_error_not_a_goal_reached_at_the_start(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "yard.world").write_text(scenario_world(scenario(goal='y="0"')))
    monkeypatch.chdir(tmp_path)
    code = cli.main(["run", "yard.world", "--no-picture"])
    err = capsys.readouterr().err
    assert code == cli.EXIT_USAGE, err
    assert err.strip() == ("ddenv: error: yard.world:5, field 'ddenv:goal/@x': missing; give the goal as "
                           'x=".." y=".." (and z=".." for a 3D goal)')


# -- 8. what was ignored ------------------------------------------------------------------------------------------
def test_a_second_world_is_an_error() -> None:
    text = ('<sdf version="1.7">\n<world name="a">' + WALL + '</world>\n<world name="b">' + WALL
            + "</world>\n</sdf>\n")
    with pytest.raises(WorldError) as caught:
        parse_sdf(text, source="two.world")
    assert (caught.value.line, caught.value.field) == (3, "world")
    assert "a second <world> ('b'; the first, 'a', is at line 2)" in str(caught.value)


def test_a_state_insertion_of_a_model_the_world_has_is_an_error() -> None:
    insertion = '<model name="wall"><static>true</static><link name="l">' + BOX + "</link></model>"
    text = (f'<sdf version="1.7">\n<world name="w">\n{WALL}\n<state world_name="w">\n<insertions>\n{insertion}\n'
            "</insertions>\n</state>\n</world>\n</sdf>\n")
    with pytest.raises(WorldError) as caught:
        parse_sdf(text, source="saved.world")
    assert (caught.value.line, caught.value.model, caught.value.field) == (6, "wall", "state/insertions/model")
    assert "the world already has a model 'wall' (line 3)" in str(caught.value)


def test_a_state_insertion_of_a_new_model_is_noted() -> None:
    insertion = '<model name="crate"><static>true</static><link name="l">' + BOX + "</link></model>"
    text = (f'<sdf version="1.7"><world name="w">{WALL}<state world_name="w"><insertions>{insertion}</insertions>'
            "</state></world></sdf>")
    world = parse_sdf(text, source="saved.world")
    assert world.names == ("wall",)
    assert any(note.startswith("<state> insertions: crate; ") for note in world.notes), world.notes


@pytest.mark.parametrize("step", ["-1", "0", "nan", "fast"])
def test_a_physics_step_that_is_not_a_positive_number_is_an_error(step: str) -> None:
    text = (f'<sdf version="1.7">\n<world name="w">\n<physics name="p" type="ode">\n<max_step_size>{step}'
            f"</max_step_size>\n</physics>\n{WALL}</world></sdf>")
    with pytest.raises(WorldError) as caught:
        parse_sdf(text, source="fast.world")
    assert (caught.value.line, caught.value.field) == (4, "physics/max_step_size"), str(caught.value)


# -- 4. includes and models bounded in total, not only in depth -------------------------------------------------------
def wide_include_tree(folder: Path, fanout: int, depth: int) -> Path:
    """level_0 includes `fanout` copies of level_1, ... level_{depth-1} holds one box: fanout**depth models."""
    for level in range(depth):
        body = (f'<link name="l">{BOX}</link>' if level == depth - 1 else "".join(
            f"<include><name>c{i}</name><uri>model://level_{level + 1}</uri></include>" for i in range(fanout)))
        (folder / f"level_{level}").mkdir()
        (folder / f"level_{level}" / "model.sdf").write_text(
            f'<sdf version="1.7"><model name="level_{level}"><static>true</static>{body}</model></sdf>')
    world = folder / "wide.world"
    tops = "".join(f"<include><name>top{i}</name><uri>model://level_0</uri></include>" for i in range(fanout))
    world.write_text(f'<sdf version="1.7"><world name="w">{tops}</world></sdf>')
    return world


def test_an_include_tree_eight_wide_is_refused_by_its_total_within_seconds(tmp_path: Path) -> None:
    world = wide_include_tree(tmp_path, 8, 8)  # 8**9 includes; was past 300 s
    before = resource.getrusage(resource.RUSAGE_SELF).ru_utime
    with pytest.raises(WorldError) as caught:
        load_sdf(world, model_paths=[tmp_path])
    used = resource.getrusage(resource.RUSAGE_SELF).ru_utime - before
    assert f"more than {sdf.MAX_INCLUDES} <include>s in one world" in str(caught.value)
    assert caught.value.field == "include"
    assert used < 10, f"{used:.1f} s of CPU to refuse it"  # CPU time, not wall time: a bound of the work done


def test_a_world_of_more_models_than_the_bound_is_refused(tmp_path: Path) -> None:
    models = "".join(f'<model name="m{i}"><static>true</static><link name="l">{BOX}</link></model>\n'
                     for i in range(sdf.MAX_MODELS + 1))
    with pytest.raises(WorldError) as caught:
        parse_sdf(f'<sdf version="1.7"><world name="w">\n{models}</world></sdf>', source="many.world")
    assert f"more than {sdf.MAX_MODELS} models in one world" in str(caught.value)
    assert caught.value.line == sdf.MAX_MODELS + 2 and caught.value.model == f"m{sdf.MAX_MODELS}"


def test_a_wide_tree_within_the_bounds_loads(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                             monkeypatch: pytest.MonkeyPatch) -> None:
    world = wide_include_tree(tmp_path, 8, 3)  # 8 top-level models of 64 boxes each
    monkeypatch.chdir(tmp_path)
    code = cli.main(["check", str(world), "--model-path", str(tmp_path), "--json"])
    assert code == 0 and json.loads(capsys.readouterr().out)["models"] == 8


@pytest.mark.parametrize(("bound", "part", "field"), [("MAX_LINKS", "links", "link"),
                                                        ("MAX_COLLISIONS", "collisions", "link 'l'/collision")])
def test_links_and_collisions_are_bounded_too(monkeypatch: pytest.MonkeyPatch, bound: str, part: str,
                                              field: str) -> None:
    """A 32 MB file of one model holds about 230 000 links (or 300 000 collisions of one link): read in 5 s of
    CPU before the bound; refused at the 50 000th (the bound here made 100 to keep the test short)."""
    module = sdf._tree if part == "links" else sdf._bodies
    monkeypatch.setattr(module, bound, 100)
    inside = ("".join(f'<link name="l{i}">{BOX}</link>' for i in range(101)) if part == "links" else
              '<link name="l">' + "".join(BOX.replace('"c"', f'"c{i}"') for i in range(101)) + "</link>")
    with pytest.raises(WorldError) as caught:
        parse_sdf(f'<sdf version="1.7"><world name="w"><model name="m"><static>1</static>{inside}</model></world></sdf>',
                  source="parts.world")
    assert f"more than 100 {part} in one world" in str(caught.value) and caught.value.field == field
