"""The MCAP recording (`pytest_ddenv.media.mcap`): real runs written to a real `.mcap` file by foxglove-sdk and
read back with the `mcap` reader, each message decoded from the protobuf schema the file carries
(`mcap-protobuf-support`)."""

from __future__ import annotations

import json
import shutil
import sys
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("foxglove")
pytest.importorskip("mcap_protobuf")

from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory
from scipy.spatial.transform import Rotation

from pytest_ddenv.detail import recording_detail
from pytest_ddenv.media import content
from pytest_ddenv.media.mcap import INSTALL_HINT, McapInfo, McapUnavailable, mcap_available, nanoseconds, write_mcap
from pytest_ddenv.oracle import PREDICATES
from pytest_ddenv.sim import Run, simulate
from pytest_ddenv.world import World

ROOT = Path(__file__).resolve().parent.parent
DATA = Path(__file__).resolve().parent / "data"
SCHEMAS = {"tf": "foxglove.FrameTransforms", "scene": "foxglove.SceneUpdate", "robot/pose": "foxglove.PoseInFrame",
           "scan": "foxglove.PointCloud", "contacts": "foxglove.SceneUpdate", "failure": "foxglove.SceneUpdate",
           "log": "foxglove.Log"}
"""Every topic of a wheeled robot's failing run with detail (after `/<label>/`) and its schema."""


class Read:
    """A file read back: the header, each topic's schema name, and each topic's (log time, decoded message)."""

    def __init__(self, path: Path) -> None:
        self.messages: dict[str, list[tuple[int, Any]]] = defaultdict(list)
        with path.open("rb") as stream:
            reader = make_reader(stream, decoder_factories=[DecoderFactory()])
            self.header = reader.get_header()
            summary = reader.get_summary()
            assert summary is not None
            self.schemas = {channel.topic: summary.schemas[channel.schema_id].name
                            for channel in summary.channels.values()}
            self.encodings = {channel.message_encoding for channel in summary.channels.values()}
            for _, channel, message, decoded in reader.iter_decoded_messages(log_time_order=True):
                self.messages[channel.topic].append((message.log_time, decoded))

    def times(self, topic: str) -> list[int]:
        return [time for time, _ in self.messages[topic]]

    def decoded(self, topic: str) -> list[Any]:
        return [message for _, message in self.messages[topic]]


def failing_run(world: World) -> Run:
    predicates = [PREDICATES["stuck"](window=5.0, min_progress=0.2), PREDICATES["high_centered"]()]
    with recording_detail():
        return simulate(world, seed=0, predicates=predicates)


def xyz(vector: Any) -> np.ndarray:
    return np.array([vector.x, vector.y, vector.z])


# -- fixtures ---------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def runs() -> list[tuple[str, World, Run]]:
    """The rubble world (35 moving models; high-centred at 4.2 s) and a 2-model sub-world that fails too (stuck
    at 15.35 s), as in tests/test_recording.py."""
    world = World.load(ROOT / "worlds" / "rubble.yaml")
    original = failing_run(world)
    if original.engine != "pybullet":
        pytest.skip("needs pybullet: the 2-model rubble sub-world fails in PyBullet only")
    minimal = world.select(["asphalt_plane", "cinder_block_0"])
    chosen = [("original", world, original), ("minimal", minimal, failing_run(minimal))]
    for label, _, run in chosen:
        assert run.failure is not None, f"the {label} world no longer fails: pick another sub-world"
    return chosen


@pytest.fixture(scope="module")
def written(runs: list[tuple[str, World, Run]], tmp_path_factory: pytest.TempPathFactory) -> tuple[McapInfo, Read]:
    info = write_mcap(tmp_path_factory.mktemp("mcap") / "recording.mcap", runs)
    return info, Read(info.path)


# -- a wheeled robot's runs -------------------------------------------------------------------------------
def test_every_run_has_every_channel_in_its_foxglove_schema(runs: list[tuple[str, World, Run]],
                                                            written: tuple[McapInfo, Read]) -> None:
    info, read = written
    assert info.path.is_file() and info.size_bytes == info.path.stat().st_size > 0
    assert [p.name for p in info.path.parent.iterdir()] == ["recording.mcap"], "the temporary file is left"
    assert read.header.profile == "pytest-ddenv" and read.encodings == {"protobuf"}
    expected = {f"/{label}/{topic}": schema for label, _, _ in runs for topic, schema in SCHEMAS.items()}
    assert read.schemas == expected and set(info.topics) == set(expected)
    assert info.messages == sum(len(messages) for messages in read.messages.values())
    assert info.to_dict()["topics"] == len(expected) and info.time_range == (0.0, 15.35)


def test_the_robot_moves_at_the_simulated_times(runs: list[tuple[str, World, Run]],
                                                written: tuple[McapInfo, Read]) -> None:
    _, read = written
    for label, _, run in runs:
        times = [nanoseconds(t) for t in run.times]
        assert read.times(f"/{label}/robot/pose") == times == read.times(f"/{label}/tf")
        poses = read.decoded(f"/{label}/robot/pose")
        assert {pose.frame_id for pose in poses} == {label}
        assert [pose.timestamp.seconds * 10**9 + pose.timestamp.nanos for pose in poses] == times
        positions = np.array([xyz(pose.pose.position) for pose in poses])
        assert np.allclose(positions, run.poses[:, :3])
        last = poses[-1].pose.orientation
        yaw = Rotation.from_quat([last.x, last.y, last.z, last.w]).as_euler("xyz")[2]
        assert yaw == pytest.approx(run.poses[-1, 5])
        robot = [next(t for t in tf.transforms if t.child_frame_id == f"{label}/robot")
                 for tf in read.decoded(f"/{label}/tf")]
        assert {t.parent_frame_id for t in robot} == {label}
        assert np.allclose([xyz(t.translation) for t in robot], run.poses[:, :3])


def test_moving_models_follow_their_recorded_poses_and_static_ones_are_placed_once(
        runs: list[tuple[str, World, Run]], written: tuple[McapInfo, Read]) -> None:
    _, read = written
    label, world, run = runs[0]
    assert run.detail is not None
    frames = read.decoded(f"/{label}/tf")
    first = {t.child_frame_id for t in frames[0].transforms}
    assert first == {f"{label}/robot", *(f"{label}/models/{model.name}" for model in world.models)}
    moving = sorted(run.detail.bodies)
    assert moving, "rubble has moving models"
    for name in moving[:3]:
        frame = f"{label}/models/{name}"
        found = [next(t for t in tf.transforms if t.child_frame_id == frame) for tf in frames]
        assert np.allclose([xyz(t.translation) for t in found], run.detail.bodies[name][:, :3])
    static = [model.name for model in world.models if model.name not in run.detail.bodies]
    for name in static:
        assert sum(t.child_frame_id == f"{label}/models/{name}" for tf in frames for t in tf.transforms) == 1


def test_the_scene_holds_the_ground_goal_models_robot_and_trajectory(runs: list[tuple[str, World, Run]],
                                                                     written: tuple[McapInfo, Read]) -> None:
    _, read = written
    for label, world, run in runs:
        (update,) = read.decoded(f"/{label}/scene")
        assert read.times(f"/{label}/scene") == [0]
        entities = {entity.id: entity for entity in update.entities}
        assert set(entities) >= {"ground", "goal", "footprint", "trajectory", *world.names}
        for model in world.models:
            entity = entities[model.name]
            assert entity.frame_id == f"{label}/models/{model.name}" and entity.frame_locked
            shapes = content.body_frame(model)[1]
            assert len(entity.cubes) == sum(shape.kind == "box" for shape in shapes)
            assert len(entity.triangles) == sum(shape.kind in content.MESH_KINDS for shape in shapes)
        footprint = entities["footprint"]
        assert footprint.frame_id == f"{label}/robot"
        assert np.allclose(xyz(footprint.cubes[0].size)[:2], run.footprint)
        path = np.array([xyz(point) for point in entities["trajectory"].lines[0].points])
        assert np.allclose(path, run.poses[:, :3])
        box = content.ground_box(world, run)
        assert box is not None and np.allclose(xyz(entities["ground"].cubes[0].size), 2 * box.half_sizes)


def test_the_laser_hits_are_one_point_cloud_per_sample(runs: list[tuple[str, World, Run]],
                                                       written: tuple[McapInfo, Read]) -> None:
    _, read = written
    label, _, run = runs[1]
    assert run.detail is not None
    points, counts = content.scan_points(run, run.detail)
    clouds = read.decoded(f"/{label}/scan")
    assert read.times(f"/{label}/scan") == [nanoseconds(t) for t in run.times[: len(counts)]]
    assert [field.name for field in clouds[0].fields] == ["x", "y", "z"] and clouds[0].point_stride == 12
    decoded = np.concatenate([np.frombuffer(cloud.data, dtype="<f4").reshape(-1, 3) for cloud in clouds])
    assert [len(cloud.data) // 12 for cloud in clouds] == counts.tolist() and counts.sum() > 0
    assert np.allclose(decoded, points, atol=1e-5)


def test_contacts_are_spheres_of_each_sample_with_the_models_touched(runs: list[tuple[str, World, Run]],
                                                                     written: tuple[McapInfo, Read]) -> None:
    _, read = written
    for label, _, run in runs:
        assert run.detail is not None
        found = content.contacts(run, run.detail)
        updates = read.decoded(f"/{label}/contacts")
        assert len(updates) == len(found.counts) and sum(found.counts) > 0
        assert [len(update.entities[0].spheres) for update in updates] == list(found.counts)
        touched = [name for update in updates for name in update.entities[0].metadata[0].value.split(",") if name]
        assert touched == list(found.models)


def test_the_failure_marker_and_the_log_are_at_the_failure_time(runs: list[tuple[str, World, Run]],
                                                                written: tuple[McapInfo, Read]) -> None:
    _, read = written
    for label, _, run in runs:
        failure = run.failure
        assert failure is not None
        assert read.times(f"/{label}/failure") == [nanoseconds(failure.time)]
        (update,) = read.decoded(f"/{label}/failure")
        (marker,) = update.entities
        assert np.allclose(xyz(marker.spheres[0].pose.position), failure.pose[:3])
        assert marker.texts[0].text == f"{failure.predicate} at t = {failure.time:.2f} s"
        logs = read.messages[f"/{label}/log"]
        assert [time for time, _ in logs] == [0, nanoseconds(failure.time)]
        start, failed = (message for _, message in logs)
        assert "seed 0" in start.message and failed.message.startswith("FAILED: ")
        assert (start.level, failed.level) == (2, 4)  # foxglove.Log's INFO, ERROR


def test_the_same_runs_give_the_same_bytes(runs: list[tuple[str, World, Run]], written: tuple[McapInfo, Read],
                                           tmp_path: Path) -> None:
    info, _ = written
    again = write_mcap(tmp_path / "again.mcap", runs)
    assert again.path.read_bytes() == info.path.read_bytes()


def test_a_run_without_detail_still_has_the_robot_and_its_trajectory(runs: list[tuple[str, World, Run]],
                                                                     tmp_path: Path) -> None:
    world = runs[1][1]
    plain = simulate(world, seed=0, predicates=[PREDICATES["stuck"](window=5.0, min_progress=0.2)])
    assert plain.detail is None
    read = Read(write_mcap(tmp_path / "plain.mcap", [("plain", world, plain)]).path)
    assert set(read.schemas) == {f"/plain/{topic}" for topic in ("tf", "scene", "robot/pose", "failure", "log")}


def test_labels_must_be_distinct(runs: list[tuple[str, World, Run]], tmp_path: Path) -> None:
    _, world, run = runs[1]
    with pytest.raises(ValueError, match="distinct, non-empty labels"):
        write_mcap(tmp_path / "x.mcap", [("a", world, run), ("a", world, run)])
    assert not list(tmp_path.iterdir())


def test_without_foxglove_sdk_the_recording_is_unavailable(runs: list[tuple[str, World, Run]], tmp_path: Path,
                                                           monkeypatch: pytest.MonkeyPatch) -> None:
    assert mcap_available()
    monkeypatch.setitem(sys.modules, "foxglove", None)
    assert not mcap_available()
    _, world, run = runs[1]
    with pytest.raises(McapUnavailable, match=r"pip install 'pytest-ddenv\[mcap\]'") as raised:
        write_mcap(tmp_path / "none.mcap", [("minimal", world, run)])
    assert isinstance(raised.value, ImportError) and str(raised.value) == INSTALL_HINT
    assert not list(tmp_path.iterdir())


# -- an arm's run -----------------------------------------------------------------------------------------
def test_an_arm_run_has_its_gripper_links_and_target(tmp_path: Path) -> None:
    world = World.load(DATA / "arm_smoke.yaml")
    with recording_detail():
        run = simulate(world, seed=0)
    assert run.robot_kind == "arm" and run.target_path is not None
    read = Read(write_mcap(tmp_path / "arm.mcap", [("arm", world, run)]).path)
    samples = [nanoseconds(t) for t in run.times]
    assert read.schemas["/arm/target"] == "foxglove.SceneUpdate" and read.times("/arm/target") == samples
    targets = np.array([xyz(update.entities[0].spheres[0].pose.position) for update in read.decoded("/arm/target")])
    assert np.allclose(targets, run.target_path)
    (scene,) = read.decoded("/arm/scene")
    entities = {entity.id: entity for entity in scene.entities}
    assert {"gripper", "arm base", "target path", "place region"} <= set(entities) and "footprint" not in entities
    assert entities["gripper"].frame_id == "arm/robot"
    if "/arm/arm/links" in read.schemas:  # replayed through pybullet's forward kinematics
        links = read.decoded("/arm/arm/links")
        assert len(links) == len(samples) and len(links[0].entities[0].lines[0].points) % 2 == 0
    else:
        pytest.importorskip("pybullet")
        pytest.fail("pybullet is installed but the arm's links were not recorded")


# -- in a reduction ---------------------------------------------------------------------------------------
TEST = '''
import pytest

@pytest.mark.ddenv(world="worlds/ditch.yaml", partition="model2model", priority="avg-trajectory")
@pytest.mark.robot_failure("stuck", window=5.0, min_progress=0.2)
def test_ditch(robot_world):
    assert robot_world.run().reached_goal
'''


@pytest.mark.slow
def test_a_reduction_with_media_mcap_leaves_one_recording_of_both_runs(pytester: pytest.Pytester) -> None:
    shutil.copytree(ROOT / "worlds", pytester.path / "worlds")
    pytester.makepyfile(test_ditch=TEST)
    result = pytester.runpytest_subprocess("--ddenv-reduce", "--ddenv-media", "mcap", "--junitxml=junit.xml",
                                           "-o", "junit_logging=system-out")
    result.assert_outcomes(failed=1)
    (folder,) = (pytester.path / "ddenv-artifacts").iterdir()
    made = {path.name for path in folder.iterdir()}
    assert "recording.mcap" in made and not made & {"recording.rrd", "original.gif", "minimal.gif"}
    read = Read(folder / "recording.mcap")
    for label in ("original", "minimal"):
        assert {f"/{label}/{topic}" for topic in SCHEMAS} <= set(read.schemas)
        (time, _), = read.messages[f"/{label}/failure"]
        assert time > 0
    summary = json.loads((folder / "summary.json").read_text())
    assert summary["media"]["files"]["recording.mcap"]["topics"] == len(read.schemas)
    records = [json.loads(line) for line in (folder / "runs.jsonl").read_text().splitlines()]
    assert [r["outcome"] for r in records if r.get("purpose") == "recording"] == ["fail"]
    assert f"[[ATTACHMENT|{folder / 'recording.mcap'}]]" in (pytester.path / "junit.xml").read_text()
