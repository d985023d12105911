"""Prefetching: idle workers start the engine's next probes; no (candidate, attempt) is simulated twice."""

from __future__ import annotations

import threading
import time
from concurrent.futures import ThreadPoolExecutor

import pytest

from pytest_ddenv.errors import ReductionError
from pytest_ddenv.reduce import ProbeObservation, reduce

from .conftest import SetOracle, names

ELEMENTS = ("a", "b", "c", "d")
NEEDS = frozenset({"a", "c"})
"""With even parts [a, b] and [c, d], both subsets of the first round must be rejected (3 runs each)."""


def test_an_idle_worker_starts_the_next_round_while_the_last_probe_of_a_round_runs() -> None:
    oracle = SetOracle(NEEDS)
    next_round_started = threading.Event()
    waited: list[bool] = []

    def probe(candidate: tuple[str, ...], attempt: int) -> ProbeObservation:
        if len(candidate) == 1:  # a first-round candidate has 2 elements; the next round's have 1 or 3
            next_round_started.set()
        if candidate == ("c", "d") and attempt == 2:  # the last probe of the first round
            waited.append(next_round_started.wait(timeout=10.0))
        return oracle(candidate, attempt)

    with ThreadPoolExecutor(max_workers=2) as executor:
        result = reduce(ELEMENTS, probe, partition="even", priority="sequential", deflake=2, executor=executor,
                        workers=2)
    assert set(result.minimal) == NEEDS and result.one_minimal
    assert waited == [True], "the second worker stayed idle while the first round's last probe ran"
    serial = reduce(ELEMENTS, SetOracle(NEEDS), partition="even", priority="sequential", deflake=2)
    assert result.minimal == serial.minimal
    assert [size for _, size in result.steps] == [size for _, size in serial.steps]


def test_no_probe_is_simulated_twice_with_slow_flaky_probes() -> None:
    culprits = frozenset({"m0003", "m0011", "m0020"})
    oracle = SetOracle(culprits, rate=0.6, salt=11)

    def probe(candidate: tuple[str, ...], attempt: int) -> ProbeObservation:
        time.sleep(0.002 * (hash((candidate, attempt)) % 5))  # finishing order differs from starting order
        return oracle(candidate, attempt)

    serial = reduce(names(24), SetOracle(culprits, rate=0.6, salt=11), partition="even", deflake=3)
    with ThreadPoolExecutor(max_workers=2) as executor:
        parallel = reduce(names(24), probe, partition="even", deflake=3, executor=executor, workers=2)
    assert len(oracle.calls) == len(set(oracle.calls)), "a (candidate, attempt) was simulated twice"
    assert parallel.minimal == serial.minimal and parallel.failure_rate == serial.failure_rate


def test_the_adaptive_policy_keeps_one_attempt_in_flight_per_candidate() -> None:
    in_flight: dict[tuple[str, ...], int] = {}
    most = 0
    lock = threading.Lock()
    oracle = SetOracle(NEEDS, rate=0.6, salt=1)

    def probe(candidate: tuple[str, ...], attempt: int) -> ProbeObservation:
        nonlocal most
        with lock:
            in_flight[candidate] = in_flight.get(candidate, 0) + 1
            most = max(most, in_flight[candidate])
        time.sleep(0.002)
        with lock:
            in_flight[candidate] -= 1
        return oracle(candidate, attempt)

    with ThreadPoolExecutor(max_workers=3) as executor:
        reduce(names(12), probe, deflake="adaptive", partition="even", executor=executor, workers=3,
               failure_rate_runs=0)
    assert most == 1, "the sequential test decides one run at a time: no speculative re-runs"


def test_workers_is_the_number_of_probes_a_round_keeps_running() -> None:
    """`workers`, not the executor's own size, sets how many probes the engine submits at once."""
    running = most = 0
    lock = threading.Lock()
    oracle = SetOracle(frozenset({"m0002", "m0009"}), rate=0.7, salt=3)

    def probe(candidate: tuple[str, ...], attempt: int) -> ProbeObservation:
        nonlocal running, most
        with lock:
            running += 1
            most = max(most, running)
        time.sleep(0.002)
        with lock:
            running -= 1
        return oracle(candidate, attempt)

    serial = reduce(names(16), SetOracle(oracle.culprits, rate=0.7, salt=3), deflake=2, failure_rate_runs=0)
    with ThreadPoolExecutor(max_workers=6) as executor:
        parallel = reduce(names(16), probe, deflake=2, executor=executor, workers=1, failure_rate_runs=0)
    assert most == 1, f"{most} probes ran at once with workers=1"
    assert parallel.minimal == serial.minimal and parallel.steps == serial.steps


@pytest.mark.parametrize("workers", [0, -1, 1.5, "2", True])
def test_workers_must_be_a_positive_integer(workers: object) -> None:
    with ThreadPoolExecutor(max_workers=2) as executor, pytest.raises(ReductionError, match="workers: expected"):
        reduce(names(4), SetOracle(frozenset({"m0001"})), executor=executor, workers=workers)  # type: ignore[arg-type]
