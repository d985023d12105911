"""pytest glue: registers the ddenv markers (the fixture and reduction arrive with the plugin issue)."""

from __future__ import annotations

import pytest


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers",
        "ddenv(world=PATH, partition=..., priority=..., deflake=N, ...): the world file of a robot scenario "
        "test and how to reduce it when the test fails under --ddenv-reduce.",
    )
    config.addinivalue_line(
        "markers",
        "robot_failure(NAME, **params): a failure predicate evaluated while the robot runs "
        "(stuck, flipped, high_centered, fell, collided, timeout).",
    )
