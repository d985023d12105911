"""The local Ray cluster of `--ddenv-executor ray`: a Ray head node started for the session, under a keeper
process that ends every process of it when the session closes it or dies.

`ray start --head --block` runs as the child of a keeper (``python -m pytest_ddenv.execution.ray_head``), a
child subreaper (Linux) so that the Ray processes orphaned on the way (agents, workers) stay its descendants.
The keeper waits for its standard input to close: the session closed the cluster, or the session's process
died (the pipe closes with it, even on SIGKILL). It then ends its descendants (`children.py`), removes the
head's temporary folder and exits.
Only those processes: another Ray cluster of the user is never touched (no `ray stop`). The head gets its
own temporary folder and free ports, no dashboard and no usage report. It asks for the node address
127.0.0.1, but Ray (2.60) registers the machine's address instead, and its servers listen on every
interface whatever the node address: so the head requires a token of its own (Ray's token authentication),
which only the session knows (`LocalHead.environ`).
"""

from __future__ import annotations

import contextlib
import os
import secrets
import select
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from pytest_ddenv.execution.errors import PoolConfigError

HEAD_TIMEOUT = 120.0
"""Seconds the head may take to start."""
STARTED = "Ray runtime started"
"""What `ray start` prints when the head runs."""
REAP_EVERY = 0.5
"""Seconds between two collections of the keeper's ended children."""


def free_port() -> int:
    """A TCP port of 127.0.0.1 that is free now."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def head_command(cpus: int, temp_dir: str, port: int) -> list[str]:
    """`ray start` for a head of `cpus` CPUs on 127.0.0.1, its GCS on `port`, its other fixed ports free ones."""
    ray = shutil.which("ray", path=os.path.dirname(sys.executable)) or shutil.which("ray")
    if ray is None:
        raise PoolConfigError("the ray executor needs the `ray` command: pip install 'pytest-ddenv[ray]'")
    return [ray, "start", "--head", "--block", "--node-ip-address", "127.0.0.1", "--port", str(port),
            "--num-cpus", str(cpus), "--num-gpus", "0", "--temp-dir", temp_dir, "--include-dashboard", "false",
            "--disable-usage-stats", "--ray-client-server-port", str(free_port()),
            "--dashboard-agent-listen-port", str(free_port()), "--object-store-memory", str(200 * 2**20)]


class LocalHead:
    """A Ray head of `cpus` CPUs started for this process (see the module docstring); `address` is its GCS
    address for `ray.init`. `close()` ends its processes and removes its temporary folder."""

    def __init__(self, cpus: int, *, timeout: float = HEAD_TIMEOUT) -> None:
        self.temp_dir = tempfile.mkdtemp(prefix="ddenv-ray-")
        port = free_port()
        self.address = f"127.0.0.1:{port}"
        self.environ = {"RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": secrets.token_hex(32)}
        """What a process connecting to this head needs in its environment (Ray reads it there)."""
        self._log = Path(self.temp_dir, "head.log")
        with open(self._log, "wb") as log:
            self._keeper = subprocess.Popen(
                [sys.executable, "-m", "pytest_ddenv.execution.ray_head", self.temp_dir,
                 *head_command(cpus, self.temp_dir, port)],
                stdin=subprocess.PIPE, stdout=log, stderr=subprocess.STDOUT,
                env={**os.environ, **self.environ, "RAY_USAGE_STATS_ENABLED": "0"},
            )
        try:
            self._await_start(timeout)
        except BaseException:
            self.close()
            raise

    def _await_start(self, timeout: float) -> None:
        deadline = time.monotonic() + timeout
        while STARTED not in self.log():
            if self._keeper.poll() is not None or time.monotonic() > deadline:
                tail = "\n".join(self.log().splitlines()[-15:])
                raise PoolConfigError(f"the local Ray cluster did not start (ray start --head):\n{tail}")
            time.sleep(0.1)

    def log(self) -> str:
        with contextlib.suppress(OSError):
            return self._log.read_text(errors="replace")
        return ""

    @property
    def pid(self) -> int:
        """The keeper's pid: every process of this head is under it."""
        return int(self._keeper.pid)

    def close(self, timeout: float = 30.0) -> None:
        if self._keeper.stdin is not None:
            with contextlib.suppress(OSError):
                self._keeper.stdin.close()
        try:
            self._keeper.wait(timeout)
        except subprocess.TimeoutExpired:
            from pytest_ddenv.execution.children import Process, _stat, descendants, end_processes

            status = _stat(self._keeper.pid)
            own = [Process(self._keeper.pid, status[2])] if status is not None else []
            end_processes(own + descendants(self._keeper.pid))
            self._keeper.wait()
        shutil.rmtree(self.temp_dir, ignore_errors=True)


def _reap_orphans() -> None:
    """Collect the exit status of the processes of the head that ended (as a subreaper, the keeper adopts
    those whose parent ended first: a probe process whose actor was killed)."""
    with contextlib.suppress(ChildProcessError):
        while os.waitpid(-1, os.WNOHANG)[0] > 0:
            pass


def keep(temp_dir: str, command: list[str]) -> int:
    """The keeper: run `command`, until standard input closes; then end every process under this one and
    remove `temp_dir` (the head's temporary folder)."""
    from pytest_ddenv.execution.children import become_subreaper, descendants, end_processes

    def stop(signum: int, frame: object) -> None:
        raise KeyboardInterrupt

    signal.signal(signal.SIGTERM, stop)
    become_subreaper(True)
    child = subprocess.Popen(command, stdin=subprocess.DEVNULL)
    with contextlib.suppress(OSError, KeyboardInterrupt):
        while not select.select([sys.stdin], [], [], REAP_EVERY)[0] or os.read(sys.stdin.fileno(), 65536):
            _reap_orphans()
    for _ in range(3):  # processes that were starting meanwhile
        if not end_processes(descendants(os.getpid()), grace=2.0):
            break
    with contextlib.suppress(ChildProcessError):
        child.wait(5)
    shutil.rmtree(temp_dir, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(keep(sys.argv[1], sys.argv[2:]))
