"""The same-failure rule in the user's hands (issue 27): a robot that dithers in front of a wall.

The test's own controller drives at the wall, bumps it, backs off and comes back; the test's own predicate
`no_goal_progress` fires when the robot has not come closer to the goal for a while. Whether the robot
touches the wall at that moment depends on the seed: with seed 17 it does in the failing run, and in none of
the fresh runs. The default rule (same predicate, same place, touching one of the models touched) calls those
fresh runs "other", so the reduction says the original and the minimal world fail 0/5; the place-only rule,
given to the marker as "place" or as a function of the test module, says they fail as often as each other.
Real simulations in worker processes and in the pytest process; `ddenv replay` re-applies the rule.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow  # real reductions (subprocesses, simulations): the full tier only

DITHER_WORLD = textwrap.dedent(
    """\
    format: 1
    name: dither
    scenario:
      start: {x: 0.0, y: 0.0, yaw: 0.0}
      goal: {x: 4.0, y: 0.0}
      timeout: 25
    models:
      - {name: far_box_a, pose: [-4, 4, 0.25], box: [0.5, 0.5, 0.5]}
      - {name: wall, pose: [2.0, 0, 0.5], box: [0.3, 4.0, 1.0]}
      - {name: far_box_b, pose: [-4, -4, 0.25], box: [0.5, 0.5, 0.5]}
      - {name: far_post, pose: [6, 5, 0.5], cylinder: {radius: 0.2, length: 1.0}}
    """
)

DITHER_TEST = textwrap.dedent(
    """\
    import math

    import pytest

    from pytest_ddenv import Command, register_predicate
    from pytest_ddenv.oracle import signature
    from pytest_ddenv.oracle.predicates import GROUND


    class NoGoalProgress:
        \"\"\"No closer to the goal by `min_progress` m for `window` s.\"\"\"

        name = "no_goal_progress"

        def __init__(self, window=11.6, min_progress=0.05):
            self.window, self.min_progress = window, min_progress
            self.reset()

        def reset(self):
            self.best, self.since = None, 0.0

        def check(self, state):
            if self.best is None or state.goal_distance < self.best - self.min_progress:
                self.best, self.since = state.goal_distance, state.time
            elif state.time - self.since >= self.window:
                return signature(self.name, state, f"no closer than {self.best:.2f} m for {self.window} s")
            return None


    register_predicate("no_goal_progress", NoGoalProgress, replace=True)


    class BumpAndBackOff:
        \"\"\"The controller under test: forward; on a bump, push a moment, back off, come again.\"\"\"

        def __init__(self, push_time=0.15, back_time=0.8):
            self.push_time, self.back_time = push_time, back_time
            self.touched_at = None

        def reset(self, observation):
            self.touched_at = None

        def __call__(self, observation):
            now = observation.time
            if self.touched_at is None and any(c.model != GROUND for c in observation.contacts):
                self.touched_at = now
            if self.touched_at is not None:
                if now < self.touched_at + self.push_time:
                    return Command(0.6, 0.0)
                if now < self.touched_at + self.push_time + self.back_time:
                    return Command(-0.4, 0.0)
                self.touched_at = None
            return Command(0.6, 0.0)


    def same_place(reference, signature):
        \"\"\"The test's own same-failure rule: the same predicate within 0.5 m, whatever it touches.\"\"\"
        return signature.predicate == reference.predicate and math.dist(signature.position, reference.position) < 0.5


    @pytest.mark.ddenv(world="dither.yaml", seed=17, stages="models"RULE)
    @pytest.mark.robot_failure("no_goal_progress")
    def test_reaches_the_goal(robot_world):
        run = robot_world.run(controller=BumpAndBackOff())
        assert run.reached_goal
    """
)


def dither_project(pytester: pytest.Pytester, rule: str = "") -> pytest.Pytester:
    pytester.makefile(".yaml", dither=DITHER_WORLD)
    pytester.makepyfile(test_dither=DITHER_TEST.replace("RULE", rule))
    return pytester


def summary_of(pytester: pytest.Pytester) -> dict:
    (summary,) = Path(pytester.path, "ddenv-artifacts").glob("*/summary.json")
    return json.loads(summary.read_text())


def ddenv_replay(pytester: pytest.Pytester, *arguments: str) -> subprocess.CompletedProcess[str]:
    """`ddenv replay` of the reduction's folder with the test module's predicate and controller."""
    (folder,) = Path(pytester.path, "ddenv-artifacts").glob("*/")
    return subprocess.run(
        [sys.executable, "-m", "pytest_ddenv.cli", "replay", str(folder), "--runs", "5", "--import", "test_dither.py",
         "--controller", "test_dither.py:BumpAndBackOff", *arguments],
        cwd=pytester.path, capture_output=True, text=True, timeout=600,
    )


@pytest.mark.pybullet  # the dither world rarely repeats its failure in PyBullet; in MuJoCo it repeats it 5/5
def test_the_default_rule_says_why_the_original_world_rarely_fails_the_same_way(pytester: pytest.Pytester) -> None:
    result = dither_project(pytester).runpytest_subprocess("--ddenv-reduce", "--ddenv-media", "none")
    result.assert_outcomes(failed=1)
    summary = summary_of(pytester)
    assert summary["minimal_models"] == ["wall"]
    # the symptom: the failure itself, 0/5 in fresh runs of the original world and of the minimal one
    assert summary["original_failure_rate"] == {"fails": 0, "runs": 5}
    assert summary["failure_rate"] == {"fails": 0, "runs": 5}
    # ... now said up front, with the reason seen most and what to do about it
    up_front = ("*warning: the original world failed the same way in only 0 of 5 fresh runs: the same predicate "
                "fired at the same place but touching no model in 5 of 5 runs (the reference touched wall); consider "
                "same_failure='place'*")
    rule = "*same failure: no_goal_progress within 0.5 m, touching one of the models the reference touched (the def*"
    result.stdout.fnmatch_lines(["*ddenv reduction*", up_front, "*minimal world: wall*", rule])
    assert summary["same_failure"] == {"match": "all", "tolerance": 0.5, "predicates": {}}
    assert summary["original_reproduction"]["reason"].startswith("the same predicate fired at the same place but "
                                                                  "touching no model")
    # every other failure the report lists says why it is not the failure
    (other,) = [failure for failure in summary["other_failures"] if failure["signature"].get("predicate")]
    assert "touching no model" in other["why"]
    # ddenv replay says why each run is other
    replayed = ddenv_replay(pytester)
    assert replayed.returncode == 1, replayed.stderr
    assert "NOT reproduced: 0/5" in replayed.stdout
    other_lines = [line for line in replayed.stdout.splitlines() if ": other (" in line]
    assert len(other_lines) == 5
    assert all("touching no model (the reference touched wall)" in line for line in other_lines), other_lines


@pytest.mark.parametrize(
    ("rule", "recorded", "workers"),
    [
        (', same_failure="place"', "place", ()),  # the default local worker processes
        (", same_failure=same_place", "test_dither:same_place", ("--ddenv-workers", "1")),  # in the pytest process
    ],
    ids=["place-workers", "function-in-process"],
)
def test_the_place_rule_says_the_minimal_world_fails_as_often_as_the_original(
        pytester: pytest.Pytester, rule: str, recorded: str, workers: tuple[str, ...]) -> None:
    result = dither_project(pytester, rule).runpytest_subprocess("--ddenv-reduce", "--ddenv-media", "none", *workers)
    result.assert_outcomes(failed=1)
    summary = summary_of(pytester)
    assert summary["minimal_models"] == ["wall"] and summary["one_minimal"] is True
    assert summary["original_failure_rate"] == {"fails": 3, "runs": 3}  # calibration; 2 more could not matter
    assert summary["failure_rate"] == {"fails": 5, "runs": 5}
    assert summary["rate_check"]["decision"] == "holds"
    assert summary["same_failure"]["match"] == recorded
    assert summary["original_reproduction"] is None
    assert not [failure for failure in summary["other_failures"] if failure["signature"].get("predicate")], \
        "the failure itself is never listed as another failure"
    result.stdout.fnmatch_lines(["*minimal world fails 5/5 fresh runs: not significantly less often than the "
                                 "original (3/3 fresh runs; 2 more could not change that; its rate: 57-100 % at "
                                 "95 % confidence)*"])
    result.stdout.no_fnmatch_line("*the original world failed the same way in only*")
    # ddenv replay re-applies the recorded rule
    replayed = ddenv_replay(pytester)
    assert replayed.returncode == 0, replayed.stdout + replayed.stderr
    assert "reproduced: 5/5" in replayed.stdout


@pytest.mark.pybullet  # what the function accepts is tuned to PyBullet's runs of the dither world
def test_ddenv_reduce_takes_a_function_and_ddenv_replay_reapplies_it(pytester: pytest.Pytester) -> None:
    """The command line, with the user's function given as FILE:FUNCTION: recorded by module name, imported
    again by `ddenv replay` (from the --import the summary records)."""
    pytester.makefile(".yaml", dither=DITHER_WORLD)
    pytester.makepyfile(dither_code=DITHER_TEST.replace("RULE", ""))
    reduced = subprocess.run(
        [sys.executable, "-m", "pytest_ddenv.cli", "reduce", "dither.yaml", "--predicate", "no_goal_progress",
         "--import", "dither_code.py", "--controller", "dither_code.py:BumpAndBackOff", "--seed", "17",
         "--same-failure", "dither_code.py:same_place", "--media", "none", "--stages", "models", "--out", "out"],
        cwd=pytester.path, capture_output=True, text=True, timeout=600,
    )
    assert reduced.returncode == 0, reduced.stderr
    assert "same failure: when dither_code:same_place(reference, signature) says so" in reduced.stdout
    summary = json.loads(Path(pytester.path, "out", "summary.json").read_text())
    assert summary["same_failure"]["match"] == "dither_code:same_place"
    assert summary["minimal_models"] == ["wall"] and summary["failure_rate"] == {"fails": 5, "runs": 5}
    replayed = subprocess.run([sys.executable, "-m", "pytest_ddenv.cli", "replay", "out", "--runs", "3"],
                              cwd=pytester.path, capture_output=True, text=True, timeout=600)
    assert replayed.returncode == 0 and "reproduced: 3/3" in replayed.stdout, replayed.stdout + replayed.stderr
    by_default = subprocess.run([sys.executable, "-m", "pytest_ddenv.cli", "replay", "out", "--runs", "3",
                                 "--same-failure", "all"], cwd=pytester.path, capture_output=True, text=True,
                                timeout=600)
    assert by_default.returncode == 1 and "NOT reproduced: 0/3" in by_default.stdout
    assert "; the same predicate fired at the same place but touching no model in 3 of 3 runs" in by_default.stdout
