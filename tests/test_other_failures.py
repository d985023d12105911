"""The other failures a reduction meets (`pytest_ddenv.driver.other_failures`): grouped from the run log, reported,
their smallest worlds kept as `other-<k>.yaml` (`--ddenv-keep-other`, `ddenv reduce --keep-other`).

The grouping runs on synthetic log records; one real `ddenv reduce` of the rubble scenario (slow) keeps two
other failures and replays the first.
"""

from __future__ import annotations

import dataclasses
import json
import shlex
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import pytest

from pytest_ddenv.cli import main as cli
from pytest_ddenv.driver.artifacts import ArtifactPaths, write_other_worlds
from pytest_ddenv.driver.other_failures import OtherFailure, other_failures
from pytest_ddenv.reduce import Reduction, events
from pytest_ddenv.driver.report import Cost, ReductionReport, ReportFiles
from pytest_ddenv.driver.report_text import other_failure_lines, result_lines
from pytest_ddenv.world import World

ROOT = Path(__file__).resolve().parent.parent
STUCK = "stuck:window=5,min_progress=0.2"


def probe(candidate: Sequence[str], *, predicate: str = "flipped", at: tuple[float, float, float] = (0.0, 0.0, 0.0),
          touched: Sequence[str] = (), time: float = 4.0, outcome: str = "other", attempt: int = 0,
          seed: int | None = 0, stage: str | None = None, purpose: str = "reduce") -> events.Probe:
    """A probe event of the run log, as the engine writes it (`signature_record` for a predicate failure)."""
    return events.Probe(
        purpose=purpose, candidate=tuple(candidate), size=len(candidate), attempt=attempt, seed=seed,
        outcome=outcome, stage=stage,
        signature={"predicate": predicate, "time": time, "pose": [*at, 0.0, 0.0, 0.0], "touched": list(touched),
                   "detail": ""})


def raised(candidate: Sequence[str], exception: str, location: str, **options: Any) -> events.Probe:
    """A probe whose test raised something else than a predicate failure (`{"exception", "location"}`)."""
    return dataclasses.replace(probe(candidate, **options), signature={"exception": exception, "location": location})


# -- grouping ----------------------------------------------------------------------------------------------
def test_the_tolerance_is_measured_from_the_first_member_of_a_group_and_includes_its_edge() -> None:
    records = [probe("abc", at=(0.0, 0.0, 0.0)), probe("ab", at=(0.5, 0.0, 0.0)),  # exactly at the tolerance
               probe("a", at=(0.75, 0.0, 0.0))]  # 0.25 from the second, but 0.75 from the first
    groups = other_failures(records)
    assert [(g.probes, g.first_probe) for g in groups] == [(2, 0), (1, 2)]
    assert groups[1].signature is not None and groups[1].signature.position == (0.75, 0.0, 0.0)
    assert len(other_failures([probe("a", at=(0.0, 0.0, 0.0)), probe("b", at=(0.0, 0.5001, 0.0))])) == 2
    assert len(other_failures(records, tolerance=1.0)) == 1  # the reduction's tolerance, not the default
    assert len(other_failures([probe("a", at=(0.0, 0.0, 0.0)), probe("b", at=(0.0, 0.0, 0.6))])) == 2  # 3D


def test_touched_models_must_overlap_as_in_the_oracle() -> None:
    def count(first: Sequence[str], second: Sequence[str]) -> int:
        return len(other_failures([probe("ab", touched=first), probe("ab", touched=second)]))

    assert count(["wall"], ["post"]) == 2  # the same spot, another obstacle: another failure
    assert count(["wall"], ["post", "wall"]) == 1
    assert count([], ["post"]) == 1  # the first touched nothing: any contact is the same, as in same_failure
    assert count(["wall"], []) == 2
    assert len(other_failures([probe("ab", predicate="flipped"), probe("ab", predicate="stuck")])) == 2


def test_exceptions_are_grouped_by_type_and_location() -> None:
    records = [raised("abc", "AssertionError", "test_yard.py:12"), raised("ab", "AssertionError", "test_yard.py:12"),
               raised("ab", "AssertionError", "test_yard.py:14"), raised("a", "ZeroDivisionError", "test_yard.py:12")]
    groups = other_failures(records)
    assert [(g.exception, g.location, g.probes) for g in groups] == [
        ("AssertionError", "test_yard.py:12", 2), ("AssertionError", "test_yard.py:14", 1),
        ("ZeroDivisionError", "test_yard.py:12", 1)]
    assert groups[0].signature is None and groups[0].predicate is None
    assert groups[0].describe() == "AssertionError at test_yard.py:12"


def test_largest_group_first_then_by_first_probe_and_only_other_outcomes() -> None:
    records = [
        events.Problem(fingerprint="", parts={}), events.Start(elements=("a", "b", "c")),
        probe("abc", outcome="fail"), probe("abc", predicate="stuck", outcome="pass"),  # not other failures
        probe("ab", predicate="fell", at=(5.0, 0.0, 0.0)),  # probe 2
        probe("ab", predicate="flipped"),  # probe 3
        probe("ac", predicate="stuck", at=(9.0, 0.0, 0.0)),  # probe 4
        probe("a", predicate="stuck", at=(9.2, 0.0, 0.0)),
        probe("a", predicate="fell", at=(5.1, 0.1, 0.0)),
        dataclasses.replace(probe("a"), signature=None),  # unreadable: left out
        dataclasses.replace(probe("a"), signature={"predicate": "fell"}),
    ]
    groups = other_failures(records)
    assert [(g.predicate, g.probes, g.first_probe) for g in groups] == [("fell", 2, 2), ("stuck", 2, 4),
                                                                        ("flipped", 1, 3)]
    assert other_failures(records) == groups  # deterministic


def test_smallest_world_seeds_attempts_and_where_it_was_seen() -> None:
    records = [
        probe(["plane", "a", "b", "c"], seed=7, attempt=0, purpose="confirmation"),
        probe(["plane", "a", "b"], seed=1000010, attempt=1),
        probe(["plane", "b"], seed=2000013, attempt=2),
        probe(["plane", "c"], seed=7, attempt=0),  # as small: the first one stays
        probe(["b#0", "b#1"], seed=None, attempt=5, stage="shapes"),  # a stage's candidate: not a set of models
        probe(["minimal world"], seed=None, attempt=1_000_000, stage="rates", purpose="failure-rate"),
        probe(["shapes world"], predicate="stuck", at=(3.0, 0.0, 0.0), seed=None, attempt=3, stage="rates"),
    ]
    first, only_stages = other_failures(records)
    assert first.probes == 6
    assert (first.smallest_world, first.smallest_seed, first.smallest_attempt) == (("plane", "b"), 2000013, 2)
    assert first.seeds == (7, 1000010, 2000013) and first.attempts == (0, 1, 2, 5, 1_000_000)
    assert first.seen_in == ("models", "shapes", "rates")
    assert only_stages.smallest_world is None and only_stages.seen_in == ("rates",)
    data = json.loads(json.dumps(first.to_json()))
    assert data["smallest_world"] == {"size": 2, "models": ["plane", "b"], "seed": 2000013, "attempt": 2}
    assert data["signature"]["predicate"] == "flipped" and data["probes"] == 6
    assert data["description"] == "flipped near (0.0, 0.0) at t = 4.0 s (touching no model)"
    touching = other_failures([probe("a", at=(3.24, -1.06, 0.0), touched=["wall", "post", "crate"], time=4.12)])
    assert touching[0].describe() == "flipped near (3.2, -1.1) at t = 4.1 s (touching wall, post and 1 more)"
    assert data["world_file"] is None and data["replay"] is None
    exception = other_failures([raised("a", "KeyError", "t.py:3")])[0].to_json()
    assert json.loads(json.dumps(exception))["signature"] == {"exception": "KeyError", "location": "t.py:3"}


# -- the report -----------------------------------------------------------------------------------------------
def report_with(failures: tuple[OtherFailure, ...], folder: Path) -> ReductionReport:
    reduction = Reduction(
        original=("plane", "a", "b"), minimal=("plane", "a"), kept=(), probes=4, cache_hits=0, skipped=0, errors=0,
        steps=((0, 3), (4, 2)), one_minimal=True, incomplete_reason=None, failure_rate=(5, 5), wall_time=1.0,
        partition="model2model", priority="sequential", granularity="ddmin", deflake=1, seed=0)
    files = ReportFiles(folder / "minimal.yaml", folder / "runs.jsonl", folder / "summary.json")
    return ReductionReport(test="t", world="w.yaml", reduction=reduction, reference_failure={}, replay="r",
                           fingerprint="f", files=files, cost=Cost(4, 6, 1.0), tolerance=0.5,
                           other_failures=failures)


def test_the_report_shows_five_groups_and_counts_the_rest(tmp_path: Path) -> None:
    records = [probe(["plane", "a", "b"][: 1 + k % 3], predicate="fell", at=(float(3 * k), 1.0, 0.0), time=4.06)
               for k in range(7) for _ in range(7 - k)]
    groups = other_failures(records)
    kept = dataclasses.replace(groups[0], world_file=str(tmp_path / "other-1.yaml"))
    report = report_with((kept, *groups[1:]), tmp_path)
    lines = other_failure_lines(report)
    assert lines[0] == ("other failure: fell near (0.0, 1.0) at t = 4.1 s (touching no model), seen in 7 probes, "
                        "smallest world 1 model (other-1.yaml)")
    assert lines[1] == ("other failure: fell near (3.0, 1.0) at t = 4.1 s (touching no model), seen in 6 probes, "
                        "smallest world 2 models")
    assert len(lines) == 6 and lines[-1] == "and 2 more other failures (see summary.json)"
    assert lines[4].endswith("seen in 3 probes, smallest world 2 models")
    text = result_lines(report)
    assert text.index(lines[0]) > text.index("minimal world fails 5/5 fresh runs")
    assert report.to_json()["other_failures"][0]["world_file"] == str(tmp_path / "other-1.yaml")
    assert other_failure_lines(report_with((), tmp_path)) == []
    only_stages = other_failures([probe(["x#0"], stage="shapes")])
    assert other_failure_lines(report_with(only_stages, tmp_path)) == [
        ("other failure: flipped near (0.0, 0.0) at t = 4.0 s (touching no model), seen in 1 probe, only in the "
         "stages' worlds")]


# -- other-<k>.yaml ---------------------------------------------------------------------------------------------
WORLD = """format: 1
name: yard
scenario: {robot: husky, start: {x: 0.0, y: 0.0, yaw: 0.0}, goal: {x: 4.0, y: 0.0}, timeout: 20.0}
models:
- {name: plane, pose: [0, 0, -0.05, 0, 0, 0], box: [20, 20, 0.1]}
- {name: a, pose: [2.0, 0.0, 0.5, 0, 0, 0], box: [0.3, 4.0, 1.0]}
- {name: b, pose: [3.0, -4.0, 0.25, 0, 0, 0], box: [0.5, 0.5, 0.5]}
- {name: c, pose: [-2.0, 3.0, 0.25, 0, 0, 0], box: [0.5, 0.5, 0.5]}
"""


def test_the_largest_groups_worlds_are_written_and_stale_ones_removed(tmp_path: Path) -> None:
    world = World.from_yaml(WORLD)
    paths = ArtifactPaths(tmp_path)
    (tmp_path / "other-3.yaml").write_text("stale")
    (tmp_path / "other-notes.yaml").write_text("not ours")
    groups = other_failures([
        probe(["x#0"], stage="shapes"), probe(["x#0"], stage="shapes"), probe(["x#0"], stage="shapes"),
        probe(["plane", "a", "b"], predicate="stuck", seed=5), probe(["plane", "b"], predicate="stuck", seed=9),
        probe(["plane", "c"], predicate="fell", seed=None),
    ])
    assert [g.probes for g in groups] == [3, 2, 1] and groups[0].smallest_world is None

    kept, files = write_other_worlds(paths, world, groups, 5, lambda path, seed: f"replay {path.name} {seed}")
    assert files == (tmp_path / "other-1.yaml", tmp_path / "other-2.yaml")  # the stages-only group has no world
    assert World.load(files[0]).names == ("plane", "b") and World.load(files[1]).names == ("plane", "c")
    assert World.load(files[0]).scenario == world.scenario
    assert kept[0].world_file is None and kept[0].replay is None
    assert (kept[1].world_file, kept[1].replay) == (str(files[0]), "replay other-1.yaml 9")
    assert kept[2].replay == "replay other-2.yaml None"
    assert not (tmp_path / "other-3.yaml").exists() and (tmp_path / "other-notes.yaml").exists()

    kept, files = write_other_worlds(paths, world, groups, 1)  # a later run keeps fewer
    assert files == (tmp_path / "other-1.yaml",) and not (tmp_path / "other-2.yaml").exists()
    assert kept[1].replay is None
    kept, files = write_other_worlds(paths, world, groups, 0)
    assert files == () and kept == groups
    assert sorted(p.name for p in tmp_path.glob("other-*.yaml")) == ["other-notes.yaml"]


# -- the options -----------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("arguments", "ini", "message"), [
    (["--ddenv-keep-other", "-1"], "", "ERROR: --ddenv-keep-other: expected an integer >= 0, got '-1'"),
    (["--ddenv-keep-other", "two"], "", "ERROR: --ddenv-keep-other: expected an integer >= 0, got 'two'"),
    ([], "ddenv_keep_other = 1.5", "ERROR: ddenv_keep_other in tox.ini: expected an integer >= 0, got '1.5'"),
])
def test_a_bad_keep_other_is_one_usage_error_naming_the_option(pytester: pytest.Pytester, arguments: list[str],
                                                               ini: str, message: str) -> None:
    if ini:
        pytester.makeini(f"[pytest]\n{ini}\n")
    pytester.makepyfile("def test_ok():\n    pass\n")
    result = pytester.runpytest_subprocess(*arguments)
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    errors = [line for line in result.stderr.lines if line.startswith("ERROR:")]
    assert errors == [message]


def test_ddenv_reduce_refuses_a_negative_keep_other(capsys: pytest.CaptureFixture[str]) -> None:
    code = cli.main(["reduce", str(ROOT / "worlds" / "rubble.yaml"), "-p", STUCK, "--keep-other", "-2"])
    err = capsys.readouterr().err
    assert code == 2 and "--keep-other" in err and "Traceback" not in err


# -- a real reduction -----------------------------------------------------------------------------------------
def ddenv(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str]:
    code = cli.main(list(argv))
    return code, capsys.readouterr().out


@pytest.mark.slow
def test_ddenv_reduce_keeps_the_other_failures_of_the_rubble_and_they_replay(
        capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Rubble (seed 0) with the examples' predicates: some probes get high-centered on another board, or stuck
    elsewhere. The first kept world, replayed with the predicates and the run seed it failed with, fails with
    the group's predicate (the same failure, within the tolerance)."""
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "rubble"
    command = ["reduce", str(ROOT / "worlds" / "rubble.yaml"), "-p", "high_centered", "-p", STUCK, "--workers", "2",
               "--media", "none", "--out", str(out), "-q"]
    code, text = ddenv(capsys, *command, "--keep-other", "2")
    assert code == 0, text
    summary = json.loads((out / "summary.json").read_text())
    groups = summary["other_failures"]
    assert groups and all(g["probes"] >= 1 for g in groups)
    assert [g["probes"] for g in groups] == sorted((g["probes"] for g in groups), reverse=True)
    first = groups[0]
    assert first["world_file"] == str(out / "other-1.yaml") == summary["files"]["other_1_yaml"]
    assert World.load(out / "other-1.yaml").names == tuple(first["smallest_world"]["models"])
    shown = [line for line in text.splitlines() if line.startswith("other failure: ")]
    assert shown and shown[0].startswith(f"other failure: {first['description']}, seen in {first['probes']} prob")
    assert shown[0].endswith("(other-1.yaml)")
    assert summary["command"].endswith("--keep-other 2")

    replay = shlex.split(first["replay"])
    assert replay[:3] == ["ddenv", "run", str(out / "other-1.yaml")]
    assert replay[replay.index("--seed") + 1] == str(first["smallest_world"]["seed"])
    code, output = ddenv(capsys, *replay[1:], "--no-picture", "--json")
    run = json.loads(output)
    assert code == 1 and run["failure"] is not None
    assert run["failure"]["predicate"] == first["signature"]["predicate"]
    from pytest_ddenv.oracle import FailureSignature, same_failure

    assert same_failure(FailureSignature.from_dict(run["failure"]), FailureSignature.from_dict(first["signature"]),
                        summary["tolerance"])

    kept = [name for name in ("other-1.yaml", "other-2.yaml") if (out / name).exists()]
    code, text = ddenv(capsys, *command, "--keep-other", "1")  # resumes the log: keeps one world
    assert code == 0, text
    assert (out / "other-1.yaml").exists() and not (out / "other-2.yaml").exists(), kept
    assert "other_2_yaml" not in json.loads((out / "summary.json").read_text())["files"]


@pytest.mark.slow
def test_pytest_keeps_the_other_failures_of_a_scenario_test(pytester: pytest.Pytester) -> None:
    """--ddenv-keep-other reaches the plugin's reduction: other-1.yaml written, attached, in the report."""
    pytester.makepyfile(test_rubble=f"""
        import pytest

        @pytest.mark.ddenv(world={str(ROOT / "worlds" / "rubble.yaml")!r}, partition="model2model",
                           priority="avg-trajectory")
        @pytest.mark.robot_failure("high_centered")
        @pytest.mark.robot_failure("stuck", window=5.0, min_progress=0.2)
        def test_rubble(robot_world):
            assert robot_world.run().reached_goal
        """)
    result = pytester.runpytest_subprocess("--ddenv-reduce", "--ddenv-keep-other", "1", "--ddenv-stages", "models",
                                           "--ddenv-media", "none", "--ddenv-workers", "2", "-p", "no:cacheprovider",
                                           "-o", "junit_logging=system-out", "--junitxml=junit.xml")
    result.assert_outcomes(failed=1)
    (summary_path,) = pytester.path.glob("ddenv-artifacts/*/summary.json")
    summary = json.loads(summary_path.read_text())
    assert summary["other_failures"], "the rubble's reduction meets other failures (docs/benchmarks.md)"
    kept = Path(summary["files"]["other_1_yaml"])
    assert kept.name == "other-1.yaml" and World.load(kept).names == tuple(
        summary["other_failures"][0]["smallest_world"]["models"])
    assert not (summary_path.parent / "other-2.yaml").exists()
    assert f"[[ATTACHMENT|{kept}]]" in (pytester.path / "junit.xml").read_text()
    result.stdout.fnmatch_lines(["*other failure: * (other-1.yaml)"])
