from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from pytest_ddenv import World
from pytest_ddenv.sim import Simulator

SMOKE = Path(__file__).resolve().parents[1] / "data" / "arm_smoke.yaml"
"""A Panda on a table, a cube to place 0.3 m to its left, three distractors away from the way."""


@pytest.fixture(scope="session")
def sim() -> Iterator[Simulator]:
    with Simulator() as simulator:
        yield simulator


@pytest.fixture(scope="session")
def smoke() -> World:
    return World.load(SMOKE)
