"""The MuJoCo engine's tests: real MuJoCo simulations; each module skips itself where mujoco is not installed."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from pytest_ddenv.sim import Simulator


@pytest.fixture(scope="session")
def sim() -> Iterator[Simulator]:
    with Simulator() as simulator:
        yield simulator
