"""Does `--ddenv-rate 20` report an interval that contains a scenario's true failure rate?

    python benchmarks/bench_rate.py --quick                      # 40 runs for the true rate, 3 repetitions
    python benchmarks/bench_rate.py [--out results.json]         # 200 runs, 20 repetitions (about 4 min on 2 cores)

The scenario is the doorway of examples/test_flaky_doorway.py (worlds/doorway.yaml, the `stuck` predicate
with window 5 s and min_progress 0.2 m): the Husky fits through with 6 cm to spare, and the start pose
jitter and actuation noise of the default `NoiseSettings` make a door jamb catch it on about 28 % of the
seeds (docs/benchmarks.md).

1. The true rate: the scenario run once per seed on seeds 0..199 (`--true-runs`) with the Python API, in this
   process (`RobotWorld(World.load(...), predicates=...).run(seed=s)`, a failure being a fired predicate or a
   missed goal, as the test's `assert run.reached_goal`), with its own Wilson 95 % interval.
2. `--repetitions` times, the example test as a user runs it in CI, in a fresh pytest process:
   `pytest examples/test_flaky_doorway.py --ddenv-rate 20 --ddenv-seed S --junitxml FILE` with the
   repetition's seed S = 1000 + r. Run i of a repetition uses the run seed S + i * 1000003, so the
   repetitions' runs are disjoint from each other and from the true rate's seeds. Each repetition's runs,
   failures, errors, interval and verdict are read from the JUnit properties (`ddenv_rate_*`) of the
   testcase, and the interval is checked to contain the true rate (the acceptance: at least 19 of 20).
3. Determinism: repetition 0's seed once more; its properties (the `ddenv_run_<i>` records included) must be
   identical to the first time's.
4. `--api-repetitions N` (default 0): N more repetitions of 20 runs with the Python API instead of pytest
   (seeds 2000 + r + i * 1000003, in `--api-workers` processes), to measure the coverage more precisely: a
   run's outcome is a function of its seed alone, the same in the pytest process, a probe worker and this
   process (tests/test_benchmarks_smoke.py compares them run by run). With them, a dispersion test of the
   repetitions' failure counts against the binomial (Pearson's chi-square): are the runs independent?

The table also gives the coverage a 95 % Wilson interval of 20 runs has at the measured true rate (the exact
binomial sum), i.e. how often a repetition is expected to contain it, and the coverage of the pooled rate (the
true rate's runs and every repetition's: a closer estimate of the true rate, on more seeds), and the
dispersion test of the repetitions' failure counts. `--out` writes everything as JSON.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import dataclasses
import functools
import json
import multiprocessing
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import ROOT, load, machine, table, write_json

from pytest_ddenv.oracle import PredicateSpec
from pytest_ddenv.reduce.rates import Rate, wilson_interval
from pytest_ddenv.scenario.robot_world import ATTEMPT_SEED_STRIDE, RobotFailure, RobotWorld
from pytest_ddenv.world import World

TEST = "examples/test_flaky_doorway.py::test_husky_drives_through_the_doorway"
WORLD = ROOT / "worlds" / "doorway.yaml"
PREDICATES = (PredicateSpec("stuck", {"window": 5.0, "min_progress": 0.2}),)
"""The example test's `robot_failure` marker."""
CONFIDENCE = 0.95
FIRST_API_SEED = 2000
"""Python API repetition r runs the seeds 2000 + r + i * 1000003: disjoint from the true rate's and the pytest
repetitions' seeds."""
FIRST_REPETITION_SEED = 1000
"""Repetition r runs with `--ddenv-seed 1000 + r`: its run seeds 1000 + r + i * 1000003 are disjoint from
the true rate's seeds (0..999 at most) and from every other repetition's."""
RATE_PROPERTIES = ("ddenv_rate_runs", "ddenv_rate_failures", "ddenv_rate_errors", "ddenv_rate_interval",
                   "ddenv_rate_verdict")


@dataclass(frozen=True)
class TrueRate:
    fails: int
    runs: int
    errors: int
    interval: tuple[float, float]
    seconds: float

    @property
    def rate(self) -> float:
        return self.fails / self.runs if self.runs else 0.0


@dataclass(frozen=True)
class Repetition:
    """One `pytest --ddenv-rate N` process, as its JUnit properties report it."""

    seed: int
    runs: int
    failures: int
    errors: int
    interval: tuple[float, float]
    verdict: str
    properties: dict[str, str]
    seconds: float
    exit_code: int
    output: str = ""
    """The end of pytest's output when a run erred (the JUnit record keeps a message's first 200 characters)."""

    def contains(self, rate: float) -> bool:
        return self.interval[0] <= rate <= self.interval[1]


def run_once(robot_world: RobotWorld, seed: int) -> str:
    """'failed', 'passed' or 'error' for one run of the scenario with `seed`, as the example test decides."""
    try:
        run = robot_world.run(seed=seed)
    except RobotFailure:
        return "failed"
    except Exception:  # noqa: BLE001 - a run that errs is counted as an error, never as a verdict
        return "error"
    return "passed" if run.reached_goal else "failed"


@functools.cache
def shared_robot_world() -> RobotWorld:
    return RobotWorld(World.load(WORLD), predicates=PREDICATES)


def true_rate(seeds: range) -> TrueRate:
    """The scenario's failure rate over `seeds`, one run each, in this process."""
    started = time.perf_counter()
    outcomes = [run_once(shared_robot_world(), seed) for seed in seeds]
    fails, errors = outcomes.count("failed"), outcomes.count("error")
    runs = len(outcomes) - errors
    return TrueRate(fails, runs, errors, wilson_interval(Rate(fails, runs), CONFIDENCE),
                    time.perf_counter() - started)


def api_repetition(seed: int, runs: int) -> list[str]:
    """The outcomes of the runs a `--ddenv-rate runs --ddenv-seed seed` repetition makes, with the Python API."""
    return [run_once(shared_robot_world(), seed + i * ATTEMPT_SEED_STRIDE) for i in range(runs)]


def api_coverage(count: int, runs: int, rate: float, workers: int) -> dict[str, Any]:
    """`count` repetitions of `runs` runs with the Python API: how many intervals contain `rate`, and Pearson's
    dispersion test of their failure counts."""
    seeds = [FIRST_API_SEED + r for r in range(count)]
    started = time.perf_counter()
    with concurrent.futures.ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn")) as pool:
        outcomes = list(pool.map(api_repetition, seeds, [runs] * count))
    counted = [Rate(o.count("failed"), len(o) - o.count("error")) for o in outcomes]
    covered = sum(low <= rate <= high for low, high in (wilson_interval(c, CONFIDENCE) for c in counted))
    statistic, p_value = dispersion(counted)
    return {"repetitions": count, "covered": covered, "fails": sum(c.fails for c in counted),
            "runs": sum(c.runs for c in counted), "errors": sum(o.count("error") for o in outcomes),
            "failures": [c.fails for c in counted], "dispersion_chi2": statistic, "dispersion_p": p_value,
            "seconds": time.perf_counter() - started}


def dispersion(counted: list[Rate]) -> tuple[float, float]:
    """Pearson's chi-square of the repetitions' failure counts against independent runs at their pooled rate,
    and its p-value (a small p: the counts spread more than independent runs give)."""
    from scipy.stats import chi2

    fails, total = sum(c.fails for c in counted), sum(c.runs for c in counted)
    mean = fails / total if total else 0.0
    if not 0 < mean < 1 or len(counted) < 2:
        return 0.0, 1.0
    statistic = sum((c.fails - c.runs * mean) ** 2 / (c.runs * mean * (1 - mean)) for c in counted)
    return statistic, float(chi2.sf(statistic, len(counted) - 1))


def rate_command(seed: int, runs: int, junit: Path, artifacts: Path) -> list[str]:
    """The CI command of one repetition (run from the repository's root, as the README's examples job)."""
    return [sys.executable, "-m", "pytest", TEST, "--ddenv-rate", str(runs), "--ddenv-seed", str(seed),
            f"--junitxml={junit}", "--ddenv-artifacts", str(artifacts), "-p", "no:cacheprovider", "-q"]


def junit_properties(path: Path, test_name: str) -> dict[str, str]:
    """The `<properties>` of the testcase named `test_name` in a JUnit XML file."""
    root = ET.parse(path).getroot()
    for case in root.iter("testcase"):
        if case.get("name") == test_name:
            return {prop.get("name", ""): prop.get("value", "") for prop in case.iter("property")}
    raise LookupError(f"{path}: no testcase named {test_name!r}")


def repetition_of(properties: dict[str, str], seed: int, seconds: float, exit_code: int) -> Repetition:
    """A repetition's figures from its JUnit properties (the shared contract of `--ddenv-rate`)."""
    missing = [name for name in RATE_PROPERTIES if name not in properties]
    if missing:
        raise LookupError(f"seed {seed}: the JUnit testcase has no {', '.join(missing)} property")
    low, high = (float(part) for part in properties["ddenv_rate_interval"].split(","))
    return Repetition(seed=seed, runs=int(properties["ddenv_rate_runs"]),
                      failures=int(properties["ddenv_rate_failures"]), errors=int(properties["ddenv_rate_errors"]),
                      interval=(low, high), verdict=properties["ddenv_rate_verdict"], properties=properties,
                      seconds=seconds, exit_code=exit_code)


def run_records(properties: dict[str, str]) -> list[dict[str, Any]]:
    """The `ddenv_run_<i>` records, in run order."""
    records = [json.loads(value) for name, value in properties.items() if name.startswith("ddenv_run_")]
    return sorted(records, key=lambda record: record["run"])


def repeat(seed: int, runs: int) -> Repetition:
    """One repetition: the example test with `--ddenv-rate runs --ddenv-seed seed` in a fresh pytest process."""
    with tempfile.TemporaryDirectory(prefix="ddenv-bench-rate-") as folder:
        junit = Path(folder) / "junit.xml"
        started = time.perf_counter()
        done = subprocess.run(rate_command(seed, runs, junit, Path(folder) / "artifacts"), cwd=ROOT,
                              capture_output=True, text=True, check=False)
        seconds = time.perf_counter() - started
        if not junit.exists():
            raise RuntimeError(f"seed {seed}: pytest wrote no JUnit XML (exit {done.returncode}):\n"
                               f"{done.stdout[-2000:]}{done.stderr[-2000:]}")
        properties = junit_properties(junit, TEST.rsplit("::", 1)[1])
    repetition = repetition_of(properties, seed, seconds, done.returncode)
    if repetition.errors:
        return dataclasses.replace(repetition, output=(done.stdout + done.stderr)[-4000:])
    return repetition


def expected_coverage(rate: float, runs: int) -> float:
    """The chance that the Wilson interval of `runs` runs at true rate `rate` contains `rate`."""
    from scipy.stats import binom

    return float(sum(binom.pmf(fails, runs, rate) for fails in range(runs + 1)
                     if (bounds := wilson_interval(Rate(fails, runs), CONFIDENCE))[0] <= rate <= bounds[1]))


def percent(interval: tuple[float, float]) -> str:
    return f"[{100 * interval[0]:.1f} %, {100 * interval[1]:.1f} %]"


def repetition_row(index: int, repetition: Repetition, rate: float) -> list[Any]:
    seeds = [str(record["seed"]) for record in run_records(repetition.properties) if record["outcome"] == "failed"]
    return [index, repetition.seed, f"{repetition.failures}/{repetition.runs}", repetition.errors,
            percent(repetition.interval), "yes" if repetition.contains(rate) else "NO", repetition.verdict,
            f"{repetition.seconds:.1f}", ", ".join(seeds[:3]) + (" ..." if len(seeds) > 3 else "")]


HEADERS = ("rep", "--ddenv-seed", "failed", "errors", "Wilson 95 %", "contains true rate", "verdict", "wall s",
           "failing run seeds")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="40 runs for the true rate, 3 repetitions")
    parser.add_argument("--true-runs", type=int, default=200, help="seeds 0..N-1 for the true rate (default 200)")
    parser.add_argument("--repetitions", type=int, default=20)
    parser.add_argument("--rate", type=int, default=20, help="--ddenv-rate of each repetition (default 20)")
    parser.add_argument("--api-repetitions", type=int, default=0,
                        help="more repetitions with the Python API, for the coverage (default 0)")
    parser.add_argument("--api-workers", type=int, default=2, help="processes for --api-repetitions (default 2)")
    parser.add_argument("--out", type=Path, help="write every measurement as JSON here")
    arguments = parser.parse_args(argv)
    true_runs, repetitions = (40, 3) if arguments.quick else (arguments.true_runs, arguments.repetitions)
    if not 0 < true_runs <= FIRST_REPETITION_SEED or repetitions < 1 or arguments.rate < 1:
        parser.error(f"--true-runs must be 1..{FIRST_REPETITION_SEED}, --repetitions and --rate at least 1")
    if not 0 <= arguments.api_repetitions <= 100_000 or arguments.api_workers < 1:
        parser.error("--api-repetitions must be 0..100000 and --api-workers at least 1")
    started = time.perf_counter()
    print(f"load {load()}; true rate: {true_runs} runs of {WORLD.relative_to(ROOT)} in this process", flush=True)
    truth = true_rate(range(true_runs))
    print(f"true rate: {truth.fails}/{truth.runs} = {100 * truth.rate:.1f} % {percent(truth.interval)}"
          f" ({truth.errors} errors, {truth.seconds:.1f} s, {truth.seconds / true_runs:.3f} s per run)", flush=True)

    done: list[Repetition] = []
    for index in range(repetitions):
        done.append(repeat(FIRST_REPETITION_SEED + index, arguments.rate))
        print(json.dumps({**asdict(done[-1]), "properties": None, "output": None}), file=sys.stderr, flush=True)
    again = repeat(done[0].seed, arguments.rate)
    identical = again.properties == done[0].properties
    differing = sorted(name for name in set(again.properties) | set(done[0].properties)
                       if again.properties.get(name) != done[0].properties.get(name))

    print()
    print(table(HEADERS, [repetition_row(index, rep, truth.rate) for index, rep in enumerate(done)]))
    covered = sum(rep.contains(truth.rate) for rep in done)
    expected = expected_coverage(truth.rate, arguments.rate)
    wall = time.perf_counter() - started
    print()
    print(f"true rate: {truth.fails}/{truth.runs} = {100 * truth.rate:.1f} % {percent(truth.interval)}")
    print(f"coverage: {covered} of {repetitions} intervals contain the true rate (acceptance: at least "
          f"{repetitions - repetitions // 20} of {repetitions}); a 95 % Wilson interval of {arguments.rate} runs "
          f"contains a rate of {100 * truth.rate:.1f} % with probability {100 * expected:.1f} %")
    pooled = Rate(truth.fails + sum(rep.failures for rep in done), truth.runs + sum(rep.runs for rep in done))
    pooled_rate = pooled.fails / pooled.runs
    pooled_covered = sum(rep.contains(pooled_rate) for rep in done)
    print(f"pooled rate (the true rate's runs and every repetition's): {pooled.fails}/{pooled.runs} = "
          f"{100 * pooled_rate:.1f} % {percent(wilson_interval(pooled, CONFIDENCE))}; {pooled_covered} of "
          f"{repetitions} intervals contain it")
    statistic, p_value = dispersion([Rate(rep.failures, rep.runs) for rep in done])
    print(f"dispersion of the repetitions' failures: chi-square {statistic:.1f} on {repetitions - 1} degrees of "
          f"freedom, p = {p_value:.2f}")
    print(f"deterministic: seed {done[0].seed} twice: "
          + ("identical properties" if identical else f"DIFFERENT properties: {', '.join(differing)}")
          + f" ({len(again.properties)} properties, {len(run_records(again.properties))} run records)")
    api = None
    if arguments.api_repetitions > 0:
        api = api_coverage(arguments.api_repetitions, arguments.rate, truth.rate, arguments.api_workers)
        print(f"Python API: {api['covered']} of {api['repetitions']} intervals of {arguments.rate} runs contain the "
              f"true rate; their failures {api['fails']}/{api['runs']}; dispersion chi-square "
              f"{api['dispersion_chi2']:.1f} on {api['repetitions'] - 1} degrees of freedom, p = "
              f"{api['dispersion_p']:.2f} ({api['seconds']:.0f} s)")
        wall = time.perf_counter() - started
    print(f"wall time: {wall / 60:.1f} min ({truth.seconds:.0f} s true rate, "
          f"{sum(rep.seconds for rep in done) + again.seconds:.0f} s for {repetitions + 1} pytest processes)")
    write_json(arguments.out, {
        "machine": machine(), "command": " ".join(rate_command(FIRST_REPETITION_SEED, arguments.rate,
                                                               Path("junit.xml"), Path("artifacts"))[1:]),
        "stride": ATTEMPT_SEED_STRIDE, "true_rate": asdict(truth), "repetitions": [asdict(rep) for rep in done],
        "coverage": [covered, repetitions], "expected_coverage": expected,
        "pooled": {"fails": pooled.fails, "runs": pooled.runs, "coverage": [pooled_covered, repetitions]},
        "dispersion": {"chi2": statistic, "p": p_value},
        "deterministic": {"seed": done[0].seed, "identical": identical, "differing": differing},
        "api": api, "wall_seconds": wall,
    })
    ok = covered >= repetitions - repetitions // 20 and identical
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
