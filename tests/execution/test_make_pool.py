"""make_pool and the validation of pool settings."""

from __future__ import annotations

import re
import sys

import pytest

from pytest_ddenv.execution import (
    Fault,
    LocalPool,
    PoolConfigError,
    cpu_count,
    make_pool,
    resolve_workers,
)
from pytest_ddenv.execution.factory import executor_problem
from pytest_ddenv.execution.request import fault_for, parse_faults

from .conftest import stuck_job


def test_workers_auto_is_one_per_core() -> None:
    assert resolve_workers("auto") == cpu_count() >= 1
    assert resolve_workers("3") == resolve_workers(3) == 3


@pytest.mark.parametrize("workers", [0, -1, "two", True, 1.5, None, ""])
def test_bad_worker_counts_are_refused(workers: object) -> None:
    message = f"workers: expected an integer >= 1 or 'auto', got {workers!r}"
    with pytest.raises(PoolConfigError, match=re.escape(message)):
        make_pool(stuck_job(), workers)  # type: ignore[arg-type]


@pytest.mark.parametrize("executor", ["http://host:8786", "threads", "tcp:/host", "ray://host", "rays", "ray://h:1/x"])
def test_bad_executors_are_refused(executor: str) -> None:
    with pytest.raises(PoolConfigError, match=f"executor: expected 'local', 'dask' or a dask scheduler address .*, got "
                                              f"'{executor}'"):
        make_pool(stuck_job(), 2, executor)


@pytest.mark.parametrize("executor", ["local", "dask", "tcp://host:8786", "tls://host:8786", "ray", "ray://host:10001"])
def test_every_executor_form_is_accepted(executor: str) -> None:
    assert executor_problem(executor) is None


def test_the_ray_executor_without_ray_names_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` raises ImportError
    with pytest.raises(PoolConfigError, match=re.escape("the ray executor needs ray: pip install 'pytest-ddenv[ray]'")):
        make_pool(stuck_job(), 2, "ray")


def test_one_worker_is_in_process_when_given_a_handler() -> None:
    job = stuck_job()
    with make_pool(job, 1, in_process=job.handler()) as pool:
        assert isinstance(pool, LocalPool) and pool.in_process and pool.size == 1
    with make_pool(job, 1) as pool:
        assert isinstance(pool, LocalPool) and not pool.in_process and pool.size == 1


def test_fork_and_bad_settings_are_refused() -> None:
    with pytest.raises(PoolConfigError, match="fork"):
        LocalPool(stuck_job(), 2, context="fork")
    with pytest.raises(PoolConfigError, match="watchdog: expected a number of seconds > 0, 'auto' or None, got 0"):
        LocalPool(stuck_job(), 2, watchdog=0)
    job = stuck_job()
    with pytest.raises(PoolConfigError, match="would take down the calling process"):
        LocalPool(job, 1, in_process=job.handler(), fault_injection="crash@1")
    with pytest.raises(PoolConfigError, match="needs a Job"):
        LocalPool("not a job", 2)  # type: ignore[arg-type]


def test_fault_specifications() -> None:
    assert parse_faults("crash@3, hang@5x2") == (Fault("crash", 3), Fault("hang", 5, 2))
    assert fault_for(parse_faults("hang@5x2"), 5, 1) == "hang" and fault_for(parse_faults("hang@5"), 5, 1) is None
    for text in ("crash", "crash@x", "boom@1", "crash@0"):
        with pytest.raises(PoolConfigError):
            parse_faults(text)


def test_faults_come_from_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("DDENV_FAULT_INJECTION", "exit@2")
    assert parse_faults(None) == (Fault("exit", 2),)
