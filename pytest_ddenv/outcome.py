"""`Outcome`: the verdict on one run, shared by the oracle (which decides it) and the reduction engine
(which consumes it). A plain value module, so that neither layer imports the other."""

from __future__ import annotations

import enum


class Outcome(str, enum.Enum):
    """What one simulation of a candidate world showed."""

    FAIL = "fail"
    """The same failure f as the original world."""
    OTHER = "other"
    """A different failure f' (not f)."""
    PASS = "pass"
    """The test passed (not f)."""
    ERROR = "error"
    """The simulation or the test itself broke; never counts as f."""
