"""The oracle: whether a run's failure is the failure being reduced (`classify`, `same_failure`).

A run ends in the reference failure f (FAIL), another failure (OTHER), no failure (PASS) or an error
(ERROR). The predicates that produce failure signatures live in `pytest_ddenv.predicates` (the simulation
uses them); their names are re-exported here, where they were first defined. The meaning of "same
failure" is documented in docs/oracle.md.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from pytest_ddenv import defaults
from pytest_ddenv.outcome import Outcome
from pytest_ddenv.predicates import (
    BUILT_IN,
    GROUND,
    PREDICATES,
    Collided,
    Contact,
    FailureSignature,
    Fell,
    Flipped,
    FunctionPredicate,
    HighCentered,
    History,
    Predicate,
    PredicateSpec,
    RobotState,
    Stuck,
    Timeout,
    check_predicate,
    check_predicate_models,
    make_predicate,
    predicate,
    predicate_spec,
    register_predicate,
    signature,
)
from pytest_ddenv.validation import expected

if TYPE_CHECKING:  # pragma: no cover
    from pytest_ddenv.sim.run import Run

__all__ = [
    "BUILT_IN",
    "GROUND",
    "PREDICATES",
    "Collided",
    "Contact",
    "FailureSignature",
    "Fell",
    "Flipped",
    "FunctionPredicate",
    "HighCentered",
    "History",
    "Predicate",
    "PredicateSpec",
    "RobotState",
    "Stuck",
    "Timeout",
    "check_predicate",
    "check_predicate_models",
    "classify",
    "make_predicate",
    "predicate",
    "predicate_spec",
    "register_predicate",
    "same_failure",
    "signature",
]


# -- the oracle --------------------------------------------------------------------------------------
def same_failure(failure: FailureSignature, reference: FailureSignature,
                 tolerance: float = defaults.TOLERANCE) -> bool:
    """Whether `failure` is the reference failure f (see `classify`)."""
    if failure.predicate != reference.predicate:
        return False
    distance = float(np.linalg.norm(np.subtract(failure.position, reference.position)))
    if distance > tolerance:
        return False
    if reference.touched and not set(reference.touched) & set(failure.touched):
        return False
    return True


def classify(
    run: Run | None,
    reference: FailureSignature,
    tolerance: float = defaults.TOLERANCE,
    *,
    error: BaseException | None = None,
) -> Outcome:
    """Classify a run against the reference failure.

    - ERROR: `error` is given or `run` is None (the simulation or the test broke).
    - PASS: the run has no failure signature.
    - FAIL (same failure f): the same predicate fired, the failure position is within `tolerance` m (3D)
      of the reference's, and, if the robot touched models at the reference failure, it touches at least
      one of those same models now. The last rule tells "trapped in the gap, wedged against the far
      plateau" from "fell off the edge onto the bare ground" at the same spot, and the 3D distance (z
      included) tells it from "blocked by the wall at ground level".
    - OTHER: any other failure.
    """
    if tolerance < 0 or not math.isfinite(tolerance):
        raise ValueError(expected("a finite number >= 0", tolerance, "tolerance"))
    if error is not None or run is None:
        return Outcome.ERROR
    failure = run.failure
    if failure is None:
        return Outcome.PASS
    return Outcome.FAIL if same_failure(failure, reference, tolerance) else Outcome.OTHER
