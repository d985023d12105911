"""The world model's bounds that hold by construction (docs/reliability.md, issue 28), beyond the rows of the
bad-input table: the files a world names are read only when they are regular files and never waited on, a
heightmap stays within what pybullet takes, YAML 1.1 base-60 numbers are text, and every world the simulator
gets holds numbers it can take, however it was made.

Processes that once waited forever run as children with a hang guard (never an assertion of speed).
"""

from __future__ import annotations

import math
import os
import re
import stat
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from pytest_ddenv import Model, Pose, RobotWorld, Scenario, Shape, World, WorldError
from pytest_ddenv.sim.builder import build_world
from pytest_ddenv.world.meshes import HEIGHTMAP_SIDE, MAX_HEIGHTMAP_PIXELS

HANG_GUARD = 60.0
"""Seconds after which a child that should have ended at once is killed and the test fails."""
SCENARIO = Scenario(goal=(4.0, 0.0, None), timeout=5.0)


def _child(code: str, folder: Path, **options: object) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-c", textwrap.dedent(code)], cwd=folder, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, **options)  # type: ignore[call-overload]


def _ended(process: subprocess.Popen[str], what: str) -> str:
    """What the child printed on stderr, once it ended; the test fails if it is still waiting after the guard."""
    try:
        process.wait(timeout=HANG_GUARD)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()
        pytest.fail(f"{what}: still waiting after {HANG_GUARD:g} s")
    assert process.stderr is not None
    return process.stderr.read()


def test_a_pipe_given_as_the_world_is_refused_without_waiting_for_a_writer(tmp_path: Path) -> None:
    process = _child("from pytest_ddenv.cli import main as cli; raise SystemExit(cli.main(['check', '/dev/stdin']))", tmp_path,
                     stdin=subprocess.PIPE)  # held open and never written
    try:
        printed = _ended(process, "ddenv check /dev/stdin on a pipe")
    finally:
        assert process.stdin is not None
        process.stdin.close()
    assert process.returncode == 2
    assert printed.strip() == "ddenv: error: /dev/stdin: not a world file: a FIFO (named pipe), not a file"


def test_a_fifo_mesh_of_a_world_made_in_python_is_refused_by_the_simulator_without_waiting(tmp_path: Path) -> None:
    os.mkfifo(tmp_path / "crate.stl")
    process = _child("""
        from pytest_ddenv import *
        crate = Model("crate", (Shape("mesh", mesh="crate.stl"),), Pose(x=-3.0))
        try:
            RobotWorld(World(models=(crate,), scenario=Scenario(goal=(4.0, 0.0, None), timeout=5.0))).run()
        except DdenvError as error:
            raise SystemExit(f"{type(error).__name__}: {error}")
        """, tmp_path)
    printed = _ended(process, "a run of a world whose mesh is a FIFO")
    assert printed.strip() == ("WorldError: model crate, field 'mesh': not a mesh file: crate.stl is a FIFO "
                               "(named pipe)")


def _halves(path: Path, width: int, height: int) -> None:
    """A heightmap image: its top half (the +y side) at 191/255, its bottom half at 64/255."""
    pixels = np.full((height, width), 64, dtype=np.uint8)
    pixels[: height // 2] = 191
    Image.fromarray(pixels).save(path)


@pytest.mark.pybullet
def test_the_largest_heightmap_allowed_is_simulated_at_its_own_heights(tmp_path: Path) -> None:
    """pybullet reads garbage heights past 2 097 152 samples (1449 x 1449: its 8 MiB stream buffer of float32);
    the limit leaves it half of that, and a heightmap at the limit is the surface the image says."""
    _halves(tmp_path / "hill.png", HEIGHTMAP_SIDE, HEIGHTMAP_SIDE)
    assert HEIGHTMAP_SIDE * HEIGHTMAP_SIDE == MAX_HEIGHTMAP_PIXELS
    (tmp_path / "hill.yaml").write_text("format: 1\nmodels:\n  - {name: hill, heightmap: {file: hill.png, "
                                        "size: [10, 10, 1]}}\n")
    world = World.load(tmp_path / "hill.yaml")
    import pybullet

    client = pybullet.connect(pybullet.DIRECT)
    try:
        build_world(pybullet, client, world)
        hits = {(x, y): pybullet.rayTest([x, y, 5.0], [x, y, -5.0], physicsClientId=client)[0]
                for x in (-4.9, 4.9) for y in (-4.9, 4.9)}
    finally:
        pybullet.disconnect(client)
    for (_, y), hit in hits.items():
        assert hit[0] >= 0, "the ray missed the heightmap"
        assert hit[3][2] == pytest.approx((191 if y > 0 else 64) / 255.0, abs=0.01)


def test_one_pixel_more_than_the_limit_is_refused(tmp_path: Path) -> None:
    _halves(tmp_path / "hill.png", HEIGHTMAP_SIDE + 1, HEIGHTMAP_SIDE)
    with pytest.raises(WorldError, match=rf"has {HEIGHTMAP_SIDE + 1} x {HEIGHTMAP_SIDE} pixels; a heightmap has at "
                                         rf"most {MAX_HEIGHTMAP_PIXELS}"):
        World.from_yaml("format: 1\nmodels:\n  - {name: hill, heightmap: {file: hill.png, size: [10, 10, 1]}}\n",
                        source=tmp_path / "hill.yaml")


def test_text_that_looks_like_a_base_60_number_is_text_and_is_written_back_as_text(tmp_path: Path) -> None:
    world = World.from_yaml("format: 1\nname: 12:30\nmodels:\n  - {name: 1:30, box: [1, 1, 1], tags: {at: 9:45}}\n")
    assert world.name == "12:30" and world.names == ("1:30",) and world.model("1:30").tags == {"at": "9:45"}
    world.save(tmp_path / "again.yaml")
    assert World.load(tmp_path / "again.yaml") == world


def test_saving_never_replaces_what_is_not_a_file_and_leaves_nothing_behind(tmp_path: Path) -> None:
    world = World(models=(Model("crate", (Shape("box", size=(1.0, 1.0, 1.0)),)),))
    os.mkfifo(tmp_path / "pipe.yaml")
    (tmp_path / "folder.sdf").mkdir()
    with pytest.raises(WorldError, match=r"pipe.yaml: is a FIFO \(named pipe\), not a world file"):
        world.save(tmp_path / "pipe.yaml")
    with pytest.raises(WorldError, match=r"folder.sdf: is a folder, not a world file"):
        world.save(tmp_path / "folder.sdf")
    with pytest.raises(WorldError, match=r"cannot write the world file: the folder .*missing does not exist"):
        world.save(tmp_path / "missing" / "world.yaml")
    assert stat.S_ISFIFO(os.stat(tmp_path / "pipe.yaml").st_mode)
    assert sorted(path.name for path in tmp_path.iterdir()) == ["folder.sdf", "pipe.yaml"]


@pytest.mark.parametrize(("model", "field"), [
    (Model("crate", (Shape("box", size=(1.0, 1.0, 1.0)),), Pose(x=math.nan)), "pose[0]"),
    (Model("crate", (Shape("box", size=(1e39, 1e39, 1.0)),)), "shapes[0].size"),
    (Model("crate", (Shape("sphere", radius=-1.0),)), "shapes[0].radius"),
    (Model("crate", (Shape("box", size=(1.0, 1.0, 1.0)),), mass=math.inf, static=False), "mass"),
])
def test_a_world_made_in_python_is_checked_before_it_is_simulated(model: Model, field: str) -> None:
    world = World(models=(model,), scenario=SCENARIO)
    with pytest.raises(WorldError, match=rf"model 'crate' \(#0\), field '{re.escape(field)}': expected"):
        RobotWorld(world)
    with pytest.raises(WorldError, match=rf"field '{re.escape(field)}'"):
        RobotWorld(World(scenario=SCENARIO)).rebound(world)
