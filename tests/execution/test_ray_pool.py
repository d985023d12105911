"""RayPool on a Ray cluster of this machine, in both forms: `ray` (the head the pool starts for the session)
and `ray://127.0.0.1:PORT` (a head the test starts with `ray start`, through the Ray client). The same runs,
the same minimal world; the test runs in the main thread of a probe process of each actor, which the
watchdog can kill; a crashed probe is retried once; no process of the session's head outlives it."""

from __future__ import annotations

import json
import os
import secrets
import shutil
import signal
import subprocess
import sys
import tempfile
import textwrap
import time
import uuid
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from plugin.conftest import WALL_WORLD
from plugin.test_plugin_user_code import MY_ROBOT_CONFTEST, USER_CODE_TEST

from pytest_ddenv.execution import (
    Channel,
    Fault,
    LocalPool,
    PoolConfigError,
    ProbeDeadline,
    WorkerError,
    WorkerStartError,
    make_cluster,
)
from pytest_ddenv.execution.children import Process, _stat, descendants, end_processes
from pytest_ddenv.execution.ray_head import STARTED, free_port
from pytest_ddenv.world import World

from .conftest import HANG, UserCodeJob, alive, gone, reduce_with, run_of, stuck_job

pytestmark = pytest.mark.slow  # Ray clusters (seconds to start), real reductions: the full tier only

ray = pytest.importorskip("ray", reason="ray is not installed (pip install 'pytest-ddenv[ray]')")

from pytest_ddenv.execution.ray_pool import RayCluster, RayPool  # noqa: E402 - after the importorskip

TESTS = str(Path(__file__).resolve().parents[1])


@pytest.fixture(scope="module")
def client_address() -> Iterator[str]:
    """A Ray head on this machine, started like a user's: `ray start --head` with its own temporary folder,
    ports and token, 4 (logical) CPUs: 2 for the module's cluster, 2 for a session's; its Ray client address.
    Stopped by ending its own processes (never `ray stop`)."""
    temp_dir = tempfile.mkdtemp(prefix="ddenv-test-ray-")
    client_port = free_port()
    command = [str(Path(sys.executable).with_name("ray")), "start", "--head", "--block", "--node-ip-address",
               "127.0.0.1", "--port", str(free_port()), "--ray-client-server-port", str(client_port),
               "--dashboard-agent-listen-port", str(free_port()), "--num-cpus", "4", "--temp-dir", temp_dir,
               "--include-dashboard", "false", "--disable-usage-stats", "--object-store-memory", str(200 * 2**20)]
    log = Path(temp_dir, "head.log")
    token = {"RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": secrets.token_hex(32)}
    with open(log, "wb") as out:  # the tests' modules (UserCodeJob) import in the actors
        head = subprocess.Popen(command, stdout=out, stderr=subprocess.STDOUT,
                                env={**os.environ, **token, "PYTHONPATH": os.pathsep.join(filter(None, (
                                    TESTS, os.environ.get("PYTHONPATH")))), "RAY_USAGE_STATS_ENABLED": "0"})
    patch = pytest.MonkeyPatch()
    for name, value in token.items():  # the Ray client (and the pytester sessions) find the token there
        patch.setenv(name, value)
    try:
        deadline = time.monotonic() + 120
        while STARTED not in log.read_text(errors="replace"):
            assert head.poll() is None and time.monotonic() < deadline, log.read_text(errors="replace")
            time.sleep(0.2)
        yield f"ray://127.0.0.1:{client_port}"
    finally:
        status = _stat(head.pid)
        end_processes(([Process(head.pid, status[2])] if status else []) + descendants(head.pid), grace=5.0)
        head.wait()
        patch.undo()
        shutil.rmtree(temp_dir, ignore_errors=True)


@pytest.fixture(scope="module", params=["ray", "ray-client"])
def cluster(request: pytest.FixtureRequest) -> Iterator[RayCluster]:
    """A `RayCluster` of 2 actors: the local head it starts itself, or the client connection to the test's
    head (one at a time: Ray's connection is one per process)."""
    address = "ray" if request.param == "ray" else request.getfixturevalue("client_address")
    cluster = make_cluster(address, 2)
    assert isinstance(cluster, RayCluster)
    try:
        yield cluster
    finally:
        cluster.close()


def test_a_cluster_has_one_actor_per_worker_with_the_same_versions(cluster: RayCluster) -> None:
    assert cluster.threads == 2
    with RayPool(stuck_job(), cluster) as pool:
        assert pool.size == 2 and not pool.in_process


def test_ray_runs_equal_local_runs(cluster: RayCluster, wall_world: World) -> None:
    job = stuck_job()
    with RayPool(job, cluster, watchdog=120.0) as remote, LocalPool(job, 1, in_process=job.handler()) as local:
        for world in (wall_world, wall_world.without(["wall"])):
            remote_run = run_of(remote.call(world, 3))
            local_run = run_of(local.call(world, 3))
            assert remote_run.same_trajectory(local_run) and remote_run.failure == local_run.failure


def test_a_reduction_on_ray_finds_the_same_minimal_world(cluster: RayCluster, wall_world: World) -> None:
    with RayPool(stuck_job(), cluster, watchdog=120.0) as pool:
        reduction = reduce_with(pool, wall_world)
        assert reduction.minimal == ("wall",) and reduction.one_minimal and reduction.errors == 0
        assert pool.stats.probes >= reduction.probes and pool.stats.errors == 0


def test_the_test_runs_in_the_main_thread_of_a_probe_process_kept_by_its_actor(
        cluster: RayCluster, wall_world: World, tmp_path: Path) -> None:
    actors = set(ray.get([actor.pid.remote() for actor in cluster._actors]))
    with RayPool(UserCodeJob(str(tmp_path / "pid")), cluster, watchdog=60.0) as pool:
        results = [pool.call(wall_world, attempt) for attempt in range(4)]
    assert all(result["models"] == len(wall_world) for result in results)  # UserCodeJob checks the main thread
    pids = {result["pid"] for result in results}
    assert not pids & actors and len(pids) <= 2  # not in the actors; kept from one probe to the next
    assert pool.stats.probes == 4 and pool.stats.errors == 0 and pool.stats.restarts == 0


def test_a_hung_probe_is_killed_by_the_watchdog_and_the_next_probe_runs(
        cluster: RayCluster, wall_world: World, tmp_path: Path) -> None:
    pid_file = tmp_path / "pid"
    with RayPool(UserCodeJob(str(pid_file)), cluster, watchdog=3.0) as pool:
        before = pool.call(wall_world, 0)
        with pytest.raises(WorkerError, match=r"ran past the 3 s watchdog; its probe process \(ray actor .* "
                                              r"pid \d+, probe process pid \d+\) was killed") as raised:
            pool.call(wall_world, HANG)
        assert not isinstance(raised.value, ProbeDeadline)
        assert gone(int(pid_file.read_text()))
        after = [pool.call(wall_world, attempt) for attempt in range(1, 4)]
        stats = pool.stats
    assert before["models"] == len(wall_world) and all(result["models"] == len(wall_world) for result in after)
    assert stats.timeouts == 1 and stats.errors == 1 and stats.probes == 4 and stats.cancelled == 0


def test_a_probe_past_its_deadline_is_killed_and_reported_as_a_deadline(
        cluster: RayCluster, wall_world: World, tmp_path: Path) -> None:
    pid_file = tmp_path / "pid"
    with RayPool(UserCodeJob(str(pid_file)), cluster, watchdog=60.0) as pool:
        pool.call(wall_world, 0)
        with pytest.raises(ProbeDeadline, match="stopped at the reduction's deadline; its probe process"):
            pool.call(wall_world, HANG, timeout=2.0)
        assert gone(int(pid_file.read_text()))
        assert pool.call(wall_world, 1)["models"] == len(wall_world)
        stats = pool.stats
    assert stats.cancelled == 1 and stats.timeouts == 0 and stats.errors == 0


def test_a_probe_process_that_crashes_is_replaced_and_its_probe_retried(
        cluster: RayCluster, wall_world: World, tmp_path: Path) -> None:
    job = UserCodeJob(str(tmp_path / "pid"))
    with RayPool(job, cluster, watchdog=60.0, fault_injection=[Fault("crash", 2)]) as pool:
        pool.call(wall_world, 0)
        second = pool.call(wall_world, 1)  # crashes once, then runs on a fresh probe process
        stats = pool.stats
    assert second["models"] == len(wall_world) and stats.errors == 0
    assert stats.crashes == 1 and stats.retries == 1 and stats.restarts == 1 and stats.simulations == 3
    with RayPool(job, cluster, watchdog=60.0, fault_injection=[Fault("kill", 1, tries=2)]) as pool:
        with pytest.raises(WorkerError, match="failed twice: its probe process died each time"):
            pool.call(wall_world, 0)
        assert pool.call(wall_world, 1)["models"] == len(wall_world)
        assert pool.stats.crashes == 2 and pool.stats.errors == 1 and pool.stats.simulations == 3


def test_an_actor_that_dies_is_replaced(cluster: RayCluster, wall_world: World, tmp_path: Path) -> None:
    job = UserCodeJob(str(tmp_path / "pid"))
    with RayPool(job, cluster, watchdog=60.0) as pool:
        pool.call(wall_world, 0)
        for actor in list(cluster._actors):
            ray.kill(actor, no_restart=True)
        errors = 0
        for attempt in range(1, 5):  # each dead actor fails one probe, then a fresh one runs the next
            try:
                assert pool.call(wall_world, attempt)["models"] == len(wall_world)
            except WorkerError as error:
                assert "its ray actor died" in str(error)
                errors += 1
        assert errors == pool.stats.errors == pool.stats.crashes <= 2 and cluster.threads == 2


@pytest.fixture
def user_project(pytester: pytest.Pytester) -> pytest.Pytester:
    """The plugin tests' user project: a robot registered by a conftest; a controller, a helper and a predicate
    of the test module (which only the pytester folder has)."""
    pytester.makefile(".yaml", wall=WALL_WORLD.replace("scenario:\n", "scenario:\n  robot: my_husky\n"))
    pytester.makeconftest(MY_ROBOT_CONFTEST)
    pytester.makepyfile(test_scenario=USER_CODE_TEST)
    return pytester


def test_a_reduction_with_user_code_finds_the_same_minimal_world_on_ray_as_locally(
        cluster: RayCluster, user_project: pytest.Pytester) -> None:
    """`--ddenv-executor ray` (the subprocess starts its own head) or the module's ray:// address."""
    executor = "ray" if cluster.address.startswith("ray (local") else cluster.address
    minimal = []
    for how in (["--ddenv-workers", "2"], ["--ddenv-executor", executor, "--ddenv-workers", "2"]):
        result = user_project.runpytest_subprocess("--ddenv-reduce", "--ddenv-media", "none", *how)
        result.assert_outcomes(failed=1)
        result.stdout.fnmatch_lines(["*'blocked' predicate fired*", "*reduced 6 -> 1 models*"])
        (summary_path,) = Path(user_project.path, "ddenv-artifacts").glob("*/summary.json")
        summary = json.loads(summary_path.read_text())
        assert summary["one_minimal"] and summary["errors"] == 0, how
        minimal.append(summary["minimal_models"])
        summary_path.unlink()
    assert minimal[0] == minimal[1] == ["wall"]


KEEPER = textwrap.dedent(
    """\
    import os, sys, time
    from pytest_ddenv.execution.children import descendants
    from pytest_ddenv.execution.ray_pool import RayCluster

    cluster = RayCluster("ray", n_workers=1)
    pids = [cluster._head.pid] + [process.pid for process in descendants(cluster._head.pid)]
    print(cluster._head.temp_dir, " ".join(map(str, pids)), flush=True)
    time.sleep(600)
    """
)


def test_the_local_head_ends_with_the_session_even_when_it_is_killed(tmp_path: Path) -> None:
    session = subprocess.Popen([sys.executable, "-c", KEEPER], stdout=subprocess.PIPE, text=True)
    try:
        assert session.stdout is not None
        temp_dir, *words = session.stdout.readline().split()
        pids = [int(word) for word in words]
        # the keeper, `ray start`, the GCS, the raylet, ...
        assert len(pids) > 3 and all(map(alive, pids)) and Path(temp_dir).is_dir()
    finally:
        session.send_signal(signal.SIGKILL)
        session.wait()
    assert all(gone(pid, within=30.0) for pid in pids)
    assert not Path(temp_dir).exists()  # the keeper removed it before it exited


def test_a_second_ray_connection_in_the_session_is_refused(cluster: RayCluster) -> None:
    with pytest.raises(PoolConfigError, match=r"needs this process's Ray connection, and it is already open"):
        make_cluster("ray", 1)


def test_ddenv_reduce_on_ray_finds_the_same_minimal_world(cluster: RayCluster, tmp_path: Path) -> None:
    world = tmp_path / "wall.yaml"
    world.write_text(WALL_WORLD)
    executor = "ray" if cluster.address.startswith("ray (local") else cluster.address
    ddenv = str(Path(sys.executable).with_name("ddenv"))
    found = []
    for how in (["--workers", "2"], ["--executor", executor, "--workers", "2"]):
        out = tmp_path / f"out-{len(found)}"
        done = subprocess.run([ddenv, "reduce", str(world), "-p", "stuck:window=2.0,min_progress=0.2", "--deflake",
                               "1", "--media", "none", "--out", str(out), "--json", *how],
                              capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, done.stderr
        summary = json.loads(done.stdout)
        assert summary["one_minimal"] and summary["errors"] == 0, how
        found.append(summary["minimal_models"])
    assert found[0] == found[1] == ["wall"]


def test_closing_the_pool_returns_its_running_probes_at_once_and_replaces_their_actors(
        cluster: RayCluster, wall_world: World, tmp_path: Path) -> None:
    import threading

    pid_file = tmp_path / "pid"
    job = UserCodeJob(str(pid_file))
    raised: list[BaseException] = []
    pool = RayPool(job, cluster, watchdog=600.0)

    def hang() -> None:
        try:
            pool.call(wall_world, HANG)
        except BaseException as error:  # noqa: BLE001 - the test looks at it
            raised.append(error)

    caller = threading.Thread(target=hang)
    caller.start()
    deadline = time.monotonic() + 120
    while not pid_file.exists() and time.monotonic() < deadline:
        time.sleep(0.05)
    pool.close()
    caller.join(timeout=30)
    assert not caller.is_alive() and len(raised) == 1
    assert isinstance(raised[0], WorkerError) and "closed while it ran" in str(raised[0])
    assert gone(int(pid_file.read_text()), within=30.0) and cluster.threads == 2
    with RayPool(job, cluster, watchdog=60.0) as again:
        assert [again.call(wall_world, attempt)["models"] for attempt in (0, 1)] == [len(wall_world)] * 2


@dataclass(frozen=True)
class UnstartableJob:
    """A job whose probe processes cannot start it (as when the test imports a module the node does not have)."""

    key: str = field(default_factory=lambda: uuid.uuid4().hex)

    @property
    def label(self) -> str:
        return "unstartable job"

    def serve(self, channel: Channel) -> None:
        channel.failed("ModuleNotFoundError: No module named 'lab_driver_only_on_the_ci_host'")


def test_a_test_that_cannot_start_in_an_actor_is_named_once_and_for_all(cluster: RayCluster,
                                                                        wall_world: World) -> None:
    with RayPool(UnstartableJob(), cluster, watchdog=60.0) as pool:
        for _ in range(2):  # the second call does not try again
            with pytest.raises(WorkerStartError, match=r"unstartable job: a ray actor could not start the test: "
                                                       r".*No module named 'lab_driver_only_on_the_ci_host'"):
                pool.call(wall_world, 0)
        assert pool.stats.errors == 1 and pool.stats.probes == 0
    assert cluster.threads == 2
