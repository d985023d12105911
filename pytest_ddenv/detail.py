"""Whether the simulations started now record their full detail (`Run.detail`).

A run normally records the robot's pose only: that is all the reduction needs, and every probe stays small.
The animations and the 3D recording need more (every moving model's pose, the laser scans, the contact
points, the robot's joints), for the one or two runs they show. The driver asks for it per probe
(`pool.call(..., record=True)`); the worker that answers sets this flag around the test, and the simulation
reads it when an episode starts. It is a context variable: it holds for the thread (or task) that set it.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from contextvars import ContextVar

_DETAIL: ContextVar[bool] = ContextVar("ddenv_record_detail", default=False)


def detail_requested() -> bool:
    """True inside `recording_detail()`: a run started now records `Run.detail`."""
    return _DETAIL.get()


@contextlib.contextmanager
def recording_detail(on: bool = True) -> Iterator[None]:
    """Runs started inside record their full detail (when `on`)."""
    token = _DETAIL.set(bool(on))
    try:
        yield
    finally:
        _DETAIL.reset(token)
