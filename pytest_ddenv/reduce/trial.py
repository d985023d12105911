"""Trials: a candidate of a round and why it is tried."""

from __future__ import annotations

from dataclasses import dataclass

from pytest_ddenv.reduce.types import Candidate


@dataclass(frozen=True)
class Trial:
    """One candidate of a round and why it is tried ("subset", "complement" or "verify"; the purpose of an
    extra run, "failure-rate" or "calibration", in its log records)."""

    candidate: Candidate
    kind: str
