"""The main function of one local worker process: it serves one `Job` over a duplex pipe.

Protocol: the worker sends ``("ready", pid)`` once the job can take probes (or ``("failed", message)``),
then answers each `ProbeRequest` with a `Reply`; ``None`` asks it to stop.
"""

from __future__ import annotations

import os
import pickle
import signal
import traceback
from multiprocessing.connection import Connection

from pytest_ddenv.errors import DdenvError
from pytest_ddenv.execution.children import become_subreaper, descendants, end_processes
from pytest_ddenv.execution.errors import WorkerError
from pytest_ddenv.execution.request import Job, ProbeRequest, Reply


def portable(error: BaseException) -> BaseException:
    """`error` if it survives pickling, else a WorkerError carrying its type, message and traceback."""
    text = "".join(traceback.format_exception(error))
    try:
        copy = pickle.loads(pickle.dumps(error))
    except Exception:  # noqa: BLE001 - any unpicklable exception
        return WorkerError(f"the probe raised {type(error).__qualname__}: {error}\n{text}")
    if isinstance(copy, BaseException):
        copy.add_note(f"(raised in probe worker pid {os.getpid()})\n{text}")
        return copy
    return WorkerError(f"the probe raised {type(error).__qualname__}: {error}")  # pragma: no cover


def quiet_stdout() -> None:
    """pybullet and pytest print to the C-level stdout; a worker's stdout is nobody's business (stderr stays)."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, 1)
        os.close(devnull)
    except OSError:  # pragma: no cover
        pass


class PipeChannel:
    """The worker's end of the pipe to the pool (see the module docstring)."""

    def __init__(self, conn: Connection) -> None:
        self.conn = conn
        self.said_ready = False
        self.closed = False

    def ready(self) -> None:
        self.said_ready = True
        self.conn.send(("ready", os.getpid()))

    def failed(self, message: str) -> None:
        self.said_ready = True
        self.conn.send(("failed", message))

    def receive(self) -> ProbeRequest | None:
        if self.closed:
            return None
        try:
            request = self.conn.recv()
        except (EOFError, OSError):  # the parent is gone
            request = None
        if request is None:
            self.closed = True
            return None
        assert isinstance(request, ProbeRequest)
        return request

    def send(self, reply: Reply) -> None:
        if reply.error is not None:
            reply = Reply(None, portable(reply.error), reply.seconds)
        try:
            self.conn.send(reply)
        except (BrokenPipeError, OSError):
            self.closed = True


def worker_main(conn: Connection, job: Job) -> None:
    """Entry point of a worker process (must stay importable: spawn and forkserver import it by name)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C reaches the whole process group: the parent decides
    quiet_stdout()
    become_subreaper()  # what the probes start stays under this process, to be ended with it
    channel = PipeChannel(conn)
    try:
        job.serve(channel)
    except BaseException as error:
        if channel.said_ready:
            raise
        # An error pytest-ddenv raises on purpose says what and where: its traceback would only be noise.
        shown = "" if isinstance(error, DdenvError) else "\n" + "".join(traceback.format_exception(error))
        try:  # the pool reports it: no second copy on the worker's stderr
            channel.failed(f"{type(error).__name__}: {error}{shown}")
        except (BrokenPipeError, OSError):
            raise error from None
    finally:
        if not channel.said_ready:  # serve() returned without a word: nothing to serve
            try:
                channel.failed(f"{job.label}: the worker stopped before it could take probes")
            except (BrokenPipeError, OSError):
                pass
        end_processes(descendants(os.getpid()))  # the processes its probes started end with it
