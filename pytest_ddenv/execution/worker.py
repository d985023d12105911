"""The main loop of one simulation worker process: one live `Simulator`, requests in, replies out.

Protocol over a duplex pipe: the worker sends ``("ready", pid)`` once its simulator is up (or
``("failed", error)``), then answers each `SimRequest` with a `Reply`; ``None`` asks it to exit.
"""

from __future__ import annotations

import importlib
import os
import pickle
import signal
import traceback
from multiprocessing.connection import Connection

from pytest_ddenv.execution.errors import SimulationError
from pytest_ddenv.execution.request import Reply, SimRequest, execute


def portable(error: BaseException) -> BaseException:
    """`error` if it survives pickling, else a SimulationError carrying its type, message and traceback."""
    text = "".join(traceback.format_exception(error))
    try:
        copy = pickle.loads(pickle.dumps(error))
    except Exception:  # noqa: BLE001 - any unpicklable exception
        return SimulationError(f"the simulation raised {type(error).__qualname__}: {error}\n{text}")
    if isinstance(copy, BaseException):
        copy.add_note(f"(raised in simulation worker pid {os.getpid()})\n{text}")
        return copy
    return SimulationError(f"the simulation raised {type(error).__qualname__}: {error}")  # pragma: no cover


def _quiet_stdout() -> None:
    """pybullet prints to the C-level stdout; a worker's stdout is nobody's business (stderr stays)."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, 1)
        os.close(devnull)
    except OSError:  # pragma: no cover
        pass


def worker_main(conn: Connection, preload: tuple[str, ...] = ()) -> None:
    """Entry point of a worker process (must stay importable: spawn and forkserver import it by name).

    `preload`: modules to import first, e.g. the one that calls `register_robot` for a custom robot.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C reaches the whole process group: the parent decides
    _quiet_stdout()
    try:
        for module in preload:
            importlib.import_module(module)
        from pytest_ddenv.sim import Simulator

        simulator = Simulator()
    except BaseException as error:  # noqa: BLE001 - reported to the parent, which raises it
        conn.send(("failed", portable(error)))
        return
    conn.send(("ready", os.getpid()))
    try:
        while True:
            try:
                request = conn.recv()
            except (EOFError, OSError):  # the parent is gone
                break
            if request is None:
                break
            assert isinstance(request, SimRequest)
            reply = execute(simulator, request)
            if reply.error is not None:
                reply = Reply(None, portable(reply.error), reply.seconds)
            try:
                conn.send(reply)
            except (BrokenPipeError, OSError):
                break
    finally:
        simulator.close()
