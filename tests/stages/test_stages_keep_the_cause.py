"""The stages keep the cause, and the pictures of their worlds tell the truth (issue 27, points 4 and 5): real
reductions through `ddenv reduce` (one worker: in this process, so the pictures' figures can be read)."""

from __future__ import annotations

import json
import math
import textwrap
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pytest_ddenv.cli.main import main
from pytest_ddenv.render import progress_chart, world_picture
from pytest_ddenv.stages.structure import clearance
from pytest_ddenv.world import World

pytestmark = pytest.mark.slow  # real reductions: the full tier only

POST_GAP = textwrap.dedent(
    """\
    format: 1
    name: post_gap
    scenario:
      start: {x: 0.0, y: 0.0, yaw: 0.0}
      goal: {x: 8.0, y: 0.0}
      timeout: 30
    models:
      - {name: crate_a, pose: [-3, 3, 0.25], box: [0.5, 0.5, 0.5]}
      - {name: post_left, pose: [4.2, 0.45, 0.5], cylinder: {radius: 0.15, length: 1.0}}
      - {name: cone, pose: [1.0, -3.0, 0.2], sphere: {radius: 0.2}}
      - {name: post_right, pose: [4.2, -0.45, 0.5], cylinder: {radius: 0.15, length: 1.0}}
      - {name: crate_b, pose: [-2, -4, 0.25], box: [0.5, 0.5, 0.5]}
      - {name: cable_cover, pose: [2.0, 0.0, 0.02], box: [0.3, 3.0, 0.04]}
    """
)
"""Two posts 0.6 m apart across the path: the Husky (0.67 m wide) is caught in the gap between them."""
STUCK = "stuck:window=3,min_progress=0.2"
HUSKY_WIDTH = 0.67


def drawn(figure: Any) -> dict[str, Any]:
    """What a picture's figure draws: its title, the runs' trajectories (legend label, points), its markers
    without lines (points), its scatters (points and whether they are filled), and the x range."""
    from matplotlib.collections import PathCollection

    axes = figure.axes[0]
    runs = [(str(line.get_label()), np.column_stack(line.get_data()).astype(float)) for line in axes.get_lines()
            if str(line.get_label()).startswith("seed ")]
    markers = [np.column_stack(line.get_data()).astype(float) for line in axes.get_lines()
               if line.get_marker() == "o" and line.get_linestyle() == "None"]
    scatters = [(np.asarray(c.get_offsets(), dtype=float), len(c.get_facecolors()) > 0,
                 tuple(np.round((c.get_facecolors() if len(c.get_facecolors()) else c.get_edgecolors())[0][:3], 3)))
                for c in axes.collections if isinstance(c, PathCollection)]
    halos = [(tuple(np.round(c.get_edgecolors()[0][:3], 3)), str(c.get_linestyle()[0]), c.get_gid())
             for c in axes.collections if type(c).__name__ == "PatchCollection" and len(c.get_facecolors()) == 0]
    legend = axes.get_legend()
    return {"title": axes.get_title(), "runs": runs, "markers": markers, "scatters": scatters, "halos": halos,
            "legend": [] if legend is None else [text.get_text() for text in legend.get_texts()],
            "xlim": axes.get_xlim()}


@pytest.fixture(scope="module")
def pictures() -> Iterator[dict[str, dict[str, Any]]]:
    """The figures the reductions of this module draw, by file name (read before they are saved)."""
    seen: dict[str, dict[str, Any]] = {}
    with pytest.MonkeyPatch.context() as patch:
        for module in (world_picture, progress_chart):
            real = module.save

            def save(figure: Any, path: str | Path, real: Any = real) -> Path:
                seen[Path(path).name] = drawn(figure)
                return real(figure, path)  # type: ignore[no-any-return]

            patch.setattr(module, "save", save)
        yield seen


def reduce(folder: Path, world_text: str, *options: str) -> dict[str, Any]:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "world.yaml").write_text(world_text)
    code = main(["reduce", str(folder / "world.yaml"), "--workers", "1", "--out", str(folder / "out"), "-q",
                 *options])
    assert code == 0  # reduced
    return json.loads((folder / "out" / "summary.json").read_text())


@pytest.fixture(scope="module")
def post_gap(tmp_path_factory: pytest.TempPathFactory, pictures: dict[str, dict[str, Any]]
             ) -> tuple[dict[str, Any], Path, dict[str, dict[str, Any]]]:
    """The two-post gap reduced with every stage (summary, artifacts folder, pictures drawn)."""
    folder = tmp_path_factory.mktemp("post_gap")
    summary = reduce(folder, POST_GAP, "-p", STUCK, "--stages", "all", "--media", "pictures")
    return summary, folder / "out", dict(pictures)


def stage(summary: dict[str, Any], name: str) -> dict[str, Any]:
    return next(result for result in summary["stages"]["results"] if result["stage"] == name)


def test_two_posts_that_form_a_gap_still_form_it_after_the_stages(post_gap: tuple[dict[str, Any], Path, Any]) -> None:
    summary, out, _ = post_gap
    assert summary["minimal_models"] == ["post_left", "post_right"]
    simplified = World.load(out / "simplified.yaml")
    left, right = simplified.model("post_left"), simplified.model("post_right")
    gap = clearance(left, right, simplified.source)
    assert 0.02 <= gap < HUSKY_WIDTH, f"the posts no longer form a gap narrower than the robot: {gap:.2f} m"
    attributes = stage(summary, "attributes")
    refused = attributes["different_structure"]
    assert refused and all("a different structure" in entry["why"] for entry in refused)
    assert any("not applied: it changes post_left and post_right from a 0.60 m gap" in finding
               for finding in attributes["findings"])
    skipped = [json.loads(line) for line in (out / "runs.jsonl").read_text().splitlines()]
    assert any(r.get("event") == "skip" and "a different structure" in r.get("reason", "") for r in skipped)


def test_the_moved_start_is_written_rounded(post_gap: tuple[dict[str, Any], Path, Any]) -> None:
    summary, out, _ = post_gap
    time = stage(summary, "time")
    assert time["start"] != [0.0, 0.0, 0.0, 0.0, 0.0, 0.0], "the time stage moved the start"
    start = World.load(out / "simplified.yaml").scenario.start  # type: ignore[union-attr]
    for value in (start.x, start.y):
        assert abs(value * 10 - round(value * 10)) < 1e-9, f"{value} is not on the 0.1 m grid"
    assert abs(math.degrees(start.yaw) / 5 - round(math.degrees(start.yaw) / 5)) < 1e-6
    text = (out / "simplified.yaml").read_text()
    start_line = next(line for line in text.splitlines() if "start:" in line)
    assert len(start_line) < 50, start_line  # "start: {x: 1.5, y: 0.1, yaw: 0.0}", no 16-digit floats


@pytest.mark.pybullet  # the stage's simplified world is tuned to fail in PyBullet's physics
def test_the_simplified_world_is_checked_1_minimal_with_counted_logged_runs(
        post_gap: tuple[dict[str, Any], Path, Any]) -> None:
    summary, out, _ = post_gap
    staged = summary["stages"]
    assert staged["final_one_minimal"] is True
    check = stage(summary, "one-minimal")
    assert check["one_minimal"] is True and sorted(check["needed"]) == ["post_left", "post_right"]
    assert check["findings"][0].startswith("the simplified world is 1-minimal")
    records = [json.loads(line) for line in (out / "runs.jsonl").read_text().splitlines()]
    runs = [r for r in records if r.get("stage") == "one-minimal" and r.get("event") == "probe"]
    assert len(runs) == check["simulations"] >= 2  # one removal of each post at least, every run logged
    assert {r["candidate"][0].split(" (world ")[0] for r in runs} == {"without post_left", "without post_right"}
    assert staged["simulations"] >= sum(result["simulations"] for result in staged["results"])


def test_simplified_png_draws_a_run_of_the_simplified_world_from_its_own_start(
        post_gap: tuple[dict[str, Any], Path, Any]) -> None:
    _, out, figures = post_gap
    simplified = World.load(out / "simplified.yaml")
    assert simplified.scenario is not None
    picture = figures["simplified.png"]
    assert len(picture["runs"]) == 1
    _, points = picture["runs"][0]
    start = simplified.scenario.start
    assert np.hypot(points[0, 0] - start.x, points[0, 1] - start.y) < 0.1, "the run starts at the world's start"


def test_passing_png_draws_a_passing_run_of_the_passing_world(post_gap: tuple[dict[str, Any], Path, Any]) -> None:
    summary, out, figures = post_gap
    assert stage(summary, "passing")["found"] is True
    picture = figures["passing.png"]
    assert picture["runs"], picture["title"]
    for label, _ in picture["runs"]:
        assert "reached the goal" in label and "stuck" not in label, label


RED = (0.839, 0.153, 0.157)
"""The colour of a probe that failed the same way."""


@pytest.mark.pybullet  # the probes' sizes and times are PyBullet's runs of this world
def test_progress_steps_sit_on_their_accepting_probe_and_the_axis_reaches_the_last(
        post_gap: tuple[dict[str, Any], Path, Any]) -> None:
    summary, _, figures = post_gap
    progress = figures["progress.png"]
    dots = np.vstack([points for points, _, _ in progress["scatters"]])
    assert progress["xlim"][1] >= max(dots[:, 0].max(), summary["probes"])  # the axis reaches the last probe
    accepted_fails = np.vstack([points for points, filled, color in progress["scatters"] if filled and color == RED])
    (steps,) = progress["markers"]
    for x, size in steps:
        assert any(fx == x and fs == size for fx, fs in accepted_fails), f"no same-failure probe of size {size} at {x}"


WALL_WITH_TIMEOUT = World.load(Path(__file__).resolve().parents[1] / "data" / "long_wall.yaml").without(
    ["ball"]).to_yaml()


def test_the_passing_world_is_searched_with_the_original_start_and_time_limit(tmp_path: Path) -> None:
    """The time stage shortens the drive to a few seconds; without the wall the robot then runs out of time
    (the `timeout` predicate: another failure) and no world would pass. The passing stage searches with the
    original start and time limit, where "without wall" passes (the models stage's log already says so)."""
    summary = reduce(tmp_path, WALL_WITH_TIMEOUT, "-p", STUCK, "-p", "timeout", "--stages", "models,time,passing",
                     "--media", "pictures", "--stage-probes", "40")
    time = stage(summary, "time")
    assert time["timeout"] < 40 and time["start"][0] > 1.0  # shortened
    found = stage(summary, "passing")
    assert found["found"] is True and found["difference"] == ["without wall"], found["findings"]
    passing = World.load(tmp_path / "out" / "passing.yaml")
    assert passing.scenario is not None
    assert passing.scenario.timeout == 40 and (passing.scenario.start.x, passing.scenario.start.y) == (0.0, 0.0)


def test_the_time_stage_shortens_the_ditch_without_media(tmp_path: Path) -> None:
    """--ddenv-media none makes no picture run of the minimal world: the time stage takes its path from a
    failing run of the minimal world the stages simulate anyway (its fresh runs)."""
    ditch = Path(__file__).parents[2] / "worlds" / "ditch.yaml"
    summary = reduce(tmp_path, ditch.read_text(), "-p", "stuck:window=5,min_progress=0.2", "--stages", "models,time",
                     "--media", "none")
    time = stage(summary, "time")
    assert not any(finding.startswith("not shortened") for finding in time["findings"]), time["findings"]
    assert time["points"] >= 2


PAD_AND_WALL = textwrap.dedent(
    """\
    format: 1
    name: pad_and_wall
    scenario:
      start: {x: 0.0, y: 0.0, yaw: 0.0}
      goal: {x: 8.0, y: 0.0}
      timeout: 30
    models:
      - {name: start_pad, pose: [0, 0, 0.02], box: [2.0, 2.0, 0.04]}
      - {name: crate, pose: [-3, 3, 0.25], box: [0.5, 0.5, 0.5]}
      - {name: wall, pose: [4.0, 0, 0.5], box: [0.3, 4.0, 1.0]}
      - {name: post, pose: [2, 5, 0.5], cylinder: {radius: 0.2, length: 1.0}}
    """
)


def test_a_model_kept_by_a_precondition_is_drawn_in_its_own_style(
        tmp_path: Path, pictures: dict[str, dict[str, Any]]) -> None:
    """The pad under the robot's start is kept by a precondition, not shown needed: reduction.png draws it
    apart from the wall the failure needs, with a legend entry that says so."""
    summary = reduce(tmp_path, PAD_AND_WALL, "-p", STUCK, "--stages", "models", "--media", "pictures")
    assert summary["minimal_models"] == ["start_pad", "wall"]
    assert [entry["model"] for entry in summary["precondition_kept"]] == ["start_pad"]
    picture = pictures["reduction.png"]
    legend = [" ".join(text.split()) for text in picture["legend"]]
    assert "kept by a precondition (not shown needed for the failure)" in legend, legend
    styles = {(color, style) for color, style, _ in picture["halos"]}
    assert len(picture["halos"]) == 2 and len(styles) == 2, picture["halos"]
    assert {gid for _, _, gid in picture["halos"]} == {"precondition:start_pad", "needed:wall"}


def test_the_explain_stage_simulates_a_precondition_kept_model_the_reduction_no_longer_checks(tmp_path: Path) -> None:
    """Issue 33: the reduction does not pay for the check without the precondition-kept pad (information only);
    the explain stage, when asked for, runs the final world without the pad (its precondition bypassed)."""
    summary = reduce(tmp_path, PAD_AND_WALL, "-p", STUCK, "--stages", "models,explain", "--media", "none")
    assert summary["minimal_models"] == ["start_pad", "wall"]
    assert summary["without_precondition_kept"] is None, "not the reduction's any more"
    entries = {entry["element"]: entry for entry in stage(summary, "explain")["elements"]}
    pad = entries["start_pad"]
    assert pad["source"] == "simulated: the final world without it (the precondition that kept it bypassed)", pad
    assert pad["same"] + pad["pass"] + pad["other"] >= 1, pad
    assert entries["wall"]["source"].startswith("log:"), "the wall's removal was decided by the reduction"
