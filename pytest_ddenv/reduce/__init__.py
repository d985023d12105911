"""The reduction engine: delta debugging over the elements of a failing world (a pure library).

It knows elements only by name; the caller supplies a probe (simulate a sub-world), optionally the
world's geometry and the reference trace of the failing run. See docs/algorithm.md.
"""

from pytest_ddenv.reduce.context import Context
from pytest_ddenv.reduce.deflake import (
    DEFLAKE_POLICIES,
    MAX_DEFLAKE,
    FixedReruns,
    SequentialTest,
)
from pytest_ddenv.reduce.engine import reduce
from pytest_ddenv.reduce.log import VOLATILE_FIELDS, ProbeLog
from pytest_ddenv.reduce.partition import PARTITIONS, Partitioner
from pytest_ddenv.reduce.priority import PRIORITIES, PRIORITY_ALIASES, Prioritizer
from pytest_ddenv.reduce.rates import Rate, RateComparison
from pytest_ddenv.reduce.settings import COMPLEMENT_ORDERS, GRANULARITIES, ReductionSettings
from pytest_ddenv.reduce.types import (
    Candidate,
    Decision,
    Geometry,
    Outcome,
    Precondition,
    Probe,
    ProbeCancelled,
    ProbeObservation,
    ProgressEvent,
    Reduction,
    ReductionInterrupted,
    Trace,
)

Observation = ProbeObservation
"""The old name of `ProbeObservation` (what a probe returns), kept for one release: `pytest_ddenv.Observation`
is what a controller sees."""

__all__ = [
    "COMPLEMENT_ORDERS",
    "DEFLAKE_POLICIES",
    "GRANULARITIES",
    "MAX_DEFLAKE",
    "PARTITIONS",
    "PRIORITIES",
    "PRIORITY_ALIASES",
    "VOLATILE_FIELDS",
    "Candidate",
    "Context",
    "Decision",
    "FixedReruns",
    "Geometry",
    "Observation",
    "Outcome",
    "Partitioner",
    "Precondition",
    "Prioritizer",
    "Probe",
    "ProbeCancelled",
    "ProbeLog",
    "ProbeObservation",
    "ProgressEvent",
    "Rate",
    "RateComparison",
    "Reduction",
    "ReductionInterrupted",
    "ReductionSettings",
    "SequentialTest",
    "Trace",
    "reduce",
]
