"""The oracle: failure signatures and classify (same failure / other / pass / error)."""

from __future__ import annotations

import json

import pytest

from pytest_ddenv.oracle import FailureSignature, classify, same_failure
from pytest_ddenv.reduce.types import Outcome

REF = FailureSignature("stuck", 9.5, (1.45, -0.7, 0.98, 0.0, 0.3, 0.0), ("asphalt_plane", "asphalt_plane_clone"))


class _Result:  # classify only reads `.failure`
    def __init__(self, failure: FailureSignature | None) -> None:
        self.failure = failure


def test_signature_round_trip_and_explain() -> None:
    assert FailureSignature.from_dict(json.loads(json.dumps(REF.to_dict()))) == REF
    text = REF.explain()
    assert "'stuck'" in text and "9.50 s" in text and "asphalt_plane_clone" in text


@pytest.mark.parametrize(
    ("failure", "expected"),
    [
        (REF, Outcome.FAIL),
        (FailureSignature("stuck", 12.0, (1.6, -0.5, 0.9, 0, 0, 0), ("asphalt_plane_clone",)), Outcome.FAIL),
        (FailureSignature("flipped", 9.5, REF.pose, REF.touched), Outcome.OTHER),  # other kind
        (FailureSignature("stuck", 9.5, (3.0, -0.7, 0.98, 0, 0, 0), REF.touched), Outcome.OTHER),  # far away
        (FailureSignature("stuck", 9.5, (1.45, -0.7, 0.1, 0, 0, 0), REF.touched), Outcome.OTHER),  # z differs
        (FailureSignature("stuck", 9.5, REF.pose, ()), Outcome.OTHER),  # touches none of the reference's models
        (None, Outcome.PASS),
    ],
)
def test_classify(failure, expected) -> None:
    assert classify(_Result(failure), REF, 0.5) == expected  # type: ignore[arg-type]


def test_classify_errors() -> None:
    assert classify(None, REF) == Outcome.ERROR
    assert classify(_Result(REF), REF, error=RuntimeError("boom")) == Outcome.ERROR  # type: ignore[arg-type]
    with pytest.raises(ValueError):
        classify(_Result(REF), REF, -1.0)  # type: ignore[arg-type]


def test_tolerance_is_3d() -> None:
    near = FailureSignature("stuck", 1.0, (1.45, -0.7, 1.38, 0, 0, 0), REF.touched)
    assert same_failure(near, REF, 0.5) and not same_failure(near, REF, 0.3)
