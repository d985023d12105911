"""Pictures: non-empty PNGs of the expected pixel size for every shipped scenario world and for a reduction."""

from __future__ import annotations

import json
import math
import struct
from pathlib import Path

import numpy as np
import pytest

from pytest_ddenv import render
from pytest_ddenv.driver import picture_data, pictures
from pytest_ddenv.driver.artifacts import ArtifactPaths
from pytest_ddenv.driver.picture_data import reference_pose, reference_text
from pytest_ddenv.oracle import FailureSignature
from pytest_ddenv.reduce import Reduction, events
from pytest_ddenv.render.canvas import pyplot
from pytest_ddenv.sim import Run, RunSettings
from pytest_ddenv.world import World

ROOT = Path(__file__).resolve().parent.parent
SCENARIOS = ("ditch", "rubble", "friction")


def png_size(path: Path) -> tuple[int, int]:
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", f"{path} is not a PNG"
    width, height = struct.unpack(">II", data[16:24])
    return width, height


def fake_run(points: list[tuple[float, float]], *, failure: str | None = "stuck", touched: tuple[str, ...] = (),
             seed: int = 0) -> Run:
    """A Run with a straight-segment trajectory through `points` (no simulation)."""
    positions = np.array([[x, y, 0.15] for x, y in points], dtype=float)
    count = len(positions)
    yaw = math.atan2(points[-1][1] - points[0][1], points[-1][0] - points[0][0])
    poses = np.column_stack([positions, np.zeros((count, 2)), np.full(count, yaw)])
    times = np.linspace(0.0, 0.5 * (count - 1), count)
    signature = None if failure is None else FailureSignature(failure, float(times[-1]), tuple(poses[-1]), touched)
    return Run(
        seed=seed, settings=RunSettings(), world_name="fake", model_names=(), times=times, poses=poses,
        velocities=np.zeros((count, 6)), wheel_contacts=np.zeros((count, 4)), first_touch={n: 1.0 for n in touched},
        last_touch={n: 1.0 for n in touched}, first_sensed={}, reached_goal=failure is None,
        goal_time=None if failure else float(times[-1]), failure=signature, sim_time=float(times[-1]), wall_time=0.1,
        steps=count, pybullet_version="test",
    )


def fake_reduction(world: World, minimal: tuple[str, ...]) -> Reduction:
    return Reduction(
        original=world.names, minimal=minimal, kept=(), probes=24, cache_hits=2, skipped=1, errors=0,
        steps=((0, len(world)), (3, len(world) // 2), (9, len(world) // 4), (17, len(minimal))), one_minimal=True,
        incomplete_reason=None, failure_rate=(5, 5), wall_time=12.0, partition="model2model",
        priority="avg-trajectory-proximal", granularity="ddmin", deflake=3, seed=0,
    )


@pytest.fixture(scope="module")
def worlds() -> dict[str, World]:
    return {name: World.load(ROOT / "worlds" / f"{name}.yaml") for name in SCENARIOS}


def scenario_run(world: World) -> Run:
    assert world.scenario is not None
    start, goal = world.scenario.start, world.scenario.goal
    middle = ((start.x + goal[0]) / 2.0, (start.y + goal[1]) / 2.0)
    return fake_run([(start.x, start.y), middle], touched=world.names[:2])


# -- footprints ------------------------------------------------------------------------------------------
def test_footprints_follow_the_real_outline_of_each_shape() -> None:
    world = World.from_yaml(
        """
format: 1
models:
- {name: turned, pose: [0, 0, 0.5, 0, 0, 0.7853981633974483], box: [2.0, 1.0, 1.0]}
- {name: lying_wall, pose: [5, 0, 0.1, 1.5707963267948966, 0, 0], box: [2.0, 0.2, 2.0]}
- {name: drum, pose: [0, 5, 0.5, 0, 0, 0], cylinder: {radius: 0.5, length: 1.0}}
- {name: log, pose: [5, 5, 0.3, 1.5707963267948966, 0, 0], cylinder: {radius: 0.3, length: 2.0}}
- {name: ball, pose: [-5, 0, 0.25, 0, 0, 0], sphere: {radius: 0.25}}
"""
    )
    prints = {fp.name: fp for fp in render.footprints(world)}
    assert prints["turned"].area == pytest.approx(2.0)
    assert prints["turned"].high[0] == pytest.approx(1.5 / math.sqrt(2))  # rotated 45 degrees
    assert prints["lying_wall"].area == pytest.approx(4.0, rel=1e-6)  # a 2 x 2 patch once laid down
    assert prints["drum"].area == pytest.approx(math.pi * 0.25, rel=0.01)
    assert prints["log"].area == pytest.approx(2.0 * 0.6, rel=0.01)  # a lying cylinder is a rectangle
    assert prints["ball"].area == pytest.approx(math.pi * 0.0625, rel=0.01)
    assert prints["turned"].top == pytest.approx(1.0)


def test_friction_and_motion_categories() -> None:
    world = World.from_yaml(
        """
format: 1
models:
- {name: rock, box: [1, 1, 1]}
- {name: crate, box: [1, 1, 1], static: false, mass: 5}
- {name: ice, box: [1, 1, 0.1], mu: 0.1}
- {name: carpet, box: [1, 1, 0.1], mu: 100}
"""
    )
    assert [render.category(m) for m in world] == ["static", "dynamic", "static", "static"]
    assert [render.friction(m) for m in world] == [None, None, "low", "high"]


# -- world pictures ----------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", SCENARIOS)
def test_world_picture_of_each_scenario(name: str, worlds: dict[str, World], tmp_path: Path) -> None:
    world = worlds[name]
    path = render.plot_world(world, [scenario_run(world)], path=tmp_path / f"{name}.png")
    assert path.stat().st_size > 10_000
    assert png_size(path) == render.WORLD_SIZE


@pytest.mark.parametrize("name", SCENARIOS)
def test_world_picture_draws_one_artist_per_model(name: str, worlds: dict[str, World]) -> None:
    """What keeps a picture cheap, counted instead of timed (no wall-clock or CPU-time assertion: they flake
    on a loaded machine): every model is one collection holding its footprint's polygons as they are (the
    ditch's 43 models are 1287 polygons), not one artist per polygon, and nothing else adds a collection."""
    import matplotlib.pyplot as plt

    world = worlds[name]
    prints = render.footprints(world)
    figure = render.draw_world(world, [scenario_run(world)])
    try:
        axes = figure.axes[0]
        assert len(axes.collections) == len(world.models)
        assert sorted(len(c.get_paths()) for c in axes.collections) == sorted(len(fp.polygons) for fp in prints)
        drawn = sum(len(path.vertices) for c in axes.collections for path in c.get_paths())
        assert drawn == sum(len(polygon) + 1 for fp in prints for polygon in fp.polygons)  # + 1: the closing vertex
        assert not axes.images  # the shipped worlds have no heightmap shading
    finally:
        plt.close(figure)


def test_world_picture_without_runs_or_scenario(tmp_path: Path) -> None:
    world = World.from_yaml("format: 1\nmodels:\n- {name: rock, box: [1, 1, 1]}\n")
    path = render.plot_world(world, path=tmp_path / "nested" / "rock.png")
    assert png_size(path) == render.WORLD_SIZE
    assert not list(path.parent.glob(".*tmp*")), "no temporary file is left behind"


# -- reduction and progress pictures -----------------------------------------------------------------------
def test_reduction_labels_never_overlap(worlds: dict[str, World]) -> None:
    import matplotlib.pyplot as plt

    world = worlds["ditch"]
    kept = world.names[::6]  # eight models spread over the world, some side by side
    figure = render.draw_reduction(world, kept, original_run=scenario_run(world), minimal_run=scenario_run(world))
    try:
        figure.canvas.draw()
        axes = figure.axes[0]
        labels = [text for text in axes.texts if text.get_bbox_patch() is not None]
        assert len(labels) == len(kept)
        boxes = [text.get_bbox_patch().get_window_extent() for text in labels]  # the drawn label boxes
        for index, box in enumerate(boxes):
            assert not any(box.overlaps(other) for other in boxes[index + 1 :]), labels[index].get_text()
        assert axes.get_xlabel() == "x (m)" and axes.get_ylabel() == "y (m)"
        assert axes.get_legend() is not None
    finally:
        plt.close(figure)


def test_reduction_pictures_in_an_artifacts_folder(worlds: dict[str, World], tmp_path: Path) -> None:
    world = worlds["rubble"]
    minimal = world.names[:3]
    reduction = fake_reduction(world, minimal)
    paths = ArtifactPaths(tmp_path)
    logged = [events.Start()] + [
        events.Probe(size=size, outcome=outcome, candidate=(), attempt=attempt) for attempt, (size, outcome)
        in enumerate([(18, "pass"), (18, "fail"), (9, "other"), (9, "fail"), (3, "fail"), (2, "error")])
    ]
    paths.log.write_text("".join(events.encode(event) + "\n" for event in logged))
    paths.summary.write_text(json.dumps({"reference_failure": {"signature": {"pose": [0, -1, 0.2, 0, 0, 0.3]}}}))
    written = pictures.write_reduction_pictures(world, reduction, paths)
    assert written == [paths.reduction_png, paths.progress_png]
    assert png_size(paths.reduction_png) == render.WORLD_SIZE
    assert png_size(paths.progress_png) == render.PROGRESS_SIZE
    assert min(p.stat().st_size for p in written) > 5_000
    assert picture_data.probe_sizes_from_log(paths.log)[:2] == [(1, 18, "pass"), (2, 18, "fail")]


def test_the_progress_note_of_a_resumed_reduction_says_which_probes_and_time_are_this_runs(
        worlds: dict[str, World]) -> None:
    """A rerun that resumes its log counts the earlier runs' probes: its wall time is this run's alone."""
    import dataclasses

    world = worlds["rubble"]
    fresh = dataclasses.replace(fake_reduction(world, world.names[:3]), probes=81, cache_hits=14, skipped=8,
                                wall_time=34.2, failure_rate=(5, 5))
    assert pictures._progress_note(fresh).splitlines() == [
        "81 probes (14 cached, 8 skipped)", "34 s wall time", "minimal world fails 5/5 seeds"]
    resumed = dataclasses.replace(fresh, resumed_probes=42, wall_time=13.5)
    assert pictures._progress_note(resumed).splitlines() == [
        "81 probes (42 in earlier runs, 14 cached, 8 skipped)", "14 s wall time in this run",
        "minimal world fails 5/5 seeds"]


def test_reduction_picture_with_both_runs(worlds: dict[str, World], tmp_path: Path) -> None:
    world = worlds["friction"]
    reduction = fake_reduction(world, world.names[:4])
    paths = ArtifactPaths(tmp_path)
    run = scenario_run(world)
    written = pictures.write_reduction_pictures(world, reduction, paths, original_run=run, minimal_run=run)
    assert [png_size(path) for path in written] == [render.WORLD_SIZE, render.PROGRESS_SIZE]


def test_failure_pose_outline_is_the_runs_own_robot_footprint() -> None:
    import dataclasses

    import matplotlib.pyplot as plt
    from matplotlib.patches import Polygon

    outline = render.robot_outline([1.0, 2.0, 0.1, 0.0, 0.0, math.pi / 2], (0.4, 0.3))
    assert np.allclose(outline, [[0.85, 2.2], [0.85, 1.8], [1.15, 1.8], [1.15, 2.2]])
    assert np.allclose(np.ptp(render.robot_outline([0, 0, 0], render.ROBOT_FOOTPRINT), axis=0), (0.99, 0.67))
    small = dataclasses.replace(fake_run([(0.0, 0.0), (3.0, 0.0)]), robot="diffbot", footprint=(0.45, 0.44))
    figure = render.draw_world(World(name="empty"), [small], failure_poses=[[1.0, 1.0, 0.0, 0.0, 0.0, 0.0]])
    try:
        outlines = [patch.get_xy() for patch in figure.axes[0].patches if isinstance(patch, Polygon)]
        assert len(outlines) == 2  # the run's failure pose and the extra pose, both the diffbot's size
        for points in outlines:
            assert np.allclose(np.ptp(points, axis=0), (0.45, 0.44))
    finally:
        plt.close(figure)


def test_progress_picture_of_a_reduction_that_removed_nothing(tmp_path: Path) -> None:
    path = render.plot_progress([(0, 1)], probes=0, path=tmp_path / "progress.png")
    assert png_size(path) == render.PROGRESS_SIZE


def test_documentation_pictures_are_small() -> None:
    images = sorted((ROOT / "docs" / "images").glob("*.png"))
    for image in images:
        assert image.stat().st_size < 200_000, f"{image} is larger than 200 KB"
    for animation in sorted((ROOT / "docs" / "images").glob("*.gif")):
        assert animation.stat().st_size < 400_000, f"{animation} is larger than 400 KB"


def test_probe_failure_poses_are_coloured_by_outcome_with_a_legend(worlds: dict[str, World]) -> None:
    poses = [[1.0, 0.0, 0.2, 0, 0, 0], [4.0, 1.0, 0.2, 0, 0, 1.0], [6.0, -1.0, 0.2, 0, 0, 2.0]]
    figure = render.draw_world(worlds["ditch"], failure_poses=poses, failure_outcomes=["fail", "other", "fail"])
    try:
        axes = figure.axes[0]
        outlines = [patch for patch in axes.patches if type(patch).__name__ == "Polygon" and not patch.get_fill()]
        colours = sorted(tuple(round(c, 3) for c in patch.get_edgecolor()[:3]) for patch in outlines[-3:])
        red, orange = (0.839, 0.153, 0.157), (1.0, 0.498, 0.055)
        assert colours == sorted([red, red, orange])
        labels = [text.get_text() for text in axes.get_legend().get_texts()]
        assert "probe failed the same way (2)" in labels and "probe failed another way (1)" in labels
    finally:
        pyplot().close(figure)
    with pytest.raises(ValueError, match="2 entries for 3 failure poses"):
        render.draw_world(worlds["ditch"], failure_poses=poses, failure_outcomes=["fail", "other"])


def test_progress_steps_are_drawn_at_the_probe_that_justified_them(tmp_path: Path) -> None:
    """Each accepted step sits on the probe dot of the candidate it adopted (same numbering as the dots)."""
    from pytest_ddenv.reduce import Outcome, ProbeObservation, reduce

    names = tuple(f"m{i}" for i in range(12))

    def probe(candidate: tuple[str, ...], attempt: int) -> ProbeObservation:
        return ProbeObservation(Outcome.FAIL if {"m3", "m8"} <= set(candidate) else Outcome.PASS)

    log = tmp_path / "runs.jsonl"
    reduce(names, probe, partition="even", priority="sequential", deflake=1, log=log, failure_rate_runs=0)
    dots = picture_data.probe_sizes_from_log(log)
    steps = picture_data.steps_from_log(log)
    assert steps[0] == (0, 12) and steps[-1][1] == 2 and len(steps) > 2
    for number, size in steps[1:]:
        assert dots[number - 1] == (number, size, "fail")  # the dot just before the step is its own candidate


PARALLEL_LOG = [  # the journal of a reduction on 2 workers (the two-post gap world), in the order it was written
    ("start", ["a", "l", "c", "r", "b", "k"], None), *[("calibration", ["a", "l", "c", "r", "b", "k"], "fail")] * 3,
    ("reduce", ["l", "r", "k"], "fail"), ("reduce", ["a", "c", "b"], "pass"), ("reduce", ["l", "r", "k"], "fail"),
    ("accept", ["l", "r", "k"], None), ("step", ["l", "r", "k"], None),
    ("reduce", ["l", "r"], "fail"), ("reduce", ["l", "r"], "fail"), ("accept", ["l", "r"], None),
    ("reduce", ["k"], "pass"), ("reduce", ["k"], "pass"), ("reject", ["k"], None), ("step", ["l", "r"], None),
    ("reduce", ["r"], "other"), ("reduce", ["l"], "other"), ("reduce", ["r"], "fail"), ("reduce", ["l"], "pass"),
    ("reject", ["l"], None), ("reduce", ["r"], "other"), ("reject", ["r"], None),
]


def write_parallel_log(path: Path) -> None:
    logged: list[events.Event] = []
    for attempt, (kind, candidate, outcome) in enumerate(PARALLEL_LOG):
        if kind == "start":
            logged.append(events.Start(elements=tuple(candidate)))
        elif outcome is not None:
            logged.append(events.Probe(purpose=kind, candidate=tuple(candidate), size=len(candidate),
                                       outcome=outcome, attempt=attempt))
        elif kind == "step":
            logged.append(events.Step(candidate=tuple(candidate)))
        else:
            logged.append(events.Accept(candidate=tuple(candidate), reproduces=True, fails=2, runs=2)
                          if kind == "accept" else events.Reject(candidate=tuple(candidate), reproduces=False,
                                                                 fails=0, runs=2))
    path.write_text("".join(events.encode(event) + "\n" for event in logged))


def test_with_parallel_probes_a_step_sits_on_its_accepting_probe(tmp_path: Path) -> None:
    """On 2 workers the runs of another candidate of the round are logged between the run that decided a
    step and the step itself: the step is drawn on its own last same-failure run, not after them."""
    log = tmp_path / "runs.jsonl"
    write_parallel_log(log)
    dots = picture_data.probe_sizes_from_log(log)
    steps = picture_data.steps_from_log(log)
    for number, size in steps[1:]:
        assert dots[number - 1] == (number, size, "fail"), f"the step to {size} models is drawn at probe {number}"
    assert len(dots) == 15  # every probe of the reduction: 3 calibration runs of the original world, 12 others
    assert steps == [(0, 6), (6, 3), (8, 2)]


def test_same_failure_probes_whose_world_was_not_accepted_are_drawn_apart(tmp_path: Path) -> None:
    from pytest_ddenv.driver.picture_data import accepted_probes_from_log
    from pytest_ddenv.render.progress_chart import NOT_ACCEPTED

    log = tmp_path / "runs.jsonl"
    write_parallel_log(log)
    dots = picture_data.probe_sizes_from_log(log)
    accepted = accepted_probes_from_log(log)
    assert accepted == {1, 2, 3, 4, 6, 7, 8}  # ["r"] failed once (probe 13), and its world was rejected
    figure = render.draw_progress(picture_data.steps_from_log(log), probes=15, probe_sizes=dots, accepted=accepted)
    try:
        axes = figure.axes[0]
        hollow = next(c for c in axes.collections if c.get_gid() == "probes:fail-not-accepted")
        assert hollow.get_offsets().tolist() == [[13.0, 1.0]] and len(hollow.get_facecolors()) == 0
        assert NOT_ACCEPTED in [text.get_text() for text in axes.get_legend().get_texts()]
        assert axes.get_xlim()[1] >= 15
    finally:
        pyplot().close(figure)


def test_a_failure_found_by_an_assert_is_labelled_in_its_own_words(worlds: dict[str, World], tmp_path: Path) -> None:
    world = worlds["ditch"]
    run = fake_run([(0.0, 0.0), (3.0, 0.5)], failure=None)
    run = Run(**{**run.__dict__, "reached_goal": False, "goal_time": None})
    summary = tmp_path / "summary.json"
    summary.write_text(json.dumps({"reference_failure": {"exception_type": "AssertionError",
                                                         "location": "test_x.py:12", "signature": None}}))
    text = reference_text(summary)
    assert text == "AssertionError at test_x.py:12"
    figure = render.draw_reduction(world, world.names[:2], original_run=run, minimal_run=run, failure_text=text)
    try:
        labels = " ".join(t.get_text() for t in figure.axes[0].get_legend().get_texts()).replace("\n", " ")
        assert labels.count("AssertionError at test_x.py:12") == 2 and "no failure" not in labels
    finally:
        pyplot().close(figure)
    summary.write_text(json.dumps({"reference_failure": {"exception_type": "RobotFailure", "location": "x:1",
                                                         "signature": {"predicate": "stuck"}}}))
    assert reference_text(summary) is None  # a predicate's failure keeps the run's own words


def test_the_reference_failure_pose_is_read_from_the_summary(tmp_path: Path) -> None:
    summary = tmp_path / "summary.json"
    assert reference_pose(summary) is None  # no summary.json
    summary.write_text(json.dumps({"reference_failure": {"signature": {"pose": [1, 2, 0.1, 0, 0, 3]}}}))
    assert reference_pose(summary) == [1.0, 2.0, 0.1, 0.0, 0.0, 3.0]
    for damaged in ("{", "[]", '{"reference_failure": []}', '{"reference_failure": {"signature": null}}',
                    '{"reference_failure": {"signature": {"pose": "x y"}}}'):
        summary.write_text(damaged)
        assert reference_pose(summary) is None, damaged


def test_terrain_is_neutral_unless_its_friction_differs(worlds: dict[str, World]) -> None:
    ditch = worlds["ditch"]
    shown = render.frictions_shown(ditch, render.footprints(ditch))
    assert ditch.model("asphalt_plane").mu > 5 and shown["asphalt_plane"] is None  # both plateaus: mu 100
    assert shown["asphalt_plane_clone"] is None
    slippery = ditch.select(["asphalt_plane", "asphalt_plane_clone"])
    slippery = World(models=(slippery.models[0], replace_mu(slippery.models[1], 0.1)), scenario=ditch.scenario)
    shown = render.frictions_shown(slippery, render.footprints(slippery))
    assert shown == {"asphalt_plane": "high", "asphalt_plane_clone": "low"}  # what differs is shown
    friction_world = worlds["friction"]
    tiles = render.frictions_shown(friction_world, render.footprints(friction_world))
    assert tiles["grey_wall_clone_clone_5"] == "high"  # small patches keep their colour


def replace_mu(model, mu: float):
    import dataclasses

    return dataclasses.replace(model, mu=mu, mu2=mu)


def test_a_world_of_terrain_only_is_framed_on_its_scenario_and_runs(worlds: dict[str, World]) -> None:
    minimal = worlds["ditch"].select(["asphalt_plane", "asphalt_plane_clone"])  # two 20 m plateaus
    run = fake_run([(-3.0, -0.5), (1.4, -0.7)])
    figure = render.draw_world(minimal, [run])
    try:
        low, high = figure.axes[0].get_xlim()
        assert high - low < 15.0  # the start, the goal and the run; not the 40 m of terrain
        assert low < -3.0 and high > 3.7  # the start (x = -3) and the goal (x = 3.75) are in view
    finally:
        pyplot().close(figure)


@pytest.mark.parametrize("name", SCENARIOS)
def test_labels_never_hide_the_goal_or_a_failure_outline(name: str, worlds: dict[str, World]) -> None:
    import matplotlib.pyplot as plt

    world = worlds[name]
    run = scenario_run(world)
    figure = render.draw_world(world, [run])  # every model the run touched is labelled
    try:
        figure.canvas.draw()
        axes = figure.axes[0]
        labels = [text.get_bbox_patch().get_window_extent() for text in axes.texts if text.get_bbox_patch()]
        keep_clear = [patch.get_window_extent() for patch in axes.patches
                      if type(patch).__name__ == "Circle" or (type(patch).__name__ == "Polygon" and not patch.get_fill())]
        assert keep_clear and labels
        for label in labels:
            assert not any(label.overlaps(box) for box in keep_clear), name
    finally:
        plt.close(figure)


def test_failure_poses_without_a_run_are_outlined_with_the_worlds_own_robot() -> None:
    """`ddenv show` of a probe log draws the poses with the world's robot (here a URDF diffbot), not a Husky."""
    from pytest_ddenv.cli.show_command import _robot_footprint

    world = World.load(ROOT / "examples" / "robots" / "diffbot_world.yaml")
    footprint = _robot_footprint(world)
    assert footprint is not None and footprint != render.ROBOT_FOOTPRINT and footprint[0] < 0.8
    figure = render.draw_world(world, failure_poses=[[5.0, 0.0, 0.1, 0, 0, 0]], robot_footprint=footprint)
    try:
        (outline,) = [p for p in figure.axes[0].patches if type(p).__name__ == "Polygon" and not p.get_fill()]
        xy = np.asarray(outline.get_xy())[:4]
        assert np.allclose(xy[:, 0].max() - xy[:, 0].min(), footprint[0])  # yaw 0: its length along x
        assert np.allclose(xy[:, 1].max() - xy[:, 1].min(), footprint[1])
    finally:
        pyplot().close(figure)
