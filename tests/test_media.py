"""Animations and what they are drawn from: runs that record their full detail (real simulations, real
worker processes, real GIF files read back with imageio)."""

from __future__ import annotations

import functools
import json
import os
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from pytest_ddenv.media.animate import FPS, HEIGHT, HOLD_SECONDS, MIN_STEP, WIDTH, frame_times, write_animation
from pytest_ddenv.media.recording import recording_available
from pytest_ddenv.detail import recording_detail
from pytest_ddenv.execution import LocalPool
from pytest_ddenv.media.writer import (
    BackgroundMedia,
    MediaChoiceError,
    PendingMedia,
    Shown,
    media_choice,
    media_parts,
    records_runs,
    write_media,
)
from pytest_ddenv.oracle import PredicateSpec
from pytest_ddenv.driver.scenario_job import ScenarioJob
from pytest_ddenv.sim import Run, simulate
from pytest_ddenv.world import World

ROOT = Path(__file__).resolve().parent.parent
PREDICATES = (PredicateSpec("stuck", {"window": 5.0, "min_progress": 0.2}), PredicateSpec("high_centered", {}))
WORLDS = ("ditch", "rubble", "friction", "cul_de_sac")


def failing_run(name: str, *, detail: bool = True) -> tuple[World, Run]:
    world = World.load(ROOT / "worlds" / f"{name}.yaml")
    with recording_detail(detail):
        run = simulate(world, seed=0, predicates=[spec.build() for spec in PREDICATES])
    return world, run


def read_gif(path: Path) -> np.ndarray:
    import imageio.v3 as iio

    return iio.imread(path, index=None)


def border_is_red(frame: np.ndarray) -> bool:
    """The failure's red frame: both side edges red from top to bottom (a red floor tile is not both)."""
    edges = np.concatenate([frame[20:HEIGHT - 20, 1], frame[20:HEIGHT - 20, WIDTH - 2]]).astype(int)
    return bool(np.all((abs(edges[:, 0] - 214) < 30) & (abs(edges[:, 1] - 39) < 30) & (abs(edges[:, 2] - 40) < 30)))


# -- the detail a run records -------------------------------------------------------------------------------
def test_recording_detail_leaves_the_run_itself_unchanged() -> None:
    world, plain = failing_run("rubble", detail=False)
    _, detailed = failing_run("rubble")
    assert plain.detail is None and detailed.detail is not None
    assert plain.same_trajectory(detailed) and plain.failure == detailed.failure
    detail, samples = detailed.detail, len(detailed.times)
    moving = {model.name for model in world.models if model.dynamic}
    assert set(detail.bodies) == moving and all(poses.shape == (samples, 7) for poses in detail.bodies.values())
    assert detail.scan_ranges is not None and detail.scan_angles is not None
    assert detail.scan_ranges.shape == (samples, len(detail.scan_angles)) and len(detail.contacts) == samples
    assert detail.joints.shape[0] == samples
    touched = {point[0] for points in detail.contacts for point in points}
    assert touched & set(detailed.touched), "the contact points name the models the run touched"


def test_a_probe_asked_to_record_brings_back_the_detail_from_a_worker_process() -> None:
    world = World.load(ROOT / "worlds" / "ditch.yaml").select(["asphalt_plane", "asphalt_plane_clone"])
    with LocalPool(ScenarioJob(PREDICATES), 1) as pool:
        recorded = pool.call(world, 0, record=True)
        plain = pool.call(world, 0)
    assert recorded.run.detail is not None and plain.run.detail is None
    assert recorded.run.same_trajectory(plain.run)


# -- animations ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", WORLDS)
def test_animation_frames_size_and_the_failure_moment(name: str, tmp_path: Path) -> None:
    world, run = failing_run(name)
    info = write_animation(tmp_path / f"{name}.gif", world, run, title=name)
    frames = read_gif(info.path)
    assert frames.shape[1:3] == (HEIGHT, WIDTH)
    assert len(frames) == info.frames and 2 <= info.frames <= 60
    assert info.size_bytes == info.path.stat().st_size < 3_000_000
    assert info.times[0] == run.times[0] and info.times[-1] == run.times[-1]
    assert not border_is_red(frames[0])
    if run.failure is not None:
        assert info.times[0] <= info.failure_time <= info.times[-1], "the failure moment is inside the clip"
        first_red = next(i for i, frame in enumerate(frames) if border_is_red(frame))
        assert info.times[first_red] == pytest.approx(run.failure.time, abs=0.06)
        assert all(border_is_red(frame) for frame in frames[first_red:])
    else:
        assert not any(border_is_red(frame) for frame in frames)
    assert len({frame.tobytes() for frame in frames[:info.frames]}) > info.frames // 2, "the picture moves"


def test_a_gif_has_a_frame_every_min_step_shown_at_fps_in_the_frame_size(tmp_path: Path) -> None:
    from PIL import Image

    world, run = failing_run("friction")
    info = write_animation(tmp_path / "friction.gif", world, run)
    steps = int((run.times[-1] - run.times[0]) / MIN_STEP)
    assert info.frames == len(frame_times(run)) and steps + 1 <= info.frames <= steps + 3  # + the failure, the end
    with Image.open(info.path) as gif:
        assert gif.size == (WIDTH, HEIGHT) and gif.n_frames == info.frames
        durations = []
        for index in range(gif.n_frames):
            gif.seek(index)
            durations.append(gif.info["duration"])
    assert durations[:-1] == [1000 / FPS] * (info.frames - 1) and durations[-1] == 1000 * HOLD_SECONDS


def test_frames_are_spread_over_the_run_and_include_the_failure() -> None:
    _, run = failing_run("ditch")
    indices = frame_times(run, max_frames=10)
    assert indices[0] == 0 and indices[-1] == len(run.times) - 1 and len(indices) <= 12
    assert run.failure is not None
    assert any(abs(run.times[i] - run.failure.time) < 0.06 for i in indices)


def test_a_failure_found_after_the_run_is_marked_on_the_last_frame_only(tmp_path: Path) -> None:
    world = World.load(ROOT / "worlds" / "ditch.yaml")
    with recording_detail():
        run = simulate(world, seed=0, timeout=6.0)  # no predicate: the test's own assert fails afterwards
    assert run.failure is None
    info = write_animation(tmp_path / "assert.gif", world, run, failure_text="AssertionError at test_x.py:12")
    frames = read_gif(info.path)
    assert border_is_red(frames[-1]) and not any(border_is_red(frame) for frame in frames[:-1])


def test_a_run_without_detail_is_animated_with_the_models_where_they_started(tmp_path: Path) -> None:
    world, run = failing_run("ditch", detail=False)
    info = write_animation(tmp_path / "plain.gif", world, run)
    assert len(read_gif(info.path)) == info.frames


@pytest.mark.slow  # a media helper process: the full tier only
@pytest.mark.pybullet  # pybullet's renderer; MuJoCo's helper: tests/sim_mujoco/test_mujoco_media.py
def test_an_animation_rendered_in_a_helper_process_is_the_same_file(tmp_path: Path) -> None:
    world, run = failing_run("ditch")
    shown = [Shown("original", world, run, True), Shown("minimal", world.select(world.names[:5]), run, True)]
    (tmp_path / "here").mkdir()
    (tmp_path / "helped").mkdir()
    here = PendingMedia(tmp_path / "here", shown, failure_text="stuck").finish()
    helped = PendingMedia(tmp_path / "helped", shown, failure_text="stuck", helper=True)
    assert helped.elsewhere is not None  # the first animation went to a helper process
    beside = helped.finish()
    assert [path.name for path in beside.paths] == [path.name for path in here.paths]
    for name in ("original.gif", "minimal.gif"):
        assert (tmp_path / "helped" / name).read_bytes() == (tmp_path / "here" / name).read_bytes()
    assert beside.info["original.gif"]["frames"] == here.info["original.gif"]["frames"]


@pytest.mark.slow  # a media helper process: the full tier only
@pytest.mark.pybullet  # pybullet's renderer; MuJoCo's helper: tests/sim_mujoco/test_mujoco_media.py
def test_an_animation_whose_helper_dies_is_rendered_here(tmp_path: Path) -> None:
    world, run = failing_run("ditch")
    shown = [Shown("original", world, run, True), Shown("minimal", world, run, True)]
    pending = PendingMedia(tmp_path, shown, helper=True)
    assert pending.elsewhere is not None
    _, executor, _ = pending.elsewhere
    for process in list(executor._processes.values()):  # the helper is killed mid-render
        process.kill()
    written = pending.finish()
    assert [path.name for path in written.paths][:2] == ["original.gif", "minimal.gif"]
    assert len(read_gif(tmp_path / "original.gif")) == written.info["original.gif"]["frames"]


@pytest.mark.slow  # a media process: the full tier only
@pytest.mark.pybullet
def test_media_made_in_the_background_are_the_files_made_here(tmp_path: Path) -> None:
    world, run = failing_run("ditch")
    shown = [Shown("minimal", world, run, True)]
    (tmp_path / "here").mkdir()
    (tmp_path / "later").mkdir()
    here = write_media(tmp_path / "here", shown, failure_text="stuck", media="pictures,animations")
    later = BackgroundMedia(tmp_path / "later", shown, failure_text="stuck", media="pictures,animations")
    assert later.expected_paths() == [tmp_path / "later" / "minimal.gif"]
    written = later.finish()
    assert later.process.exitcode == 0 and later.finish() is written  # waited for once, no zombie
    assert [path.name for path in written.paths] == [path.name for path in here.paths] == ["minimal.gif"]
    assert (tmp_path / "later" / "minimal.gif").read_bytes() == (tmp_path / "here" / "minimal.gif").read_bytes()


@pytest.mark.slow  # a media process: the full tier only
@pytest.mark.pybullet
def test_media_whose_background_process_dies_are_made_here(tmp_path: Path) -> None:
    world, run = failing_run("ditch")
    later = BackgroundMedia(tmp_path, [Shown("minimal", world, run, True)], media="pictures,animations")
    later.process.kill()
    with pytest.warns(UserWarning, match=r"ddenv: the media process \d+ ended with status -9; making the media"):
        written = later.finish()
    assert [path.name for path in written.paths] == ["minimal.gif"] and len(read_gif(tmp_path / "minimal.gif")) > 2


def background_pictures(directory: Path) -> tuple[functools.partial[list[Path]], list[Path]]:
    """The pictures of a rubble reduction to 3 models (a real drawing, picklable), and the files it writes."""
    from pytest_ddenv.driver import pictures
    from pytest_ddenv.driver.artifacts import ArtifactPaths
    from pytest_ddenv.reduce import Reduction

    world, run = failing_run("rubble")
    reduction = Reduction(
        original=world.names, minimal=world.names[:3], kept=(), probes=4, cache_hits=0, skipped=0, errors=0,
        steps=((0, len(world)), (3, 3)), one_minimal=True, incomplete_reason=None, failure_rate=(5, 5),
        wall_time=1.0, partition="model2model", priority="avg-trajectory", granularity="ddmin", deflake=3, seed=0)
    paths = ArtifactPaths(directory)
    return (functools.partial(pictures.write_reduction_pictures, world, reduction, paths, original_run=run,
                              minimal_run=run), [paths.reduction_png, paths.progress_png])


def ditch_media_with_pictures(directory: Path) -> tuple[BackgroundMedia, list[Path]]:
    """The ditch's minimal GIF made in a background process that draws the pictures first, and their paths."""
    world, run = failing_run("ditch")
    draw, expected = background_pictures(directory)
    return BackgroundMedia(directory, [Shown("minimal", world, run, True)], media="pictures,animations",
                           pictures=draw, picture_paths=expected), expected


@pytest.mark.slow  # a media process: the full tier only
@pytest.mark.pybullet
def test_pictures_are_drawn_in_the_background_process_before_the_media(tmp_path: Path) -> None:
    later, expected = ditch_media_with_pictures(tmp_path)
    assert later.expected_paths() == [*expected, tmp_path / "minimal.gif"]
    written = later.finish()
    assert later.process.exitcode == 0 and written.pictures == expected and written.picture_seconds > 0
    assert [path.name for path in written.paths] == ["minimal.gif"]
    assert all(path.stat().st_size > 5_000 for path in later.expected_paths())


@pytest.mark.slow  # a media process: the full tier only
@pytest.mark.pybullet
def test_a_killed_background_process_loses_none_of_the_pictures_and_media_it_promised(tmp_path: Path) -> None:
    later, expected = ditch_media_with_pictures(tmp_path)
    later.process.kill()
    with pytest.warns(UserWarning, match=r"ddenv: the media process \d+ ended with status -9; making the media"):
        written = later.finish()
    assert [*written.pictures, *written.paths] == later.expected_paths()
    assert all(path.stat().st_size > 5_000 for path in later.expected_paths())


@pytest.mark.slow  # a media process: the full tier only
@pytest.mark.pybullet
def test_a_medium_that_fails_in_the_background_is_a_warning_here(tmp_path: Path) -> None:
    world, run = failing_run("ditch")
    later = BackgroundMedia(tmp_path / "missing", [Shown("minimal", world, run, True)], media="pictures,animations")
    with pytest.warns(UserWarning, match=r"ddenv: minimal.gif not written: "):
        written = later.finish()
    assert written.paths == [] and later.process.exitcode == 0


# -- the media setting --------------------------------------------------------------------------------------
def test_media_choice_reads_the_option_then_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("DDENV_MEDIA", raising=False)
    assert media_choice(None, "--x") == "all" and media_choice("Pictures", "--x") == "pictures"
    monkeypatch.setenv("DDENV_MEDIA", "none")
    assert media_choice(None, "--x") == "none" and media_choice("all", "--x") == "all"
    monkeypatch.setenv("DDENV_MEDIA", "movies")
    with pytest.raises(MediaChoiceError, match=r"\$DDENV_MEDIA: expected one of all, pictures, none, got 'movies'"):
        media_choice(None, "--x")


def test_a_bad_media_option_is_one_usage_error(pytester: pytest.Pytester) -> None:
    pytester.makepyfile("def test_nothing():\n    pass\n")
    result = pytester.runpytest_subprocess("--ddenv-media", "movies")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines(["*--ddenv-media: expected one of all, pictures, none, got 'movies'*"])


def test_a_media_list_picks_and_always_brings_the_pictures(monkeypatch: pytest.MonkeyPatch) -> None:
    assert media_choice("mcap", "--x") == "pictures,mcap"
    assert media_choice(" MCAP, pictures ", "--x") == "pictures,mcap"
    if recording_available():  # rerun-sdk (not in the lowest-versions tier: .ci/lowest)
        assert media_choice("rrd,animations", "--x") == "pictures,animations,rrd"
    else:
        with pytest.raises(MediaChoiceError, match="needs rerun-sdk"):
            media_choice("rrd,animations", "--x")
    assert media_parts("all") == {"pictures", "animations", "rrd", "mcap"} and media_parts("none") == set()
    assert media_parts("pictures,mcap") == {"pictures", "mcap"}
    assert records_runs("all") and records_runs("pictures,mcap") and records_runs("pictures,animations")
    assert not records_runs("pictures") and not records_runs("none")
    for bad in ("none,mcap", "pictures,movies", "pictures,"):
        with pytest.raises(MediaChoiceError, match=r"--x: expected one of all, pictures, none, got .* \(or a "
                                                   r"comma-separated list of pictures, animations, rrd, mcap\)"):
            media_choice(bad, "--x")


def test_a_recording_named_without_its_package_is_an_error_and_all_leaves_it_out(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setitem(sys.modules, "foxglove", None)
    with pytest.raises(MediaChoiceError, match=r"--ddenv-media: 'mcap' was asked for, but the MCAP recording "
                                               r"needs foxglove-sdk: pip install 'pytest-ddenv\[mcap\]'"):
        media_choice("pictures,mcap", "--ddenv-media")
    monkeypatch.setitem(sys.modules, "rerun", None)
    with pytest.raises(MediaChoiceError, match=r"'rrd' was asked for, but .*pytest-ddenv\[viewer\]"):
        media_choice("rrd", "--ddenv-media")
    assert media_choice("all", "--ddenv-media") == "all"
    world, run = failing_run("ditch", detail=False)
    written = write_media(tmp_path, [Shown("minimal", world, run, True)], media="all")
    assert [path.name for path in written.paths] == ["minimal.gif"]


def test_mcap_asked_for_without_foxglove_sdk_stops_the_session(pytester: pytest.Pytester,
                                                               monkeypatch: pytest.MonkeyPatch) -> None:
    blocked = pytester.mkdir("blocked") / "foxglove"
    blocked.mkdir()
    (blocked / "__init__.py").write_text("raise ImportError('not installed here')\n")
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(filter(None, [str(blocked.parent),
                                                                  os.environ.get("PYTHONPATH")])))
    pytester.makepyfile("def test_nothing():\n    pass\n")
    result = pytester.runpytest_subprocess("--ddenv-media", "pictures,mcap")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    assert result.stderr.lines[0] == ("ERROR: --ddenv-media: 'mcap' was asked for, but the MCAP recording needs "
                                      "foxglove-sdk: pip install 'pytest-ddenv[mcap]'")
    assert pytester.runpytest_subprocess("--ddenv-media", "all").ret == pytest.ExitCode.OK


def test_the_media_chosen_are_the_files_written(tmp_path: Path) -> None:
    pytest.importorskip("foxglove")
    world, run = failing_run("ditch", detail=False)
    shown = [Shown("minimal", world, run, True)]
    written = write_media(tmp_path, shown, media=media_choice("mcap", "--x"))
    assert [path.name for path in written.paths] == ["recording.mcap"] == sorted(p.name for p in tmp_path.iterdir())
    assert written.info["recording.mcap"]["messages"] > len(run.times)
    assert write_media(tmp_path / "none", shown, media="pictures").paths == []


TEST = '''
import pytest

@pytest.mark.ddenv(world="worlds/ditch.yaml", partition="model2model", priority="avg-trajectory")
@pytest.mark.robot_failure("stuck", window=5.0, min_progress=0.2)
def test_ditch(robot_world):
    assert robot_world.run().reached_goal
'''


@pytest.mark.slow
def test_a_reduction_leaves_animations_counted_runs_and_an_inline_html_animation(pytester: pytest.Pytester) -> None:
    shutil.copytree(ROOT / "worlds", pytester.path / "worlds")
    pytester.makepyfile(test_ditch=TEST)
    result = pytester.runpytest_subprocess("--ddenv-reduce", "--ddenv-media", "all", "--html=report.html",
                                           "--self-contained-html", "--junitxml=junit.xml",
                                           "-o", "junit_logging=system-out")
    result.assert_outcomes(failed=1)
    (folder,) = (pytester.path / "ddenv-artifacts").iterdir()
    for name in ("original.gif", "minimal.gif"):
        frames = read_gif(folder / name)
        assert len(frames) > 2 and border_is_red(frames[-1])
    records = [json.loads(line) for line in (folder / "runs.jsonl").read_text().splitlines()]
    recordings = [r for r in records if r.get("event") == "probe" and r.get("purpose") == "recording"]
    assert len(recordings) == 1 and recordings[0]["outcome"] == "fail", "one recorded run of the minimal world"
    summary = json.loads((folder / "summary.json").read_text())
    logged = sum(1 for r in records if r.get("event") == "probe")  # + speculative probes cancelled unlogged
    assert summary["simulations"] >= logged and set(summary["media"]["files"]) >= {"original.gif", "minimal.gif"}
    timings = summary["timings"]  # the media were made after the summary, beside the rest, and waited for
    assert set(timings) >= {"test_run", "pool_start", "confirmation", "reduction", "recording_runs", "files",
                            "pictures_background", "media", "media_wait"}  # the pictures too, in the background
    assert "pictures" not in timings and (folder / "reduction.png").is_file() and (folder / "progress.png").is_file()
    assert timings["media"] == summary["media"]["seconds"] > 0 and timings["media_wait"] >= 0  # (how long: no
    # assertion: the wait includes the process's start on a machine of any load)
    html = (pytester.path / "report.html").read_text()
    assert "image/gif" in html and "minimal.gif" in html and "original.gif" in html
    xml = (pytester.path / "junit.xml").read_text()
    assert f"[[ATTACHMENT|{folder / 'minimal.gif'}]]" in xml and "original.gif" in xml
    assert f"[[ATTACHMENT|{folder / 'reduction.png'}]]" in xml and "reduction.png" in html
