"""What crosses the process boundary: the `Job` a worker serves, a probe request and its reply, the faults a
test may inject, and `serve_requests`, the loop every job's `serve` runs (local workers, dask, in-process)."""

from __future__ import annotations

import contextlib
import hashlib
import os
import pickle
import signal
import sys
import threading
import time
import weakref
from collections import OrderedDict
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Literal, Protocol, runtime_checkable

from pytest_ddenv.detail import recording_detail
from pytest_ddenv.execution.errors import PoolConfigError
from pytest_ddenv.validation import expected, is_integer

if TYPE_CHECKING:
    from pytest_ddenv.world.model import World

FaultKind = Literal["crash", "kill", "exit", "hang", "error"]
FAULT_KINDS: tuple[FaultKind, ...] = ("crash", "kill", "exit", "hang", "error")
FAULT_ENV = "DDENV_FAULT_INJECTION"
"""Test-only: e.g. ``crash@3,hang@5,crash@7x2`` (kind@simulation-number[xTRIES]); read by pools created
without an explicit ``fault_injection=``."""


@dataclass(frozen=True)
class Fault:
    """Test-only: make the worker that runs the pool's `at`-th probe (1-based, in submission order)
    misbehave, on the first `tries` tries of that probe (2 = the retry faults too).

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
            if not is_integer(value) or value < 1:
                raise PoolConfigError(expected("an integer >= 1", value, f"fault {name}"))


def parse_faults(value: str | Sequence[Fault] | None) -> tuple[Fault, ...]:
    """Faults from a sequence, from text like ``crash@3,hang@5x2``, or from $DDENV_FAULT_INJECTION if None."""
    if value is None:
        value = os.environ.get(FAULT_ENV, "")
    if not isinstance(value, str):
        faults = tuple(value)
        if not all(isinstance(f, Fault) for f in faults):
            raise PoolConfigError(expected("Fault objects or text like 'crash@3'", value, "fault_injection"))
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
    """The fault to inject into try `try_index` (0-based) of probe number `sequence`, if any."""
    for fault in faults:
        if fault.at == sequence and try_index < fault.tries:
            return fault.kind
    return None


@dataclass(frozen=True)
class ProbeRequest:
    """One probe for a worker: run the job's test on `world` as re-run number `attempt` (picklable);
    `record`: the runs it makes record their full detail (`Run.detail`, for animations and recordings)."""

    world: World
    attempt: int
    fault: FaultKind | None = None
    record: bool = False

    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        """A large world travels as its pickled bytes (made once per `World` object on this side) and its
        digest; the receiving process keeps the last worlds it unpickled by digest (`SharedWorld`)."""
        world: Any = self.world
        if len(self.world) >= SHARED_WORLD_MODELS:
            world = SharedWorld.of(self.world)
        return (_request, (world, self.attempt, self.fault, self.record))


SHARED_WORLD_MODELS = 1000
"""Worlds of at least this many models are sent as `SharedWorld`s: pickling a 10 000-model world cost 0.2-0.35
s and unpickling it 0.17-0.25 s (a busy machine), every probe of the original world (its confirmation,
calibration and failure-rate runs); at 1 000 models both are about 15 ms."""
SHARED_WORLDS_KEPT = 2
"""Worlds a process keeps, by digest, of those it sent or received."""


@dataclass(frozen=True)
class SharedWorld:
    """A `World` as it crosses a process boundary again and again: its pickled bytes and their digest. The
    sender pickles a `World` object once (`of`); the receiver unpickles one digest once (`world`): the same
    world every time, so the runs are those of the world sent."""

    digest: str
    data: bytes

    _sent: ClassVar[OrderedDict[int, tuple[weakref.ref[World], SharedWorld]]] = OrderedDict()
    _received: ClassVar[OrderedDict[str, World]] = OrderedDict()
    _lock: ClassVar[threading.Lock] = threading.Lock()

    @classmethod
    def of(cls, world: World) -> SharedWorld:
        with cls._lock:
            known = cls._sent.get(id(world))
            if known is not None and known[0]() is world:
                cls._sent.move_to_end(id(world))
                return known[1]
        data = pickle.dumps(world, protocol=pickle.HIGHEST_PROTOCOL)
        shared = cls(hashlib.blake2b(data, digest_size=16).hexdigest(), data)
        with cls._lock:
            cls._sent[id(world)] = (weakref.ref(world), shared)
            while len(cls._sent) > SHARED_WORLDS_KEPT:
                cls._sent.popitem(last=False)
        return shared

    def world(self) -> World:
        with self._lock:
            known = self._received.get(self.digest)
            if known is not None:
                self._received.move_to_end(self.digest)
                return known
        world: World = pickle.loads(self.data)
        with self._lock:
            self._received[self.digest] = world
            while len(self._received) > SHARED_WORLDS_KEPT:
                self._received.popitem(last=False)
        return world


def _request(world: World | SharedWorld, attempt: int, fault: FaultKind | None, record: bool) -> ProbeRequest:
    """A `ProbeRequest` unpickled (`ProbeRequest.__reduce__`)."""
    return ProbeRequest(world.world() if isinstance(world, SharedWorld) else world, attempt, fault, record)


@dataclass(frozen=True)
class Reply:
    """A worker's answer: what the job's handler returned (`value`), or the exception the handler itself
    raised (`error`: a bug or a broken setup, never an outcome of the test); `seconds` spent on the worker."""

    value: Any
    error: BaseException | None
    seconds: float
    cpu_seconds: float = 0.0
    """CPU time of the thread that ran the probe (pybullet simulates in that thread)."""


class Channel(Protocol):
    """How a job's `serve` talks to whoever sends it probes (a pipe to the parent, a queue on dask)."""

    def ready(self) -> None:
        """The job can take probes now (its test is imported)."""

    def failed(self, message: str) -> None:
        """The job cannot start: `message` says why (an import error with its traceback, ...)."""

    def receive(self) -> ProbeRequest | None:
        """The next probe, or None: stop serving."""

    def send(self, reply: Reply) -> None: ...


Handler = Callable[["World", int], Any]
"""handler(world, attempt) -> the probe's result (a plain, picklable value)."""


@runtime_checkable
class Job(Protocol):
    """What a probe does and where its code comes from; picklable, sent to every worker.

    `serve(channel)` runs in the worker's main thread: it imports what the test needs, says `ready()` (or
    `failed(...)`), then answers probes until `receive()` gives None (use `serve_requests`). `key` is
    unique per job (workers that serve several jobs tell them apart by it); `label` names it in errors.
    """

    @property
    def key(self) -> str: ...

    @property
    def label(self) -> str: ...

    def serve(self, channel: Channel) -> None: ...


def serve_requests(channel: Channel, handle: Handler) -> None:
    """Say ready, then answer every probe with `handle(world, attempt)` until told to stop."""
    channel.ready()
    while (request := channel.receive()) is not None:
        channel.send(answer(request, handle))


def answer(request: ProbeRequest, handle: Handler) -> Reply:
    """Run one probe (after its injected fault, if any), catching what the handler raises."""
    started, cpu = time.perf_counter(), time.thread_time()
    try:
        inject(request.fault)
        with recording_detail(request.record):
            value = handle(request.world, request.attempt)
    except Exception as error:  # noqa: BLE001 - sent back to the caller, which re-raises it
        return Reply(None, error, time.perf_counter() - started, time.thread_time() - cpu)
    return Reply(value, None, time.perf_counter() - started, time.thread_time() - cpu)


def describe_request(label: str, request: ProbeRequest) -> str:
    name = request.world.name or request.world.source or "world"
    return f"{label} on {name!s} ({len(request.world)} models, attempt {request.attempt})"


def inject(fault: FaultKind | None) -> None:
    """Misbehave on purpose (test-only hook); says so on stderr first (pid included), so that a test can wait
    for the fault instead of guessing when it happens."""
    if fault is None:
        return
    with contextlib.suppress(Exception):
        sys.stderr.write(f"ddenv fault injection: {fault} (pid {os.getpid()})\n")
        sys.stderr.flush()
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
        raise RuntimeError("injected fault: the probe raised on purpose")
