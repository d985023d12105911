"""Issue 29, point 6: one of each mechanism (errors, rate statistics, budget, names), and the driver's typed
hand-overs (point 5)."""

from __future__ import annotations

import pytest

from pytest_ddenv.errors import ControllerError, ControllerTimeout, DdenvError


def test_every_error_the_package_raises_on_purpose_is_a_ddenv_error() -> None:
    from pytest_ddenv.media.writer import MediaChoiceError, media_choice
    from pytest_ddenv.stages import StagesError, parse_stages

    for error_type in (ControllerError, ControllerTimeout, StagesError, MediaChoiceError):
        assert issubclass(error_type, DdenvError), error_type
    # the builtin base classes users may catch stay
    assert issubclass(StagesError, ValueError) and issubclass(MediaChoiceError, ValueError)
    with pytest.raises(DdenvError, match="unknown stage"):
        parse_stages("models,colours")
    with pytest.raises(DdenvError, match=r"--media: expected one of all, pictures, none, got 'movies'"):
        media_choice("movies", "--media")


def test_a_controller_error_stays_the_tests_failure_not_an_error_of_ddenv() -> None:
    """ControllerError is a DdenvError now, but what the controller under test did is still the test's
    failure (a verdict), never an error of pytest-ddenv (which a probe reports as ERROR). A run stopped by
    its wall-clock cap (ControllerTimeout) is an error of the run, though (issue 33): ERROR, never a verdict."""
    from pytest_ddenv.errors import raised_by_ddenv
    from pytest_ddenv.outcome import Outcome
    from pytest_ddenv.scenario.probe import FailureReference, classify_result, describe_error

    for raised in (ControllerError("the controller returned NaN"),
                   ControllerTimeout("the run went past its wall-clock limit")):
        try:
            raise raised
        except ControllerError as error:
            info = describe_error(error, None)
        assert not info.ddenv_error and not raised_by_ddenv(raised)
        reference = FailureReference(info.type_name, info.location)
        expected = Outcome.ERROR if isinstance(raised, ControllerTimeout) else Outcome.FAIL
        assert classify_result(info, reference, 0.5) is expected
    assert raised_by_ddenv(DdenvError("x"))


def test_one_artifacts_error_for_the_folder_and_its_replay() -> None:
    from pytest_ddenv.cli.replay import ArtifactError
    from pytest_ddenv.driver.artifacts import ArtifactsError

    assert ArtifactError is ArtifactsError


def _classes_named(*names: str) -> list[str]:
    import ast
    from pathlib import Path

    import pytest_ddenv

    package = Path(pytest_ddenv.__file__).parent
    return sorted(f"{path.relative_to(package)}:{node.name}" for path in package.rglob("*.py")
                  for node in ast.walk(ast.parse(path.read_text()))
                  if isinstance(node, ast.ClassDef) and node.name in names)


def test_one_budget_module_and_one_observation_per_meaning() -> None:
    """The engine's budget and the stages' share of the driver's count are both in reduce/budget.py; the
    controller's `Observation` (the simulation's) and the probe's `ProbeObservation` (the engine's) differ by
    name."""
    from pytest_ddenv import reduce, stages
    from pytest_ddenv.reduce import budget

    assert _classes_named("Budget", "StageBudget") == ["reduce/budget.py:Budget", "reduce/budget.py:StageBudget"]
    assert _classes_named("Observation", "ProbeObservation") == ["reduce/types.py:ProbeObservation",
                                                                 "sim/control.py:Observation"]
    assert stages.StageBudget is budget.StageBudget and stages.Budget is budget.StageBudget  # the old name
    assert reduce.Observation is reduce.ProbeObservation  # the old name, for one release


def test_the_pool_protocol_declares_what_its_callers_use() -> None:
    """The driver and the front ends use `in_process`, `expect` and `notes` of a pool and a typed `call`:
    the protocol declares them (no `getattr(pool, ...)`), and both pools have them."""
    import inspect
    import typing

    from pytest_ddenv.execution import DaskPool, LocalPool, Pool, RayPool
    from pytest_ddenv.scenario.probe import ProbeResult

    for name in ("in_process", "expect", "notes", "call", "size", "stats", "close"):
        assert name in vars(Pool), name
    assert typing.get_args(Pool[ProbeResult]) == (ProbeResult,)  # `call` returns the job's result type
    assert inspect.signature(Pool.call).return_annotation == "ResultT_co"
    for pool in (DaskPool, LocalPool, RayPool):
        assert isinstance(inspect.getattr_static(pool, "in_process"), property), pool


def _package_lines_with(*fragments: str) -> list[str]:
    from pathlib import Path

    import pytest_ddenv

    package = Path(pytest_ddenv.__file__).parent
    return [f"{path.relative_to(package)}:{number}" for path in sorted(package.rglob("*.py"))
            for number, line in enumerate(path.read_text().splitlines(), 1)
            if any(fragment in line for fragment in fragments)]


def test_no_getattr_on_a_pool_and_no_data_attached_to_an_exception_past_its_type() -> None:
    assert _package_lines_with("getattr(pool", "getattr(self.pool", "getattr(stop") == []
    assert _package_lines_with(".outcome = outcome  # type: ignore", "stop.outcome, True  # type: ignore") == []


def test_an_interrupted_reductions_outcome_is_a_typed_field() -> None:
    import typing

    from pytest_ddenv.driver.run import ReductionOutcome, interrupted_outcome
    from pytest_ddenv.reduce import Reduction, ReductionInterrupted

    reduction = Reduction(original=("a", "b"), minimal=("a",), kept=(), probes=3, cache_hits=0, skipped=0, errors=0,
                          steps=(), one_minimal=False, incomplete_reason="interrupted", failure_rate=(0, 0),
                          wall_time=0.0, partition="model2model", priority="sequential", granularity="binary",
                          deflake=0, seed=0)
    stop = ReductionInterrupted(reduction)
    assert stop.outcome is None and interrupted_outcome(stop) is None
    assert "outcome" in typing.get_type_hints(ReductionInterrupted)
    outcome = ReductionOutcome("reduced")
    stop.outcome = outcome
    assert interrupted_outcome(stop) is outcome


def test_the_engine_uses_its_deciding_parts_without_a_pass_through_facade() -> None:
    """`Prober` only forwarded calls to the decider, the scheduler, the runner and the extra runs: the engine
    calls them itself; what is left wires them together and has no method."""
    import dataclasses

    from pytest_ddenv.reduce import prober

    assert not hasattr(prober, "Prober")
    assert dataclasses.is_dataclass(prober.Probing)
    assert [name for name, value in vars(prober.Probing).items() if callable(value) and not name.startswith("_")] == []


def test_one_verdict_function_judges_a_run_and_what_a_test_raised() -> None:
    """`classify` (a run against a reference signature) is `classify_result` (what a test raised against the
    reference failure) applied to the run's failure: one verdict, in the oracle."""
    import inspect

    from pytest_ddenv.oracle import verdict
    from pytest_ddenv.oracle.predicates import FailureSignature
    from pytest_ddenv.outcome import Outcome
    from pytest_ddenv.scenario import probe

    assert probe.classify_result is verdict.classify_result and probe.ErrorInfo is verdict.ErrorInfo
    assert probe.FailureReference is verdict.FailureReference
    assert "classify_result(" in inspect.getsource(verdict.classify)

    class Failed:
        def __init__(self, failure: FailureSignature | None) -> None:
            self.failure = failure

    here = FailureSignature("stuck", 3.0, (1.0, 0.0, 0.0, 0.0, 0.0, 0.0), ("wall",))
    near = FailureSignature("stuck", 3.5, (1.2, 0.0, 0.0, 0.0, 0.0, 0.0), ("wall",))
    far = FailureSignature("stuck", 3.5, (4.0, 0.0, 0.0, 0.0, 0.0, 0.0), ("wall",))
    assert [verdict.classify(Failed(f), here, 0.5) for f in (near, far, None)] == [
        Outcome.FAIL, Outcome.OTHER, Outcome.PASS]
    assert verdict.classify(None, here) is Outcome.ERROR
    assert verdict.classify(Failed(near), here, error=RuntimeError("x")) is Outcome.ERROR


def test_the_driver_writes_files_one_way() -> None:
    """The driver builds what a file says (a summary in report.py, a world by its format's writer) and then
    writes it (artifacts.py): artifacts.py knows no report, and no driver module goes back through the
    `World` methods that dispatch to the format layer."""
    import ast
    from pathlib import Path

    from pytest_ddenv import driver

    folder = Path(driver.__file__).parent
    tree = ast.parse((folder / "artifacts.py").read_text())
    modules = {node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)}
    names = {alias.name for node in ast.walk(tree) if isinstance(node, ast.ImportFrom) for alias in node.names}
    assert "pytest_ddenv.driver.report" not in modules and "Reduction" not in names
    assert [line for line in _package_lines_with(".to_yaml(", ".to_sdf(") if line.startswith("driver/")] == []
