"""The words around a failing scenario test: which of pytest-ddenv's frames a traceback leaves out, short
reprs, plurals, angles without "-0", and the failure-rate line in words (issue 27, point 6)."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import pytest

from pytest_ddenv.oracle.predicates import FailureSignature
from pytest_ddenv.reduce import Observation, Outcome, Rate, Reduction, reduce
from pytest_ddenv.driver.report_text import failure_rate_line
from pytest_ddenv.scenario.robot_world import RobotWorld
from pytest_ddenv.sim import ControllerError, Simulator
from pytest_ddenv.sim.control import wrap_angle
from pytest_ddenv.sim.tracebacks import hidden_in_tracebacks
from pytest_ddenv.world import Model, Pose, Scenario, Shape, World


def box(name: str) -> Model:
    return Model(name, (Shape("box", size=(0.5, 0.5, 0.5)),), pose=Pose(9.0, 9.0, 0.25))


def open_world() -> World:
    return World(models=(box("far"),), scenario=Scenario(goal=(3.0, 0.0, None), timeout=2.0), name="open")


# -- which frames a traceback leaves out --------------------------------------------------------------------
def test_the_frames_on_the_way_to_the_users_controller_are_hidden() -> None:
    def divides(observation: Any) -> Any:
        return 1 / 0

    with Simulator() as sim, pytest.raises(ZeroDivisionError) as caught:
        sim.run(open_world(), controller=divides)
    assert hidden_in_tracebacks(caught)


def test_the_frames_of_a_broken_contract_are_hidden() -> None:
    with Simulator() as sim, pytest.raises(ControllerError) as caught:
        sim.run(open_world(), controller=lambda observation: "forward")
    assert hidden_in_tracebacks(caught)


def test_the_frames_of_an_exception_pytest_ddenv_did_not_mean_are_kept() -> None:
    with pytest.raises(TypeError) as caught:
        wrap_angle("north")  # type: ignore[arg-type]
    assert not hidden_in_tracebacks(caught)


# -- short reprs and plurals --------------------------------------------------------------------------------
def test_a_world_repr_names_the_world_its_size_and_its_first_models() -> None:
    many = World(models=tuple(box(f"crate_{index}") for index in range(40)), name="warehouse")
    assert repr(many) == "World('warehouse', 40 models: crate_0, crate_1, crate_2, crate_3, ...)"
    assert repr(World(models=(box("wall"),))) == "World(1 model: wall)"
    assert repr(World(name="empty")) == "World('empty', no models)"


def test_a_world_is_printed_short_by_hypothesis() -> None:
    from hypothesis.vendor.pretty import pretty

    many = World(models=tuple(box(f"crate_{index}") for index in range(40)), name="warehouse")
    assert pretty(many) == repr(many)


def test_a_robot_world_of_one_model_says_one_model() -> None:
    assert repr(RobotWorld(open_world())) == "RobotWorld('open', 1 model, seed=0)"


# -- angles --------------------------------------------------------------------------------------------------
def test_an_angle_or_a_position_just_below_zero_is_not_minus_zero() -> None:
    signature = FailureSignature("stuck", 3.15, (1.35, -0.002, 0.15, 1e-4, -1e-4, -0.003))
    assert "at (1.35, 0.00, 0.15) m, roll 0 deg, pitch 0 deg, yaw 0 deg" in signature.explain()
    tilted = FailureSignature("flipped", 1.0, (0.0, 0.0, 0.1, 0.0, -0.5, 3.0))
    assert "pitch -29 deg, yaw 172 deg" in tilted.explain()


# -- the failure-rate line --------------------------------------------------------------------------------
def _solid() -> Reduction:
    """A reduction whose minimal world fails every fresh run, as the original does."""
    return reduce(("a", "b"), lambda candidate, attempt: Observation(Outcome.FAIL if "a" in candidate
                                                                     else Outcome.PASS),
                  deflake="auto", failure_rate_runs=5)


def test_the_failure_rate_line_says_in_words_how_often_the_minimal_world_fails() -> None:
    solid = _solid()
    assert solid.rate_check is not None and solid.rate_check.decision == "holds"
    assert failure_rate_line(solid) == ("minimal world fails 5/5 fresh runs: not significantly less often than the "
                                        "original (3/3 fresh runs; 2 more could not change that; its rate: 57-100 % at 95 % "
                                        "confidence)")
    check = replace(solid.rate_check, original=Rate(5, 5), skipped=0)
    assert failure_rate_line(replace(solid, rate_check=check)) == (
        "minimal world fails as often as the original: 5/5 vs 5/5 fresh runs (its rate: 57-100 % at 95 % confidence)")
    fewer = replace(solid, rate_check=replace(check, original=Rate(20, 20), reduced=Rate(17, 20)))
    assert failure_rate_line(fewer) == ("minimal world fails about as often as the original: 17/20 vs 20/20 fresh "
                                        "runs (fewer, within chance; its rate: 64-95 % at 95 % confidence)")
    more = replace(solid, rate_check=replace(check, original=Rate(4, 5)))
    assert failure_rate_line(more) == ("minimal world fails at least as often as the original: 5/5 vs 4/5 fresh runs "
                                       "(its rate: 57-100 % at 95 % confidence)")
    below = replace(solid, rate_check=replace(check, reduced=Rate(0, 5), decision="below"), rate_backoffs=3)
    assert failure_rate_line(below) == ("minimal world fails less often than the original: 0/5 vs 5/5 fresh runs "
                                        "(warning: significantly less often, after 3 back-offs)")
    for line in map(failure_rate_line, (solid, fewer, more, below)):
        assert "Fisher" not in line and "p =" not in line
