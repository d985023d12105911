"""MuJoCo lists what the robot nearly touches (within pybullet's 2 cm contact breaking threshold) with force 0,
as pybullet does, and listing them changes nothing in the physics."""

from __future__ import annotations

import pytest

pytest.importorskip("mujoco", reason="needs mujoco: pip install \"pytest-ddenv[mujoco]\"")

from mujoco_worlds import box, digest, flat_world

from pytest_ddenv.sim import NoiseSettings, RunSettings, Simulator
from pytest_ddenv.sim.mujoco.near import NEAR_DISTANCE

NO_NOISE = RunSettings(noise=NoiseSettings.none())
WHEEL_SIDE = 0.2854 + 0.1143 / 2
"""y of the Husky's left wheels' outer side at the noise-free start: half its track plus half a wheel's width (m;
beyond the footprint's 0.335 m, so the start's support rays miss a wall there)."""


def _first_contacts(sim: Simulator, gap: float) -> tuple[tuple[str, str, float], ...]:
    wall = box("side", (1.0, 0.2, 0.3), (0.0, WHEEL_SIDE + gap + 0.1, 0.15))
    episode = sim.start(flat_world(wall, timeout=1.0), seed=0, settings=NO_NOISE)
    return tuple((c.model, c.link, c.normal_force) for c in episode.observe().contacts)


def test_a_model_a_few_mm_from_the_wheels_is_listed_with_force_zero(sim: Simulator) -> None:
    contacts = _first_contacts(sim, 0.005)
    assert {(model, link) for model, link, _ in contacts} == {("side", "front_left_wheel_link"),
                                                              ("side", "rear_left_wheel_link")}
    assert all(force == 0.0 for _, _, force in contacts)


def test_a_model_farther_than_the_threshold_is_not_listed(sim: Simulator) -> None:
    assert _first_contacts(sim, NEAR_DISTANCE + 0.01) == ()


def test_near_contacts_change_nothing_in_the_run(sim: Simulator) -> None:
    # a wall the robot drives along, 5 mm from its wheels: listed as touched from the first tick on, while the
    # trajectory is the same as beside a wall 5 cm away (listed never)
    def run(gap: float):  # noqa: ANN202
        wall = box("side", (8.0, 0.2, 0.3), (3.0, WHEEL_SIDE + gap + 0.1, 0.15))
        return sim.run(flat_world(wall, timeout=3.0), seed=0, settings=NO_NOISE)

    near, far = run(0.005), run(0.05)
    assert near.first_touch.get("side") == 0.0 and "side" not in far.first_touch
    assert digest(near) == digest(far)
