"""The 3D recording (`pytest_ddenv.media.recording`): real runs written to a real `.rrd` file and read back with
rerun's own reader (`rerun.chunk.RrdReader`)."""

from __future__ import annotations

import dataclasses
import math
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from engines import in_engine

rr = pytest.importorskip("rerun")
pa = pytest.importorskip("pyarrow")

from rerun.chunk import RrdReader
from scipy.spatial.transform import Rotation

from pytest_ddenv.detail import recording_detail
from pytest_ddenv.oracle import PREDICATES
from pytest_ddenv.media.recording import (
    INSTALL_HINT,
    RecordingInfo,
    RecordingUnavailable,
    quaternions,
    recording_available,
    write_recording,
)
from pytest_ddenv.sim import Run, simulate
from pytest_ddenv.world import Model, Pose, Scenario, Shape, World

ROOT = Path(__file__).resolve().parent.parent
DATA = Path(__file__).resolve().parent / "data"
Rows = Mapping[str, list[Any]]


# -- helpers ----------------------------------------------------------------------------------------------
def failing_run(world: World) -> Run:
    """A run of `world` with its full detail, under the predicates the scenario worlds fail."""
    predicates = [PREDICATES["stuck"](window=5.0, min_progress=0.2), PREDICATES["high_centered"]()]
    with recording_detail():
        return simulate(world, seed=0, predicates=predicates)


def read_entities(path: Path) -> dict[str, dict[str, list[Any]]]:
    """Entity path -> column name -> values (the rows of all its chunks, sorted by `sim_time`; static rows
    have no `sim_time` and come first). `sim_time` is in seconds."""
    rows: dict[str, list[dict[str, Any]]] = {}
    for chunk in RrdReader(path).stream().to_chunks():
        batch = chunk.to_record_batch()
        names = [name for name in batch.schema.names if not name.startswith("rerun.controls")]
        columns = {name: _values(batch.column(name)) for name in names}
        for index in range(batch.num_rows):
            rows.setdefault(chunk.entity_path, []).append({name: values[index] for name, values in columns.items()})
    result: dict[str, dict[str, list[Any]]] = {}
    for entity, entity_rows in rows.items():
        entity_rows.sort(key=lambda row: row.get("sim_time", -math.inf))
        names = sorted({name for row in entity_rows for name in row})
        result[entity] = {name: [row.get(name) for row in entity_rows] for name in names}
    return result


def _values(column: Any) -> list[Any]:
    if pa.types.is_duration(column.type):
        return [None if v is None else v / 1e9 for v in column.cast(pa.int64()).to_pylist()]
    return list(column.to_pylist())


def timed(rows: Rows, column: str) -> list[Any]:
    """The values of `column` in the rows that have a time."""
    return [value for time, value in zip(rows["sim_time"], rows[column]) if time is not None]


def entity(label: str, *parts: str) -> str:
    return "/" + "/".join([rr.escape_entity_path_part(label), *parts])


def model_entity(label: str, name: str) -> str:
    return entity(label, "models", rr.escape_entity_path_part(name))


# -- fixtures ---------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def runs() -> list[tuple[str, World, Run]]:
    """The rubble world (35 moving models; high-centred at 4.2 s) and a 2-model sub-world that fails too (stuck
    on `cinder_block_0` at 15.35 s): two runs of different lengths on one timeline. (Before issue 33 made dynamic
    models rigid bodies the sub-world was the other block, stuck at 11.15 s; the Husky now pushes it aside.)"""
    world = World.load(ROOT / "worlds" / "rubble.yaml")
    original = failing_run(world)
    if original.engine != "pybullet":  # the recording of MuJoCo runs: tests/sim_mujoco/test_mujoco_features.py
        pytest.skip("needs pybullet: the 2-model rubble sub-world these tests record fails in PyBullet only")
    minimal = world.select(["asphalt_plane", "cinder_block_0"])
    chosen = [("original", world, original), ("minimal", minimal, failing_run(minimal))]
    for label, _, run in chosen:
        assert run.failure is not None, f"the {label} world no longer fails: pick another sub-world"
    return chosen


@pytest.fixture(scope="module")
def written(runs: list[tuple[str, World, Run]], tmp_path_factory: pytest.TempPathFactory
            ) -> tuple[RecordingInfo, dict[str, dict[str, list[Any]]]]:
    path = tmp_path_factory.mktemp("recording") / "recording.rrd"
    info = write_recording(path, runs)
    return info, read_entities(path)


# -- tests ------------------------------------------------------------------------------------------------
def test_one_file_holds_every_run_under_its_label(runs: list[tuple[str, World, Run]], written: Any) -> None:
    info, entities = written
    assert info.path.is_file() and info.size_bytes == info.path.stat().st_size > 0
    assert [p.name for p in info.path.parent.iterdir()] == ["recording.rrd"], "the temporary file is left"
    assert set(info.entities) == set(entities) - {"/__properties"}
    for label, world, run in runs:
        for part in ("ground", "goal", "goal/tolerance", "robot", "robot/footprint", "trajectory/path",
                     "trajectory/position", "scan", "contacts", "failure", "log"):
            assert entity(label, *part.split("/")) in entities, (label, part)
        for model in world.models:
            assert model_entity(label, model.name) in entities
            assert model_entity(label, model.name) + "/boxes" in entities
    assert info.to_dict()["entities"] == len(info.entities)


def test_one_timeline_covers_every_run_to_its_failure(runs: list[tuple[str, World, Run]], written: Any) -> None:
    info, entities = written
    times = [t for rows in entities.values() for t in rows.get("sim_time", []) if t is not None]
    assert min(times) == 0.0
    last = max(float(run.times[-1]) for _, _, run in runs)
    assert max(times) == pytest.approx(last)
    assert info.time_range == (0.0, pytest.approx(last))
    for label, _, run in runs:
        assert run.failure is not None
        robot_times = timed(entities[entity(label, "robot")], "sim_time")
        assert robot_times[0] == 0.0 and robot_times[-1] >= run.failure.time - 1e-9
        failure = entities[entity(label, "failure")]
        assert failure["sim_time"] == [pytest.approx(run.failure.time)]
        assert np.allclose(failure["Points3D:positions"][0][0], run.failure.pose[:3], atol=1e-5)
        assert run.failure.predicate in failure["Points3D:labels"][0][0]
        log = entities[entity(label, "log")]
        assert log["TextLog:level"][-1] == ["ERROR"] and log["sim_time"][-1] == pytest.approx(run.failure.time)
        assert run.failure.predicate in log["TextLog:text"][-1][0]


def test_robot_transform_follows_the_run(runs: list[tuple[str, World, Run]], written: Any) -> None:
    _, entities = written
    for label, _, run in runs:
        rows = entities[entity(label, "robot")]
        assert timed(rows, "sim_time") == pytest.approx(run.times.tolist())
        translation = np.array(timed(rows, "Transform3D:translation")[-1][0])
        quaternion = np.array(timed(rows, "Transform3D:quaternion")[-1][0])
        assert np.allclose(translation, run.poses[-1, :3], atol=1e-5)
        expected = Rotation.from_euler("xyz", run.poses[-1, 3:6]).as_quat()  # extrinsic x y z: Rz @ Ry @ Rx
        assert min(np.abs(quaternion - expected).max(), np.abs(quaternion + expected).max()) < 1e-5
        path = entities[entity(label, "trajectory", "path")]["LineStrips3D:strips"][0][0]
        assert np.allclose(path, run.poses[:, :3], atol=1e-5)
        assert len(timed(entities[entity(label, "trajectory", "position")], "Points3D:positions")) == len(run.times)


def test_moving_models_follow_their_recorded_poses(runs: list[tuple[str, World, Run]], written: Any) -> None:
    _, entities = written
    label, world, run = runs[0]
    assert run.detail is not None
    moving = [model for model in world.models if model.dynamic]
    assert len(moving) == 35
    for model in moving:
        rows = entities[model_entity(label, model.name)]
        recorded = run.detail.bodies[model.name]
        assert len(timed(rows, "sim_time")) == len(run.times)
        assert np.allclose([v[0] for v in timed(rows, "Transform3D:translation")], recorded[:, :3], atol=1e-5)
        assert np.allclose([v[0] for v in timed(rows, "Transform3D:quaternion")], recorded[:, 3:], atol=1e-5)
    static = next(model for model in world.models if model.static)
    assert "sim_time" not in entities[model_entity(label, static.name)]


def test_scan_has_one_row_per_sample_in_the_world_frame(runs: list[tuple[str, World, Run]], written: Any) -> None:
    _, entities = written
    for label, _, run in runs:
        detail = run.detail
        assert detail is not None and detail.scan_ranges is not None
        positions = timed(entities[entity(label, "scan")], "Points3D:positions")
        assert len(positions) == len(run.times)
        assert [len(row) for row in positions] == np.isfinite(detail.scan_ranges).sum(axis=1).tolist()
        sample = int(np.argmax(np.isfinite(detail.scan_ranges).sum(axis=1)))
        origin = run.poses[sample, :3] + [0.0, 0.0, detail.scan_height]
        reach = np.linalg.norm(np.array(positions[sample]) - origin, axis=1)
        ranges = detail.scan_ranges[sample]
        assert np.allclose(reach, ranges[np.isfinite(ranges)], atol=1e-4)


def test_contacts_have_one_row_per_sample(runs: list[tuple[str, World, Run]], written: Any) -> None:
    _, entities = written
    for label, _, run in runs:
        assert run.detail is not None
        rows = entities[entity(label, "contacts")]
        positions = timed(rows, "Points3D:positions")
        assert [len(row) for row in positions] == [len(contacts) for contacts in run.detail.contacts]
        touched = {name for labels in timed(rows, "Points3D:labels") for name in labels}
        assert touched == {contact[0] for contacts in run.detail.contacts for contact in contacts}
        assert all(0.0199 <= r <= 0.2001 for radii in timed(rows, "Points3D:radii") for r in radii)


def test_a_run_without_detail_still_has_robot_and_trajectory(runs: list[tuple[str, World, Run]],
                                                             tmp_path: Path) -> None:
    _, world, run = runs[0]
    bare = dataclasses.replace(run, detail=None)
    info = write_recording(tmp_path / "bare.rrd", [("bare", world, bare)], application_id="test")
    entities = read_entities(info.path)
    for part in ("robot", "robot/footprint", "trajectory/path", "trajectory/position", "failure", "log"):
        assert entity("bare", *part.split("/")) in entities
    assert entity("bare", "scan") not in entities and entity("bare", "contacts") not in entities
    assert len(timed(entities[entity("bare", "robot")], "sim_time")) == len(run.times)
    moving = next(model for model in world.models if model.dynamic)
    rows = entities[model_entity("bare", moving.name)]
    assert "sim_time" not in rows  # static: where the world puts it
    assert np.allclose(rows["Transform3D:translation"][0][0], moving.pose.position, atol=1e-5)


def shapes_world() -> World:
    """One model of each shape kind, and a moving polyline (whose simulated body sits at its centre of mass),
    around a robot that does not reach them in its one second."""
    hill = str(DATA / "sdf" / "corpus" / "media" / "hill.png")
    outline = ((0.0, 0.0), (0.6, 0.0), (0.6, 0.2), (0.2, 0.2), (0.2, 0.6), (0.0, 0.6))
    models = (
        Model("crate", (Shape("box", size=(0.4, 0.3, 0.2), pose=Pose(z=0.1)),), Pose(4.0, 2.0, 0.0, yaw=0.3)),
        Model("pipe", (Shape("cylinder", radius=0.1, length=1.0, pose=Pose(z=0.1, roll=math.pi / 2)),),
              Pose(4.0, -2.0)),
        Model("ball", (Shape("sphere", radius=0.2, pose=Pose(z=0.2)),), Pose(5.0, 3.0)),
        Model("pill", (Shape("capsule", radius=0.1, length=0.6, pose=Pose(z=0.1, pitch=math.pi / 2)),),
              Pose(5.0, -3.0)),
        Model("mesh", (Shape("mesh", mesh=str(DATA / "meshes" / "textured_box.dae"), scale=(0.3, 0.3, 0.3)),),
              Pose(6.0, 3.0, 0.5)),
        Model("wall", (Shape("polyline", points=outline, height=0.5),), Pose(6.0, -3.0)),
        Model("ell", (Shape("polyline", points=outline, height=0.2),), Pose(-3.0, 3.0), mass=2.0, static=False),
        Model("hill", (Shape("heightmap", mesh=hill, size=(4.0, 4.0, 0.5)),), Pose(-5.0, -5.0)),
    )
    return World(models, Scenario(start=Pose(), goal=(0.0, 8.0, None), timeout=1.0), name="shapes")


def test_every_shape_kind_is_drawn_where_the_world_puts_it(tmp_path: Path, physics_engine: str) -> None:
    world = in_engine(shapes_world(), physics_engine)
    with recording_detail():
        run = simulate(world, seed=0)
    info = write_recording(tmp_path / "shapes.rrd", [("shapes", world, run)])
    entities = read_entities(info.path)
    drawn = {"crate": "boxes", "pipe": "cylinders", "ball": "spheres", "pill": "capsules", "mesh": "mesh0",
             "wall": "mesh0", "ell": "mesh0", "hill": "mesh0"}
    for name, part in drawn.items():
        assert model_entity("shapes", name) + "/" + part in entities, name
    for name in ("mesh", "wall", "hill"):  # static meshes: their vertices, placed, span the model's bounds
        model_rows = entities[model_entity("shapes", name)]
        translation = np.array(model_rows["Transform3D:translation"][0][0])
        rotation = Rotation.from_quat(model_rows["Transform3D:quaternion"][0][0]).as_matrix()
        vertices = np.array(entities[model_entity("shapes", name) + "/mesh0"]["Mesh3D:vertex_positions"][0])
        placed = vertices @ rotation.T + translation
        low, high = world.bounds(name)
        assert np.allclose(placed.min(axis=0), low, atol=1e-4) and np.allclose(placed.max(axis=0), high, atol=1e-4)
    pill = entities[model_entity("shapes", "pill") + "/capsules"]  # rerun's capsule starts at its translation
    assert np.allclose(pill["Capsules3D:translations"][0][0], [-0.3, 0.0, 0.1], atol=1e-5)
    ell = entities[model_entity("shapes", "ell")]  # the moving polyline: its body frame and its outline agree
    start = np.array(timed(ell, "Transform3D:translation")[0][0])
    outline = np.array(entities[model_entity("shapes", "ell") + "/mesh0"]["Mesh3D:vertex_positions"][0])
    assert np.allclose((outline + start).min(axis=0), world.bounds("ell")[0], atol=0.02)
    assert entity("shapes", "failure") not in entities
    assert "without a failure" in entities[entity("shapes", "log")]["TextLog:text"][-1][0]


def test_quaternions_match_the_fixed_axis_roll_pitch_yaw() -> None:
    angles = np.random.default_rng(0).uniform(-math.pi, math.pi, (50, 3))
    expected = Rotation.from_euler("xyz", angles).as_quat()
    found = quaternions(angles)
    assert np.allclose(np.abs((found * expected).sum(axis=1)), 1.0)


def test_labels_must_be_distinct(runs: list[tuple[str, World, Run]], tmp_path: Path) -> None:
    _, world, run = runs[1]
    with pytest.raises(ValueError, match="distinct"):
        write_recording(tmp_path / "twice.rrd", [("a", world, run), ("a", world, run)])
    assert not list(tmp_path.iterdir())


def test_without_rerun_the_recording_is_unavailable(runs: list[tuple[str, World, Run]], tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    assert recording_available()
    monkeypatch.setitem(sys.modules, "rerun", None)
    assert not recording_available()
    _, world, run = runs[1]
    with pytest.raises(RecordingUnavailable, match=r"pip install 'pytest-ddenv\[viewer\]'") as raised:
        write_recording(tmp_path / "none.rrd", [("minimal", world, run)])
    assert isinstance(raised.value, ImportError) and str(raised.value) == INSTALL_HINT
    assert not list(tmp_path.iterdir())
