"""Bit-identical reruns, invariance to far-away models, seeds that matter."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import numpy as np
from helpers import box, digest, far_boxes, flat_world

from pytest_ddenv.sim import RunSettings, Simulator

SHORT = 6.0
SETTINGS = RunSettings()


def _clutter_world(*extra):  # a few touched and untouched things near the path
    return flat_world(
        box("board", (1.2, 0.09, 0.04), (2.0, 0.3, 0.02), static=False, mass=1.4),
        box("wall", (0.2, 3.0, 1.0), (4.0, 3.0, 0.5)),
        *extra,
        timeout=SHORT,
    )


def test_same_seed_same_process_is_bit_identical(sim: Simulator) -> None:
    world = _clutter_world(*far_boxes())
    first = sim.run(world, seed=3)
    second = sim.run(world, seed=3)
    assert first.same_trajectory(second)
    assert np.array_equal(first.wheel_contacts, second.wheel_contacts)
    assert first.first_touch == second.first_touch and first.first_sensed == second.first_sensed


def test_same_seed_after_50_other_runs(sim: Simulator) -> None:
    world = _clutter_world(*far_boxes())
    reference = sim.run(world, seed=11)
    other = flat_world(box("x", (1, 1, 1), (3, 0, 0.5)), timeout=0.25)
    for seed in range(50):
        sim.run(other, seed=seed)
    assert sim.run(world, seed=11).same_trajectory(reference)


def test_same_seed_in_a_fresh_process(sim: Simulator) -> None:
    world = _clutter_world(*far_boxes())
    here = digest(sim.run(world, seed=5))
    code = textwrap.dedent(
        f"""
        import sys, json
        sys.path.insert(0, {json.dumps(str(__import__('pathlib').Path(__file__).parent))})
        from helpers import box, digest, far_boxes, flat_world
        from test_determinism import _clutter_world
        from pytest_ddenv.sim import simulate
        print(digest(simulate(_clutter_world(*far_boxes()), seed=5)))
        """
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert result.stdout.strip().splitlines()[-1] == here
    assert "b3Warning" not in result.stdout + result.stderr  # pybullet's C-level chatter is silenced


def test_removing_untouched_far_models_changes_nothing(sim: Simulator) -> None:
    static, dynamic = far_boxes()
    full = sim.run(_clutter_world(static, dynamic), seed=2)
    assert "far_static" not in full.first_touch and "far_dynamic" not in full.first_touch
    for kept in ((), (static,), (dynamic,)):
        assert sim.run(_clutter_world(*kept), seed=2).same_trajectory(full)


def test_different_seeds_differ(sim: Simulator) -> None:
    world = _clutter_world()
    a, b = sim.run(world, seed=1), sim.run(world, seed=2)
    assert not a.same_trajectory(b)


def test_noise_free_runs_do_not_depend_on_the_seed(sim: Simulator) -> None:
    from pytest_ddenv.sim import NoiseSettings

    settings = RunSettings(noise=NoiseSettings.none())
    world = _clutter_world()
    assert sim.run(world, seed=1, settings=settings).same_trajectory(sim.run(world, seed=2, settings=settings))
