"""The one place that says what a number, an integer or a flag is, and the spellings every front end
accepts alike."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pytest_ddenv.driver.markers import parse_ddenv_marker
from pytest_ddenv.reduce.partition import PARTITION_ALIASES
from pytest_ddenv.validation import is_finite_number, is_flag, is_integer, is_integral, is_number, is_real


@pytest.mark.parametrize(
    ("value", "flag", "number", "finite", "real", "integer", "integral"),
    [
        (True, True, False, False, False, False, False),
        (3, False, True, True, True, True, True),
        (3.0, False, True, True, True, False, False),
        (math.nan, False, True, False, True, False, False),
        (math.inf, False, True, False, True, False, False),
        (10**400, False, True, True, True, True, True),
        (np.int64(3), False, False, False, True, False, True),
        (np.float32(1.5), False, False, False, True, False, False),
        ("3", False, False, False, False, False, False),
        (None, False, False, False, False, False, False),
    ],
)
def test_what_counts_as_what(value: object, flag: bool, number: bool, finite: bool, real: bool, integer: bool,
                             integral: bool) -> None:
    assert (is_flag(value), is_number(value), is_finite_number(value), is_real(value), is_integer(value),
            is_integral(value)) == (flag, number, finite, real, integer, integral)


@pytest.mark.parametrize("alias", sorted(PARTITION_ALIASES))
def test_the_marker_accepts_the_partition_aliases_reduce_and_the_cli_accept(alias: str) -> None:
    assert parse_ddenv_marker((), {"partition": alias}).partition == PARTITION_ALIASES[alias]
