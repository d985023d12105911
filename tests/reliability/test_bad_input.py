"""Every row of the bad-input table in docs/reliability.md, checked: the input is made, given to its interface
(`ddenv`, `pytest` with an option, an ini file or a marker, the Python API), and the message the table shows
must be what is printed, on one line; `ddenv` exits 2 for it and prints it in its `--json` object too.

The table is read from the page: a row's first cell is its id, a key of `CASES` below. In a message, `…`
stands for a part that changes from machine to machine (a temporary folder, the libyaml version's field).
"""

from __future__ import annotations

import json
import os
import random
import re
import subprocess
import sys
import textwrap
import tracemalloc
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from pytest_ddenv import World, WorldError
from pytest_ddenv.cli import main as cli

ROOT = Path(__file__).resolve().parents[2]
PAGE = ROOT / "docs" / "reliability.md"

# -- the inputs --------------------------------------------------------------------------------------------
HEAD = "format: 1\nname: yard\n"
SCENARIO = "scenario: {start: {x: 0, y: 0}, goal: {x: 4, y: 0}, timeout: 20}\n"
WALL = "  - {name: wall, pose: [2, 0, 0.5], box: [0.3, 4, 1]}\n"
YARD = HEAD + SCENARIO + "models:\n" + WALL + "  - {name: crate, pose: [-3, 3, 0.25], box: [0.5, 0.5, 0.5]}\n"
PASSWD = "".join(f"{user}:x:{uid}:{uid}:{user}:/home/{user}:/usr/sbin/nologin\n"
                 for uid, user in enumerate(["root", "daemon", "bin", "sys", "sync", "games", "man", "lp"]))
BOMB = "format: 1\n" + "".join(
    f"{name}: &{name} [{', '.join([f'*{previous}'] * 9)}]\n" if previous else f'{name}: &{name} ["lol"]\n'
    for previous, name in zip(["", *"abcdefgh"], "abcdefghi")
) + "models: *i\n"
SDF = "<sdf version='1.7'><world name='yard'>{}</world></sdf>\n"
BOX_LINK = "<link name='l'><collision name='c'><geometry><box><size>1 1 1</size></box></geometry></collision></link>"
SDF_MESH = ("<model name='crate'><static>true</static><link name='l'><collision name='c'><geometry><mesh>"
            "<uri>crate.stl</uri></mesh></geometry></collision></link></model>")
XML_BOMB = ('<?xml version="1.0"?>\n<!DOCTYPE lolz [\n <!ENTITY lol "lol">\n'
            ' <!ENTITY lol2 "&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;">\n]>\n'
            "<sdf version='1.7'><world name='w'>&lol2;</world></sdf>\n")
GARBAGE = random.Random(16).randbytes(3000)
TEST_MODULE = """\
import pytest

@pytest.mark.ddenv(world="{world}"{ddenv})
@pytest.mark.robot_failure("stuck", window=2.0, min_progress=0.2){failure}
def test_robot(robot_world):
    assert robot_world.run().reached_goal
"""
QUICK_DASK = """\
import pytest_ddenv.execution.factory as factory

class QuickCluster(factory.DaskCluster):  # a real connection attempt that gives up after 1 s, not 30 s
    def __init__(self, address=None, **options):
        super().__init__(address, **{**options, "connect_timeout": 1.0})

factory.DaskCluster = QuickCluster  # the cluster the session opens (execution.make_cluster)
"""


def _robot_test(world: str = "yard.yaml", ddenv: str = "", failure: str = "") -> str:
    return TEST_MODULE.format(world=world, ddenv=ddenv, failure=failure)


def _sparse(size: int) -> Callable[[Path], None]:
    def make(path: Path) -> None:
        with path.open("wb") as handle:
            handle.write(b"format: 1\n")
            handle.truncate(size)

    return make


def _read_only(path: Path) -> None:
    path.mkdir()
    path.chmod(0o500)


@dataclass(frozen=True)
class Case:
    """An input and the command that reads it: `ddenv ...` (in-process, exit code 2 unless `code`),
    `pytest ...` (in a subprocess, exit code `code`) or `python CODE` (see `python`). `files`: text, bytes, or a
    function making the path."""

    command: tuple[str, ...]
    files: dict[str, str | bytes | Callable[[Path], None]] = field(default_factory=dict)
    code: int = 2
    subprocess: bool = False
    """Run `ddenv` as its own process (inputs that once crashed the interpreter)."""
    also: tuple[str, ...] = ()
    """More text the output must hold (e.g. the test's own failure, kept)."""
    env: dict[str, str] = field(default_factory=dict)
    """Environment variables set for the command."""


def ddenv(*words: str, files: dict[str, str | bytes | Callable[[Path], None]] | None = None, code: int = 2,
          subprocess: bool = False) -> Case:
    return Case(("ddenv", *words), files or {}, code, subprocess)


def check(name: str, content: str | bytes | Callable[[Path], None], **more: str | bytes) -> Case:
    return ddenv("check", name, files={name: content, **more})


def run_pytest(*options: str, files: dict[str, str | bytes | Callable[[Path], None]] | None = None,
               code: int = pytest.ExitCode.USAGE_ERROR, also: tuple[str, ...] = ()) -> Case:
    return Case(("pytest", *options), {"yard.yaml": YARD, "test_robot.py": _robot_test(), **(files or {})}, code,
                also=also)


NESTED_MODELS = SDF.format("".join(f"<model name='m{i}'>" for i in range(5000)) + BOX_LINK + "</model>" * 5000)
FRAME_CHAIN = SDF.format(
    "<model name='m'><frame name='f0'/>"
    + "".join(f"<frame name='f{i}'><pose relative_to='f{i - 1}'>0 0 0 0 0 0</pose></frame>" for i in range(1, 3000))
    + "<link name='l'><pose relative_to='f2999'>0 0 0 0 0 0</pose>"
    + "<collision name='c'><geometry><box><size>1 1 1</size></box></geometry></collision></link></model>"
)
SELF_INCLUDE = "<sdf version='1.7'><model name='loop'><include><uri>loop.sdf</uri></include></model></sdf>\n"
# issue 28, SDF: what was accepted silently, ran unbounded or said too little
DDENV_SDF = SDF.replace("<sdf version='1.7'>",
                        "<sdf version='1.7' xmlns:ddenv='https://github.com/pytest-ddenv/pytest-ddenv/sdf'>")
SDF_WALL = f"<model name='wall'><static>true</static><pose>2 0 0.5 0 0 0</pose>{BOX_LINK}</model>"
GROUND_INCLUDE = "<include><uri>model://ground_plane</uri></include>"
BOX_COLLISION = "<collision name='c'><geometry><box><size>1 1 1</size></box></geometry></collision>"


def _scenario(start: str = "x='0' y='0'", goal: str = "x='4' y='0'", attributes: str = "timeout='20'",
              inside: str = "") -> str:
    return (f"<ddenv:scenario robot='husky' {attributes}><ddenv:start {start}/><ddenv:goal {goal}/>{inside}"
            "</ddenv:scenario>")


def _geometry(geometry: str, name: str = "wall") -> str:
    return (f"<model name='{name}'><static>true</static><link name='l'><collision name='c'><geometry>{geometry}"
            "</geometry></collision></link></model>")


def _wide_includes(path: Path) -> None:
    """8 includes per level, 8 levels: 8**8 models (ran past 300 s)."""
    for level in range(8):
        body = BOX_LINK if level == 7 else "".join(
            f"<include><name>c{i}</name><uri>model://level_{level + 1}</uri></include>" for i in range(8))
        (path.parent / f"level_{level}").mkdir()
        (path.parent / f"level_{level}" / "model.sdf").write_text(
            f"<sdf version='1.7'><model name='level_{level}'><static>true</static>{body}</model></sdf>")
    path.write_text(SDF.format("".join(f"<include><name>top{i}</name><uri>model://level_0</uri></include>"
                                       for i in range(8))))


def _many_models(path: Path) -> None:
    path.write_text("<sdf version='1.7'><world name='yard'>\n" + "".join(
        f"<model name='m{i}'><static>true</static>{BOX_LINK}</model>\n" for i in range(10_001)) + "</world></sdf>\n")


def _many_links(path: Path) -> None:
    path.write_text(SDF.format("<model name='m'><static>true</static>" + "".join(
        f"<link name='l{i}'>{BOX_COLLISION}</link>" for i in range(50_001)) + "</model>"))


SDF_LINK_JOINT = SDF.format(f"<model name='arm'><link name='base'>{BOX_COLLISION}</link><link name='attachment'>"
                            f"{BOX_COLLISION}</link><joint name='attachment' type='fixed'><parent>base</parent>"
                            "<child>attachment</child></joint></model>")

CASES: dict[str, Case] = {
    # YAML world files
    "alias-bomb": check("bomb.yaml", BOMB),
    "recursive-alias": check("loop.yaml", "format: 1\nmodels: &m [*m]\n"),
    "deep-nesting": ddenv("check", "deep.yaml", files={"deep.yaml": "format: 1\nmodels: " + "[" * 100_000
                                                       + "]" * 100_000 + "\n"}, subprocess=True),
    "foreign-text": check("passwd", PASSWD),
    "foreign-yaml": check("compose.yaml", 'version: "3"\nservices:\n  web: {image: nginx}\n'),
    "binary": check("garbage.yaml", GARBAGE),
    "nul": check("nul.yaml", "format: 1\nname: yard\x00\n"),
    "empty": check("empty.yaml", ""),
    "two-documents": check("two.yaml", "format: 1\n---\nformat: 1\n"),
    "duplicate-key": check("dup.yaml", HEAD + "models:\n  - name: crate\n    box: [1, 1, 1]\n    mass: 2\n"
                                              "    static: false\n    mass: 20\n"),
    "duplicate-model": check("twins.yaml", HEAD + "models:\n" + WALL + WALL),
    "exponent": ddenv("check", "e9.yaml", files={"e9.yaml": HEAD + "models:\n  - {name: slab, box: [1e1, 1e1, "
                                                                    "1.5E-1], mass: 1e3, static: false}\n"}, code=0),
    "quoted-number": check("quoted.yaml", HEAD + "models:\n  - {name: crate, box: [1, 1, 1], mass: '2.5'}\n"),
    "number-name": check("named.yaml", HEAD + "models:\n  - {name: 1e5, box: [1, 1, 1]}\n"),
    "solver-iterations": check("physics.yaml", HEAD + "physics: {solver_iterations: 1e12}\n"),
    "timestep": check("physics.yaml", HEAD + "physics: {timestep: 1e-12}\n"),
    "huge-integer": check("huge.yaml", HEAD + "models:\n  - {name: crate, box: [1, 1, 1], mass: " + "9" * 5000 + "}\n"),
    "overflow": check("far.yaml", HEAD + "models:\n  - {name: crate, box: [1, 1, 1], pose: [1e400, 0, 0]}\n"),
    "long-integer": check("far.yaml", HEAD + "models:\n  - {name: crate, box: [1, 1, 1], pose: [1" + "0" * 400
                          + ", 0, 0]}\n"),
    "nan": check("nan.yaml", HEAD + "models:\n  - {name: crate, box: [1, 1, 1], pose: [0, .nan, 0]}\n"),
    "control-name": check("bell.yaml", HEAD + 'models:\n  - {name: "crate\\a", box: [1, 1, 1]}\n'),
    "blank-name": check("blank.yaml", HEAD + 'models:\n  - {name: " crate", box: [1, 1, 1]}\n'),
    "long-name": check("long.yaml", HEAD + "models:\n  - {name: " + "c" * 300 + ", box: [1, 1, 1]}\n"),
    "long-key": check("key.yaml", HEAD + "k" * 1000 + ": 1\n"),
    "python-tag": check("tag.yaml", "format: !!python/object/apply:os.system ['echo hi']\n"),
    "garbage-mesh": check("crate.yaml", HEAD + "models:\n  - {name: crate, mesh: {file: crate.stl}}\n",
                          **{"crate.stl": GARBAGE}),
    "non-mesh": check("crate.yaml", HEAD + "models:\n  - {name: crate, mesh: {file: crate.obj}}\n",
                      **{"crate.obj": PASSWD}),
    "long-file-name": check("crate.yaml", HEAD + "models:\n  - {name: crate, mesh: {file: " + "m" * 300 + ".stl}}\n"),
    "missing-mesh": check("crate.yaml", HEAD + "models:\n  - {name: crate, mesh: {file: crate.stl}}\n"),
    "big-file": check("big.yaml", _sparse(60 * 1024 * 1024)),
    "folder": ddenv("check", "worlds", files={"worlds/yard.yaml": YARD}),
    "device": ddenv("check", "/dev/zero"),
    # SDF world files
    "sdf-nesting": check("nested.world", NESTED_MODELS),
    "sdf-frame-chain": check("chain.world", FRAME_CHAIN),
    "sdf-control-name": check("bell.world", SDF.format(f"<model name='crate&#9;1'>{BOX_LINK}</model>")),
    "sdf-entity-bomb": check("lol.world", XML_BOMB),
    "sdf-binary": check("garbage.world", GARBAGE),
    "sdf-foreign": check("passwd.world", PASSWD),
    "sdf-solver-iterations": check("physics.world", SDF.replace("<sdf version='1.7'>", (
        "<sdf version='1.7' xmlns:ddenv='https://github.com/pytest-ddenv/pytest-ddenv/sdf'>")).format(
        "<ddenv:physics solver_iterations='1e12'/>")),
    "sdf-garbage-mesh": check("crate.world", SDF.format(SDF_MESH), **{"crate.stl": GARBAGE}),
    "sdf-include-cycle": check("yard.world", SDF.format("<include><uri>loop.sdf</uri></include>"),
                               **{"loop.sdf": SELF_INCLUDE}),
    "sdf-infinite": check("far.world", SDF.format(f"<model name='m'><pose>1e400 0 0 0 0 0</pose>{BOX_LINK}</model>")),
    "sdf-goal-without-x": ddenv("run", "goal.world", "--no-picture", files={"goal.world": DDENV_SDF.format(
        GROUND_INCLUDE + _scenario(goal="y='0'") + SDF_WALL)}),
    "sdf-start-without-y": ddenv("run", "start.world", "--no-picture", files={"start.world": DDENV_SDF.format(
        GROUND_INCLUDE + _scenario(start="x='0' yaw='0'") + SDF_WALL)}),
    "sdf-scenario-attribute": check("typo.world", DDENV_SDF.format(_scenario(attributes="timeout='20' time_out='60'")
                                                                   + SDF_WALL)),
    "sdf-start-attribute": check("typo.world", DDENV_SDF.format(_scenario(start="x='0' y='0' theta='1.57'") + SDF_WALL)),
    "sdf-second-goal": check("goals.world", DDENV_SDF.format(_scenario(inside="<ddenv:goal x='8' y='0'/>") + SDF_WALL)),
    "sdf-second-scenario": check("two.world", DDENV_SDF.format(_scenario() + _scenario(goal="x='9' y='9'") + SDF_WALL)),
    "sdf-ddenv-element": check("typo.world", DDENV_SDF.format("<ddenv:scenaro robot='husky'/>" + SDF_WALL)),
    "sdf-ddenv-physics": check("typo.world", DDENV_SDF.format("<ddenv:physics timestep='0.01' solver_iteration='50'/>"
                                                              + SDF_WALL)),
    "sdf-keep-twice": check("keep.world", DDENV_SDF.format(
        f"<model name='wall'><ddenv:keep>true</ddenv:keep><ddenv:keep>false</ddenv:keep>{BOX_LINK}</model>")),
    "sdf-goal-nan": check("nan.world", DDENV_SDF.format(_scenario(goal="x='nan' y='0'") + SDF_WALL)),
    "sdf-second-world": check("two.world", f"<sdf version='1.7'><world name='a'>{SDF_WALL}</world><world name='b'>"
                                           f"{SDF_WALL}</world></sdf>\n"),
    "sdf-state-insertion": check("saved.world", SDF.format(f"{SDF_WALL}<state world_name='yard'><insertions>{SDF_WALL}"
                                                           "</insertions></state>")),
    "sdf-max-step-size": check("step.world", SDF.format("<physics name='p' type='ode'><max_step_size>-1</max_step_size>"
                                                        f"</physics>{SDF_WALL}")),
    "sdf-state-scale": check("scale.world", SDF.format(f"{SDF_WALL}<state world_name='yard'><model name='wall'>"
                                                       "<scale>0 1 1</scale></model></state>")),
    "sdf-include-breadth": ddenv("check", "wide.world", "--model-path", ".", files={"wide.world": _wide_includes}),
    "sdf-many-models": check("many.world", _many_models),
    "sdf-many-links": check("links.world", _many_links),
    "sdf-misspelt-geometry": check("typo.world", SDF.format(_geometry("<bx><size>0.2 4 1</size></bx>"))),
    "sdf-two-geometries": check("two.world", SDF.format(_geometry("<box><size>1 1 1</size></box><sphere><radius>1"
                                                                  "</radius></sphere>"))),
    "sdf-cone-radius": check("cone.world", SDF.format(_geometry("<cone><radius>-1</radius></cone>", "cone"))),
    "sdf-cone-length": check("cone.world", SDF.format(_geometry("<cone><length>tall</length></cone>", "cone"))),
    "sdf-fuel-missing": check("fuel.world", SDF.format("<include><uri>https://fuel.gazebosim.org/1.0/o/models/x</uri>"
                                                       "</include>")),
    "sdf-remote-not-fuel": check("remote.world", SDF.format("<include><uri>https://example.com/crate.sdf</uri>"
                                                            "</include>")),
    "sdf-link-joint-1-7": check("arm.world", SDF_LINK_JOINT),
    "cli-start-negative": ddenv("run", "yard.world", "--start", "-5,x", "--goal", "1,1",
                                files={"yard.world": SDF.format(GROUND_INCLUDE + SDF_WALL)}),
    # ddenv options
    "cli-collided-unknown": ddenv("run", "yard.yaml", "-p", "collided:models=[wal]", files={"yard.yaml": YARD}),
    "cli-out-file": ddenv("reduce", "yard.yaml", "-p", "stuck", "--out", "notes.txt",
                          files={"yard.yaml": YARD, "notes.txt": "taken"}),
    "cli-max-time": ddenv("reduce", "yard.yaml", "-p", "stuck", "--max-time", "nan", files={"yard.yaml": YARD}),
    "cli-probe-timeout": ddenv("reduce", "yard.yaml", "-p", "stuck", "--probe-timeout", "0",
                               files={"yard.yaml": YARD}),
    "cli-executor": ddenv("reduce", "yard.yaml", "-p", "stuck", "--executor", "tcp://scheduler",
                          files={"yard.yaml": YARD}),
    "cli-stages": ddenv("reduce", "yard.yaml", "-p", "stuck", "--stages", "everything", files={"yard.yaml": YARD}),
    "cli-start": ddenv("run", "yard.yaml", "--start", "1,nan", files={"yard.yaml": YARD}),
    "cli-keep": ddenv("reduce", "yard.yaml", "-p", "stuck", "--keep", "wal", files={"yard.yaml": YARD}),
    "cli-model-path": ddenv("check", "yard.yaml", "--model-path", "models", files={"yard.yaml": YARD}),
    "cli-deflake": ddenv("reduce", "yard.yaml", "-p", "stuck", "--deflake", "1000000000000",
                         files={"yard.yaml": YARD}),
    "cli-predicate": ddenv("run", "yard.yaml", "-p", "wobbly", files={"yard.yaml": YARD}),
    # pytest options and ini settings
    "max-time-nan": run_pytest("--ddenv-max-time", "nan"),
    "probe-timeout-word": run_pytest("--ddenv-probe-timeout", "soon"),
    "stages-word": run_pytest("--ddenv-stages", "models,shape"),
    "max-time-inf": run_pytest("--ddenv-max-time", "inf"),
    "max-time-negative": run_pytest("--ddenv-max-time=-5"),
    "ini-bool": run_pytest(files={"pytest.ini": "[pytest]\nddenv_reduce = maybe\n"}),
    "ini-number": run_pytest(files={"pytest.ini": "[pytest]\nddenv_max_probes = zero\n"}),
    "executor-form": run_pytest("--ddenv-executor", "tcp://scheduler"),
    "executor-unreachable": run_pytest("--ddenv-reduce", "--ddenv-executor", "tcp://127.0.0.1:9",
                                       files={"conftest.py": QUICK_DASK}, code=pytest.ExitCode.TESTS_FAILED,
                                       also=("RobotFailure: The 'stuck' predicate fired",)),
    "artifacts-file": run_pytest("--ddenv-artifacts", "notes.txt", files={"notes.txt": "taken"}),
    "artifacts-read-only": run_pytest("--ddenv-reduce", "--ddenv-artifacts", "locked/out",
                                      files={"locked": _read_only}),
    "deflake": run_pytest("--ddenv-deflake", "many"),
    "deflake-huge": run_pytest(files={"test_robot.py": _robot_test(ddenv=", deflake=10**12")}),
    # markers
    "marker-world-field": run_pytest(files={"yard.yaml": YARD.replace("box: [0.3, 4, 1]", "box: [0.3, 4, 1], "
                                                                                          "mass: heavy")},
                                     code=pytest.ExitCode.TESTS_FAILED),
    "marker-world-missing": run_pytest(files={"test_robot.py": _robot_test(world="yrad.yaml")},
                                       code=pytest.ExitCode.TESTS_FAILED),
    "marker-collided-unknown": run_pytest(files={"test_robot.py": _robot_test(
        failure="\n@pytest.mark.robot_failure('collided', models=['wal'])")}, code=pytest.ExitCode.TESTS_FAILED),
    "marker-keep-unknown": run_pytest(files={"test_robot.py": _robot_test(ddenv=", keep=['wal']")},
                                      code=pytest.ExitCode.TESTS_FAILED),
    "marker-tolerance": run_pytest(files={"test_robot.py": _robot_test(ddenv=", tolerance=float('inf')")}),
    "marker-predicate": run_pytest(files={"test_robot.py": _robot_test(failure="\n@pytest.mark.robot_failure("
                                                                                "'stuck', window=float('nan'))")}),
}


# -- issue 28: world files, values and the Python API ---------------------------------------------------------
def _fifo(path: Path) -> None:
    os.mkfifo(path)


def _link_to(target: str) -> Callable[[Path], None]:
    """A symbolic link to `target` (itself: a loop; a missing file: a dangling link)."""
    return lambda path: path.symlink_to(target)


def _png(width: int, height: int) -> Callable[[Path], None]:
    def make(path: Path) -> None:
        from PIL import Image

        Image.new("L", (width, height), 40).save(path)

    return make


def _png_header(width: int, height: int) -> bytes:
    """A PNG that says it has `width` x `height` pixels and holds none (a decompression bomb's header)."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return len(data).to_bytes(4, "big") + kind + data + zlib.crc32(kind + data).to_bytes(4, "big")

    header = width.to_bytes(4, "big") + height.to_bytes(4, "big") + bytes([8, 0, 0, 0, 0])
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IEND", b"")


def _models(*lines: str) -> str:
    return HEAD + "models:\n" + "".join(f"  - {line}\n" for line in lines)


def _robot(urdf: str) -> str:
    return HEAD + ("scenario:\n  robot: {urdf: " + urdf + ", left_wheels: [l], right_wheels: [r]}\n"
                   "  start: {x: 0, y: 0}\n  goal: {x: 4, y: 0}\n  timeout: 20\n")


def python(code: str, files: dict[str, str | bytes | Callable[[Path], None]] | None = None) -> Case:
    """Python code run in a folder holding `files` (yard.yaml by default), with `from pytest_ddenv import *` and
    `world = World.load('yard.yaml')`: it must raise the table's error (`Type: message`)."""
    return Case(("python", code), {"yard.yaml": YARD, **(files or {})})


NAN_STL = "solid t\nfacet normal 0 0 1\nouter loop\nvertex nan 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid t\n"
BOX = "Shape('box', size=(1, 1, 1))"
WORLD_MODEL_CASES: dict[str, Case] = {
    # world files that are not regular files
    "fifo-world": ddenv("check", "yard.yaml", files={"yard.yaml": _fifo}, subprocess=True),
    "loop-world": check("loop.yaml", _link_to("loop.yaml")),
    "dangling-world": check("gone.yaml", _link_to("moved.yaml")),
    "newline-name": check("bad\n.yaml", YARD.replace("box: [0.3, 4, 1]", "box: [0.3, 4, 1], mass: heavy")),
    # YAML values
    "models-mapping": check("m.yaml", HEAD + "models: {}\n"),
    "models-empty-text": check("m.yaml", HEAD + "models: ''\n"),
    "models-zero": check("m.yaml", HEAD + "models: 0\n"),
    "models-false": check("m.yaml", HEAD + "models: false\n"),
    "base-60": check("slow.yaml", _models("{name: crate, box: [1, 1, 1], mass: 1" + ":0" * 1_000_000 + "}")),
    "base-60-tag": check("tag.yaml", _models("{name: crate, box: [1, 1, 1], mass: !!int 1:30}")),
    "float-tag": check("tag.yaml", _models("{name: crate, box: [1, 1, 1], mass: !!float abc}")),
    "int-tag": check("tag.yaml", _models("{name: crate, box: [1, 1, 1], mass: !!int abc}")),
    "bool-tag": check("tag.yaml", _models("{name: crate, box: [1, 1, 1], keep: !!bool maybe}")),
    "timestamp-tag": check("tag.yaml", HEAD.replace("name: yard", "name: !!timestamp noon")),
    "huge-box": check("huge.yaml", _models("{name: crate, box: [1e39, 1e39, 1]}")),
    "huge-radius": check("huge.yaml", _models("{name: drum, cylinder: {radius: 1e38, length: 1}}")),
    "far-pose": check("far.yaml", _models("{name: crate, pose: [1e20, 0, 0], box: [1, 1, 1]}")),
    "far-goal": check("far.yaml", HEAD + SCENARIO.replace("x: 4", "x: 1e20")),
    "far-polyline": check("far.yaml", _models("{name: curb, polyline: {points: [[0, 0], [1e20, 0], [0, 1]], height: 1}}")),
    "huge-mesh-scale": check("crate.yaml", _models("{name: crate, mesh: {file: crate.stl, scale: 1e39}}"),
                             **{"crate.stl": NAN_STL.replace("nan", "0.5")}),
    "gravity-overflow": check("g.yaml", HEAD + "physics: {gravity: [0, 0, -1e300]}\n"),
    "gravity-strong": check("g.yaml", HEAD + "physics: {gravity: [0, 0, -1e4]}\n"),
    "sdf-far-pose": check("far.world", SDF.format(f"<model name='m'><pose>1e20 0 0 0 0 0</pose>{BOX_LINK}</model>")),
    # meshes, heightmaps and URDFs
    "mesh-folder": check("crate.yaml", _models("{name: crate, mesh: {file: crate.stl}}"),
                         **{"crate.stl/part.stl": "solid"}),
    "mesh-fifo": check("crate.yaml", _models("{name: crate, mesh: {file: crate.stl}}"), **{"crate.stl": _fifo}),
    "mesh-device": check("crate.yaml", _models("{name: crate, mesh: {file: /dev/zero}}")),
    "mesh-loop": check("crate.yaml", _models("{name: crate, mesh: {file: crate.stl}}"),
                       **{"crate.stl": _link_to("crate.stl")}),
    "mesh-nan": check("crate.yaml", _models("{name: crate, mesh: {file: crate.stl}}"), **{"crate.stl": NAN_STL}),
    "heightmap-big": check("hill.yaml", _models("{name: hill, heightmap: {file: hill.png, size: [20, 20, 1]}}"),
                           **{"hill.png": _png(1500, 1500)}),
    "heightmap-bomb": check("hill.yaml", _models("{name: hill, heightmap: {file: hill.png, size: [20, 20, 1]}}"),
                            **{"hill.png": _png_header(20_000, 20_000)}),
    "heightmap-folder": check("hill.yaml", _models("{name: hill, heightmap: {file: hill.png, size: [20, 20, 1]}}"),
                              **{"hill.png/x.png": "x"}),
    "heightmap-fifo": check("hill.yaml", _models("{name: hill, heightmap: {file: hill.png, size: [20, 20, 1]}}"),
                            **{"hill.png": _fifo}),
    "urdf-folder": check("robot.yaml", _robot("robot"), **{"robot/robot.urdf": "<robot/>"}),
    "urdf-fifo": check("robot.yaml", _robot("robot.urdf"), **{"robot.urdf": _fifo}),
    "urdf-device": check("robot.yaml", _robot("/dev/zero")),
    # ddenv convert and run
    "convert-folder": ddenv("convert", "yard.yaml", "out.sdf", files={"yard.yaml": YARD, "out.sdf/keep": "x"}),
    "convert-no-folder": ddenv("convert", "yard.yaml", "new/yard.sdf", files={"yard.yaml": YARD}),
    "convert-loop": ddenv("convert", "loop.yaml", "yard.sdf", files={"loop.yaml": _link_to("loop.yaml")}),
    "scenario-folder": ddenv("run", "yard.yaml", "--scenario", "scenarios", files={"yard.yaml": YARD,
                                                                                   "scenarios/a.yaml": YARD}),
    # the Python API
    "api-robotworld-path": python("RobotWorld('yard.yaml')"),
    "api-robotworld-none": python("RobotWorld(None)"),
    "api-rebound-path": python("RobotWorld(world).rebound('yard.yaml')"),
    "api-run-settings": python("RobotWorld(world).run(settings='fast')"),
    "api-seed-text": python("RobotWorld(world, seed='1')"),
    "api-attempt-negative": python("RobotWorld(world, attempt=-1).run()"),
    "api-load-number": python("World.load(42)"),
    "api-from-yaml-none": python("World.from_yaml(None)"),
    "api-models-text": python("World(models='crate')"),
    "api-save-extension": python("world.save('yard.txt')"),
    "api-save-negative-box": python(f"World(models=(Model('crate', (Shape('box', size=(-1, 1, 1)),)),)).save('c.yaml')"),
    "api-save-nan-pose": python(f"World(models=(Model('crate', ({BOX},), Pose(x=float('nan'))),)).save('c.yaml')"),
    "api-save-shape-kind": python("World(models=(Model('crate', (Shape('cube', size=(1, 1, 1)),)),)).save('c.yaml')"),
    "api-huge-gravity": python("RobotWorld(World(physics=Physics(gravity=(0, 0, -1e300))))"),
    "api-distances-nan": python("world.distances([[float('nan'), 0, 0]])"),
    "api-distances-2d": python("world.distances([[0, 0]])"),
}
CASES.update(WORLD_MODEL_CASES)


# -- issue 28: the process, command-line, plugin and journal interfaces -------------------------------------
def _symlink(target: str) -> Callable[[Path], None]:
    def make(path: Path) -> None:
        path.symlink_to(target)

    return make


def _pipe(path: Path) -> None:
    os.mkfifo(path)


def _deep_json(path: Path) -> None:
    path.write_text("[" * 100_000 + "]" * 100_000 + "\n", encoding="utf-8")


SIGNATURE = {"predicate": "stuck", "time": 6.2, "pose": [1.35, 0.0, 0.15, 0.0, 0.0, 0.0], "touched": ["wall"],
             "detail": ""}
SUMMARY = {"reference_failure": {"exception_type": "RobotFailure", "location": "ddenv", "signature": SIGNATURE},
           "predicates": [{"name": "stuck", "params": {"window": 2.0, "min_progress": 0.2}}], "scenario_seed": 0}
CONTROLLERS = """\
import os

def exits(observation):
    raise SystemExit(0)

def ends(observation):
    os._exit(0)
"""


def _artifacts(**fields: object) -> dict[str, str | bytes | Callable[[Path], None]]:
    """A reduction's artifacts folder `art` (as `ddenv reduce` leaves it) whose summary has these fields."""
    return {"art/minimal.yaml": YARD, "art/summary.json": json.dumps({**SUMMARY, **fields})}


def _with_env(case: Case, **env: str) -> Case:
    return Case(case.command, case.files, case.code, case.subprocess, case.also, env)


REDUCE = ("reduce", "yard.yaml", "-p", "stuck:window=2.0,min_progress=0.2", "--workers", "1", "--media", "none")
PROCESS_CASES: dict[str, Case] = {
    # pytest options, ini settings and environment variables, checked when pytest starts
    "artifacts-proc": run_pytest("--ddenv-artifacts", "/proc/ddenv-out"),
    "artifacts-dangling": run_pytest("--ddenv-artifacts", "out", files={"out": _symlink("nowhere/out")}),
    "artifacts-no-user": run_pytest("--ddenv-artifacts", "~nosuchuser/out"),
    "artifacts-lock-link": run_pytest("--ddenv-reduce", "--ddenv-artifacts", "out",
                                      files={"out/.ddenv.lock": _symlink("../precious.txt"), "precious.txt": "mine"}),
    "ini-artifacts-proc": run_pytest(files={"pytest.ini": "[pytest]\nddenv_artifacts = /proc/ddenv-out\n"}),
    "ini-artifacts-dangling": run_pytest(files={"pytest.ini": "[pytest]\nddenv_artifacts = out\n",
                                                "out": _symlink("nowhere/out")}),
    "model-path-no-user": run_pytest("--ddenv-model-path", "~nosuchuser/models"),
    "world-long-name": run_pytest("--ddenv-world", "w" * 3000),
    "model-path-long-name": run_pytest("--ddenv-model-path", "m" * 3000),
    "probe-timeout-env": _with_env(run_pytest(), DDENV_PROBE_TIMEOUT="soon"),
    "probe-timeout-env-negative": _with_env(run_pytest(), DDENV_PROBE_TIMEOUT="-5"),
    # markers and parameters
    "marker-priority-list": run_pytest(files={"test_robot.py": _robot_test(ddenv=", priority=['x']")}),
    "marker-priority-dict": run_pytest(files={"test_robot.py": _robot_test(ddenv=", priority={'a': 1}")}),
    "marker-stages-long": run_pytest(files={"test_robot.py": _robot_test(ddenv=", stages='s' * 1000")}),
    "marker-world-no-user": run_pytest(files={"test_robot.py": _robot_test(world="~nosuchuser/yard.yaml")},
                                       code=pytest.ExitCode.TESTS_FAILED),
    "param-int": run_pytest(files={"test_robot.py": TEST_MODULE.format(world="yard.yaml", ddenv="", failure=(
        "\n@pytest.mark.parametrize('robot_world', [5], indirect=True)"))}, code=pytest.ExitCode.TESTS_FAILED),
    "marker-collided-empty": run_pytest(files={"test_robot.py": _robot_test(
        failure="\n@pytest.mark.robot_failure('collided', models=[])")}),
    # ddenv options and the user's code
    "cli-predicate-twice": ddenv("run", "yard.yaml", "-p", "stuck:window=2,window=3", files={"yard.yaml": YARD}),
    "cli-collided-empty": ddenv("run", "yard.yaml", "-p", "collided:models=[]", files={"yard.yaml": YARD}),
    "cli-controller-not-callable": ddenv("run", "yard.yaml", "--controller", "uncallable:not_callable",
                                         files={"yard.yaml": YARD, "uncallable.py": "not_callable = 42\n"}),
    "cli-controller-exit": ddenv("run", "yard.yaml", "--controller", "controllers:exits", "--no-picture",
                                 files={"yard.yaml": YARD, "controllers.py": CONTROLLERS}, code=3, subprocess=True),
    "cli-controller-os-exit": ddenv("run", "yard.yaml", "--controller", "controllers:ends", "--no-picture",
                                    files={"yard.yaml": YARD, "controllers.py": CONTROLLERS}, code=3,
                                    subprocess=True),
    "cli-import-exit": ddenv("run", "yard.yaml", "--import", "quits.py", files={
        "yard.yaml": YARD, "quits.py": "import sys\nsys.exit(0)\n"}, code=3, subprocess=True),
    "cli-reduce-controller-exit": ddenv(*REDUCE, "--controller", "controllers:exits",
                                        files={"yard.yaml": YARD, "controllers.py": CONTROLLERS}, code=3,
                                        subprocess=True),
    "cli-record-full": ddenv("run", "yard.yaml", "--no-picture", "--record", "/dev/full", files={"yard.yaml": YARD}),
    "cli-record-fifo": ddenv("run", "yard.yaml", "--no-picture", "--record", "runs.pipe",
                             files={"yard.yaml": YARD, "runs.pipe": _pipe}),
    "cli-output-folder": ddenv("run", "yard.yaml", "-o", ".", files={"yard.yaml": YARD}),
    "cli-output-suffix": ddenv("run", "yard.yaml", "-o", "out.txt", files={"yard.yaml": YARD}),
    "cli-animate-suffix": ddenv("show", "yard.yaml", "--animate", "run.mp4", files={"yard.yaml": YARD}),
    "cli-mplbackend": _with_env(ddenv("run", "yard.yaml", files={"yard.yaml": YARD}, subprocess=True),
                                MPLBACKEND="nonsense"),
    "cli-stages-long": ddenv("reduce", "yard.yaml", "-p", "stuck", "--stages", "s" * 1000, files={"yard.yaml": YARD}),
    "cli-probe-timeout-env": _with_env(ddenv("reduce", "yard.yaml", "-p", "stuck", files={"yard.yaml": YARD}),
                                       DDENV_PROBE_TIMEOUT="soon"),
    "cli-out-proc": ddenv("reduce", "yard.yaml", "-p", "stuck", "--out", "/proc/ddenv-out", files={"yard.yaml": YARD}),
    "cli-out-dangling": ddenv("reduce", "yard.yaml", "-p", "stuck", "--out", "out",
                              files={"yard.yaml": YARD, "out": _symlink("nowhere/out")}),
    "cli-out-lock-link": ddenv("reduce", "yard.yaml", "-p", "stuck", "--out", "out", files={
        "yard.yaml": YARD, "out/.ddenv.lock": _symlink("../precious.txt"), "precious.txt": "mine"}),
    # journals and summaries read back
    "log-folder": ddenv(*REDUCE, "--out", "out", files={"yard.yaml": YARD, "out/runs.jsonl/x": "a folder"}),
    "log-fifo": ddenv(*REDUCE, "--out", "out", files={"yard.yaml": YARD, "out/runs.jsonl": _pipe}),
    "replay-deep-summary": ddenv("replay", "art", files={"art/minimal.yaml": YARD, "art/summary.json": _deep_json}),
    "replay-summary-fifo": ddenv("replay", "art", files={"art/minimal.yaml": YARD, "art/summary.json": _pipe}),
    "replay-summary-seed": ddenv("replay", "art", "--runs", "1", files=_artifacts(scenario_seed="x")),
    "replay-summary-imports": ddenv("replay", "art", "--runs", "1", files=_artifacts(imports=5)),
    "replay-summary-controller": ddenv("replay", "art", "--runs", "1", files=_artifacts(controller=5)),
    "replay-summary-reference": ddenv("replay", "art", "--runs", "1", files=_artifacts(reference_failure="x")),
    "replay-summary-rate": ddenv("replay", "art", "--runs", "1", files=_artifacts(original_failure_rate={"a": 1})),
    "show-deep-runs": ddenv("show", "yard.yaml", "--runs", "runs.jsonl",
                            files={"yard.yaml": YARD, "runs.jsonl": _deep_json}),
    "show-runs-fifo": ddenv("show", "yard.yaml", "--runs", "runs.pipe", files={"yard.yaml": YARD, "runs.pipe": _pipe}),
}
CASES.update(PROCESS_CASES)


# -- the table ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Row:
    id: str
    input: str
    interface: str
    message: str


def table() -> dict[str, Row]:
    rows: dict[str, Row] = {}
    for line in PAGE.read_text(encoding="utf-8").splitlines():
        if not line.startswith("| `") or line.count(" | ") < 3:
            continue
        cells = [cell.strip() for cell in re.split(r"(?<!\\) \| ", line.strip().strip("|"))]
        identifier, what, interface = cells[0].strip("` "), cells[1], cells[2]
        message = re.match(r"`([^`]*)`", cells[-1])
        assert message is not None, f"the message of row {identifier} is not in backticks"
        rows[identifier] = Row(identifier, what, interface, message[1].replace("\\|", "|"))
    return rows


ROWS = table()


def test_every_row_has_a_case_and_every_case_a_row() -> None:
    assert sorted(ROWS) == sorted(CASES)
    assert len(ROWS) >= 40


def test_messages_are_one_short_line() -> None:
    for row in ROWS.values():
        assert "\n" not in row.message and len(row.message) <= 400, row.id


def _pattern(message: str) -> re.Pattern[str]:
    return re.compile(".*".join(re.escape(part) for part in message.split("…")))


def _make(folder: Path, files: dict[str, str | bytes | Callable[[Path], None]]) -> None:
    for name, content in files.items():
        path = folder / name
        path.parent.mkdir(parents=True, exist_ok=True)
        if callable(content):
            content(path)
        elif isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content, encoding="utf-8")


def _ddenv(case: Case, folder: Path, capsys: pytest.CaptureFixture[str], *extra: str) -> tuple[int, str, str]:
    words = [*case.command[1:], *extra]
    if case.subprocess:
        done = subprocess.run([sys.executable, "-m", "pytest_ddenv.cli", *words], cwd=folder, capture_output=True,
                              text=True, timeout=600, check=False)
        return done.returncode, done.stdout, done.stderr
    code = cli.main(words)
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def _python(code: str) -> str:
    """`Type: message` of the DdenvError `code` raised; what it returned, if it raised none."""
    import pytest_ddenv

    namespace = {name: getattr(pytest_ddenv, name) for name in pytest_ddenv.__all__}
    namespace["world"] = World.load("yard.yaml")
    try:
        result = eval(code, namespace)  # noqa: S307 - the table's own code
    except pytest_ddenv.DdenvError as error:
        return f"{type(error).__name__}: {error}"
    return f"(no error: returned {result!r})"


SLOW_CASES = {"sdf-include-breadth", "sdf-many-links"}
"""Inputs refused within their bounds only after seconds of CPU, by design: the full tier only."""


@pytest.mark.parametrize("identifier", [pytest.param(identifier, marks=pytest.mark.slow) if identifier in SLOW_CASES
                                        else identifier for identifier in sorted(CASES)])
def test_bad_input_gets_the_message_of_the_table(identifier: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                 capsys: pytest.CaptureFixture[str], request: pytest.FixtureRequest
                                                 ) -> None:
    case, row = CASES[identifier], ROWS[identifier]
    for name, value in case.env.items():
        monkeypatch.setenv(name, value)
    if identifier == "artifacts-read-only" and os.geteuid() == 0:  # root writes into read-only folders
        if os.access("/proc/sys", os.W_OK):
            pytest.skip("no folder is read-only for root here")
        case = Case(("pytest", "--ddenv-reduce", "--ddenv-artifacts", "/proc/sys/ddenv-out"), case.files, case.code)
    pattern = _pattern(row.message)
    if case.command[0] == "ddenv":
        _make(tmp_path, case.files)
        monkeypatch.chdir(tmp_path)
        code, out, err = _ddenv(case, tmp_path, capsys)
        printed = err if case.code else out
        assert code == case.code, printed
        assert any(pattern.fullmatch(line) for line in printed.splitlines()), f"{row.message!r} not in:\n{printed}"
        if case.code == cli.EXIT_USAGE:
            assert len(err.strip().splitlines()) == 1, err  # one line, no traceback
            code, out, err = _ddenv(case, tmp_path, capsys, "--json")
            data = json.loads(out)
            assert code == 2 and data["ok"] is False and data["exit_code"] == 2
            assert pattern.fullmatch("ddenv: error: " + data["error"]), data
        return
    if case.command[0] == "python":
        _make(tmp_path, case.files)
        monkeypatch.chdir(tmp_path)
        printed = _python(case.command[1])
        assert pattern.fullmatch(printed), f"{row.message!r} is not:\n{printed}"
        assert not list(tmp_path.glob(".*.tmp*")), "a temporary file was left behind"
        return
    pytester: pytest.Pytester = request.getfixturevalue("pytester")
    _make(pytester.path, case.files)
    result = pytester.runpytest_subprocess(*case.command[1:], "-p", "no:cacheprovider")
    printed = result.stderr.str() + "\n" + result.stdout.str()
    assert result.ret == case.code, printed
    assert any(pattern.fullmatch(line) for line in printed.splitlines()), f"{row.message!r} not in:\n{printed}"
    assert all(text in printed for text in case.also), printed
    if case.code == pytest.ExitCode.USAGE_ERROR or "ERROR at setup" in printed:  # no plugin traceback
        assert "Traceback" not in printed and "pytest_ddenv" not in printed and "During handling" not in printed, (
            printed)


# -- bounded time and memory ---------------------------------------------------------------------------------
def test_the_alias_bomb_is_refused_without_expanding_it(tmp_path: Path) -> None:
    path = tmp_path / "bomb.yaml"
    path.write_text(BOMB, encoding="utf-8")
    assert len(BOMB.encode()) < 500
    tracemalloc.start()
    try:
        with pytest.raises(WorldError, match="aliases expand the document by more than 100000 nodes"):
            World.load(path)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 20 * 1024 * 1024  # the expanded document would hold 387 million strings


def test_aliases_within_the_budget_are_read(tmp_path: Path) -> None:
    text = textwrap.dedent("""\
        format: 1
        models:
          - &crate {name: crate_1, box: [0.5, 0.5, 0.5], mass: 2, static: false}
          - {<<: *crate, name: crate_2, pose: [2, 0, 0]}
        """)
    world = World.from_yaml(text)
    assert world.names == ("crate_1", "crate_2") and world.model("crate_2").mass == 2


def test_a_message_never_holds_a_whole_file(tmp_path: Path) -> None:
    path = tmp_path / "notes.yaml"
    path.write_text("a long note " * 100_000, encoding="utf-8")
    with pytest.raises(WorldError) as caught:
        World.load(path)
    assert "not a world file" in str(caught.value) and len(str(caught.value)) < 400


def test_exponent_numbers_are_numbers_and_such_names_are_written_quoted(tmp_path: Path) -> None:
    world = World.from_yaml(HEAD + "physics: {timestep: 2.5E-3}\nmodels:\n  - {name: '1e5', box: [1e0, 1, 1]}\n")
    assert world.physics.timestep == 0.0025 and world.names == ("1e5",)
    assert World.from_yaml(world.to_yaml()) == world
