"""The unit tier (`pytest -m unit`): the tests of the world model, the file formats, the oracle, the
simulation, the reduction engine and the stages that run in the test process alone. No subprocess, no
compiler, no media helper process, no `ddenv` or pytest run in a child: tests/conftest.py marks them and runs
each under `no_process_started`, so a unit test that starts a process fails and says how.

Which tests: those of the folders and modules below that are not `slow` and request none of the fixtures that
start processes (`PROCESS_FIXTURES`). A marker given by place, not written on each test: a test added to one
of these modules is in the tier, and the guard keeps it honest.
"""

from __future__ import annotations

import _posixsubprocess
import contextlib
import multiprocessing.process
import os
import subprocess
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

TESTS = Path(__file__).resolve().parent
UNIT_FOLDERS = ("reduce", "stages")
UNIT_MODULES = (
    # the world model and its files
    "test_worlds.py", "test_world_errors.py", "test_world_properties.py", "test_value_checks.py",
    "test_shapes.py", "test_sdf.py", "test_sdf_gazebo_rules.py", "test_sdf_hostile.py", "test_sdf_shipped.py",
    "test_sdf_surgical.py", "reliability/test_yaml_nesting.py",
    "mjcf/test_mjcf_read.py", "mjcf/test_mjcf_errors.py", "mjcf/test_mjcf_cut.py",
    # the oracle and the test's view of a run
    "test_oracle.py", "test_same_failure_rule.py", "test_custom_predicates.py", "test_arm_predicates.py", "test_reported_runs.py",
    "test_user_line.py", "test_code_identity.py", "test_report_rule_note.py",
    # the folders of a test's earlier reductions
    "test_superseded.py",
    # a run log of the release before, read back
    "test_old_run_logs.py",
    # the simulation, in this process's own pybullet client
    "sim/test_controllers.py", "sim/test_driving.py", "sim/test_oracle_ditch.py", "sim/test_predicates.py",
    "sim/test_shapes_sim.py", "sim/test_urdf_robot.py", "sim/test_validation.py",
    # the first cut by reach, on real runs
    "test_reach.py",
    # the settings each front end takes, declared once
    "test_settings.py",
    # this tier's own check
    "test_tiers.py",
)
PROCESS_FIXTURES = frozenset({"pytester", "testdir", "sdformat_check", "sdformat_dump"})
"""Fixtures that start processes (pytest runs, the libsdformat programs and their build): a test that
requests one is not in the unit tier, wherever it is."""


def in_unit_tier(item: pytest.Item) -> bool:
    if item.get_closest_marker("slow") is not None:
        return False
    if PROCESS_FIXTURES.intersection(getattr(item, "fixturenames", ())):
        return False
    try:
        place = item.path.resolve().relative_to(TESTS)
    except ValueError:  # a test outside tests/ (pytester's own runs)
        return False
    return place.parts[0] in UNIT_FOLDERS or place.as_posix() in UNIT_MODULES


class ProcessStarted(AssertionError):
    """A unit-tier test started a process."""


WAYS_TO_START = (
    (subprocess, "_fork_exec"),  # subprocess.Popen, run, check_output, ...
    (_posixsubprocess, "fork_exec"),  # multiprocessing's spawn and forkserver starts
    (os, "posix_spawn"), (os, "posix_spawnp"), (os, "fork"), (os, "forkpty"), (os, "system"),
    (multiprocessing.process.BaseProcess, "start"),  # also through a forkserver already running
)


@contextlib.contextmanager
def no_process_started(test: str) -> Iterator[None]:
    """Within: every way of starting a process raises `ProcessStarted`, naming `test` and the way."""

    def refuse(way: str) -> Callable[..., Any]:
        def refused(*args: object, **kwargs: object) -> Any:
            raise ProcessStarted(
                f"{test} is in the unit tier, which starts no process, and it started one ({way}): request a "
                f"fixture that starts it ({', '.join(sorted(PROCESS_FIXTURES))}), mark the test slow, or move it "
                f"out of the unit tier's folders and modules (tests/unit_tier.py)")

        return refused

    saved = [(owner, name, owner.__dict__[name]) for owner, name in WAYS_TO_START if name in owner.__dict__]
    for owner, name, _ in saved:
        setattr(owner, name, refuse(f"{getattr(owner, '__name__', owner)}.{name}"))
    try:
        yield
    finally:
        for owner, name, original in saved:
            setattr(owner, name, original)
