"""The skid-steered Husky turns on the spot in MuJoCo as a robot whose wheel motors hold their speed (pybullet's
velocity-motor constraint), and drives straight as far as in pybullet: the wheel joints carry their servo's
armature (sim/mujoco/robot_spec.py `servo_armature`; without it the turn was 17 degrees, a third of pybullet's)."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("mujoco", reason="needs mujoco: pip install \"pytest-ddenv[mujoco]\"")

from mujoco_worlds import flat_world

from pytest_ddenv.sim import Command, NoiseSettings, RunSettings, Simulator
from pytest_ddenv.sim.mujoco.robot_spec import VELOCITY_GAIN, servo_armature

TICKS = 60
"""3 s at 20 Hz."""


def _drive(sim: Simulator, command: Command) -> tuple[float, float]:
    """(yaw turned in degrees, distance travelled in m) after `TICKS` ticks of `command`, noise off."""
    episode = sim.start(flat_world(timeout=4.0), seed=0, settings=RunSettings(noise=NoiseSettings.none()))
    start, yaws = episode.pose, []
    for _ in range(TICKS):
        episode.observe()
        episode.act(command)
        yaws.append(episode.pose[5])
    end = episode.pose
    turned = np.unwrap([start[5], *yaws])[-1] - start[5]
    return math.degrees(float(turned)), math.hypot(end[0] - start[0], end[1] - start[1])


def test_the_husky_turns_on_the_spot_with_its_wheels_holding_their_speed(sim: Simulator) -> None:
    turned, moved = _drive(sim, Command(0.0, 0.8))
    assert 45.0 < turned < math.degrees(0.8 * TICKS / 20)  # pybullet 57; 17 without the armature; 137 commanded
    assert moved < 0.1


def test_the_husky_drives_straight_as_far_as_in_pybullet(sim: Simulator) -> None:
    turned, moved = _drive(sim, Command(1.0, 0.0))
    assert abs(turned) < 1.0 and moved == pytest.approx(2.94, abs=0.05)  # pybullet 2.94 m


def test_the_armature_is_the_servo_gain_over_one_step() -> None:
    assert servo_armature(VELOCITY_GAIN, 1 / 240) == pytest.approx(200 / 240)
