"""What crosses the process boundary: a simulation request, the faults a test may inject, and the code
that runs a request on a live `Simulator` (shared by local workers, dask tasks and the in-process pool)."""

from __future__ import annotations

import contextlib
import os
import signal
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal, Union

from pytest_ddenv.execution.errors import PoolConfigError
from pytest_ddenv.markers import PredicateSpec

if TYPE_CHECKING:
    from pytest_ddenv.oracle import Predicate
    from pytest_ddenv.sim import Run, RunSettings, Simulator
    from pytest_ddenv.world import World

PredicateLike = Union[PredicateSpec, "Predicate"]
"""A predicate as a spec (built on the worker: preferred) or as a picklable predicate object."""
FaultKind = Literal["crash", "kill", "exit", "hang", "error"]
FAULT_KINDS: tuple[FaultKind, ...] = ("crash", "kill", "exit", "hang", "error")
FAULT_ENV = "DDENV_FAULT_INJECTION"
"""Test-only: e.g. ``crash@3,hang@5,crash@7x2`` (kind@simulation-number[xTRIES]); read by pools created
without an explicit ``fault_injection=``."""


@dataclass(frozen=True)
class Fault:
    """Test-only: make the worker that runs the pool's `at`-th simulation (1-based, in submission order)
    misbehave, on the first `tries` tries of that simulation (2 = the retry faults too).

    crash: SIGSEGV; kill: SIGKILL; exit: os._exit(70); hang: sleep forever; error: raise RuntimeError.
    """

    kind: FaultKind
    at: int
    tries: int = 1

    def __post_init__(self) -> None:
        if self.kind not in FAULT_KINDS:
            raise PoolConfigError(f"unknown fault kind {self.kind!r}; valid kinds: {', '.join(FAULT_KINDS)}")
        for name in ("at", "tries"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise PoolConfigError(f"fault {name} must be an integer >= 1, got {value!r}")


def parse_faults(value: str | Sequence[Fault] | None) -> tuple[Fault, ...]:
    """Faults from a sequence, from text like ``crash@3,hang@5x2``, or from $DDENV_FAULT_INJECTION if None."""
    if value is None:
        value = os.environ.get(FAULT_ENV, "")
    if not isinstance(value, str):
        faults = tuple(value)
        if not all(isinstance(f, Fault) for f in faults):
            raise PoolConfigError(f"fault_injection must be Fault objects or text like 'crash@3', got {value!r}")
        return faults
    faults_list: list[Fault] = []
    for item in filter(None, (part.strip() for part in value.split(","))):
        kind, _, rest = item.partition("@")
        at, _, tries = rest.partition("x")
        if not at.isdigit() or (tries and not tries.isdigit()):
            raise PoolConfigError(f"fault {item!r}: expected kind@N or kind@NxTRIES, e.g. crash@3 or hang@5x2")
        faults_list.append(Fault(kind, int(at), int(tries or 1)))  # type: ignore[arg-type]
    return tuple(faults_list)


def fault_for(faults: Sequence[Fault], sequence: int, try_index: int) -> FaultKind | None:
    """The fault to inject into try `try_index` (0-based) of simulation number `sequence`, if any."""
    for fault in faults:
        if fault.at == sequence and try_index < fault.tries:
            return fault.kind
    return None


@dataclass(frozen=True)
class SimRequest:
    """One simulation, as plain picklable data."""

    world: World
    seed: int
    predicates: tuple[PredicateLike, ...]
    settings: RunSettings
    timeout: float | None
    fault: FaultKind | None = None


@dataclass(frozen=True)
class Reply:
    """A worker's answer: the Run, or the exception the simulation raised; `seconds` spent on the worker."""

    run: Run | None
    error: BaseException | None
    seconds: float


def build_predicates(predicates: Sequence[PredicateLike]) -> list[Predicate]:
    from pytest_ddenv.oracle import make_predicate

    built: list[Predicate] = []
    for item in predicates:
        if isinstance(item, PredicateSpec):
            built.append(make_predicate(item.name, **dict(item.params)))
        else:
            built.append(item)
    return built


def inject(fault: FaultKind | None) -> None:
    """Misbehave on purpose (test-only hook)."""
    if fault is None:
        return
    if fault == "crash":
        with contextlib.suppress(Exception):  # no core file: a test must not litter or wait for the dump
            import resource

            resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
        os.kill(os.getpid(), signal.SIGSEGV)
        time.sleep(5)  # the signal is delivered asynchronously
    if fault == "kill":
        os.kill(os.getpid(), signal.SIGKILL)
        time.sleep(5)
    if fault == "exit":
        os._exit(70)
    if fault == "hang":
        while True:
            time.sleep(3600)
    if fault == "error":
        raise RuntimeError("injected fault: the simulation raised on purpose")


def run_request(simulator: Simulator, request: SimRequest) -> Run:
    inject(request.fault)
    return simulator.run(
        request.world,
        seed=request.seed,
        predicates=build_predicates(request.predicates),
        settings=request.settings,
        timeout=request.timeout,
    )


def execute(simulator: Simulator, request: SimRequest) -> Reply:
    """Run `request`, catching what the simulation raises (a fault that kills the process is not caught)."""
    started = time.perf_counter()
    try:
        run = run_request(simulator, request)
    except Exception as error:  # noqa: BLE001 - sent back to the caller, which re-raises it
        return Reply(None, error, time.perf_counter() - started)
    return Reply(run, None, time.perf_counter() - started)


def describe_request(request: SimRequest) -> str:
    name = request.world.name or request.world.source or "world"
    return f"{name!s} ({len(request.world)} models, seed {request.seed})"

