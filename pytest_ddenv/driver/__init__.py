"""One reduction, from a failing test to its files (layer 10): what both front ends call.

`run` (`run_reduction(plan, pool)`: confirm the failure, reduce, run the stages, write the files, the report
and the media) with its parts: `plan` (`ReductionPlan`, `ReductionOutcome`), `logged_runs` (its own runs in the
log), `stages_phase` (the stages after the models), `media_phase` (the pictures; `LaterMedia`), `interrupts`
(SIGTERM and Ctrl-C), `import_ahead` (the heavy imports in a thread); `scenario_job` (`ScenarioJob`: a
world's scenario as the test, for `ddenv reduce` and the benchmarks) and `user_code` (the modules it imports in
each worker), `markers` (the `ddenv` and `robot_failure` markers' arguments as a `ReductionSpec`), `problem`
(which problem a run log belongs to) and `code_identity` (the code under test, by content), `artifacts` (the
files: lock, atomic writes, summary), `report` (`ReductionReport`, the typed result) and `report_text` (its
words), `other_failures` (the other failures the probes met), `pictures` and `picture_data` (the pictures of an
artifacts folder), `progress` (a reduction's progress line).

`run_reduction`, `ReductionPlan`, `ReductionOutcome` and `ScenarioJob` are imported here on first use, so
that a module of this package (the progress line at pytest's start) does not load the whole reduction.
"""

from importlib import import_module
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from pytest_ddenv.driver.run import ReductionOutcome, ReductionPlan, run_reduction
    from pytest_ddenv.driver.scenario_job import ScenarioJob

_LAZY = {
    "ReductionOutcome": "pytest_ddenv.driver.run",
    "ReductionPlan": "pytest_ddenv.driver.run",
    "run_reduction": "pytest_ddenv.driver.run",
    "ScenarioJob": "pytest_ddenv.driver.scenario_job",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'pytest_ddenv.driver' has no attribute {name!r}")


__all__ = ["ReductionOutcome", "ReductionPlan", "ScenarioJob", "run_reduction"]
