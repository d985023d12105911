"""Smoke test of the benchmark scripts' building blocks on tiny worlds (< 30 s).

benchmarks/ is not a package: the modules are imported from its directory, as the scripts import them.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parent.parent / "benchmarks"


@pytest.fixture(scope="module")
def bench():
    sys.path.insert(0, str(BENCHMARKS))
    try:
        import common
        import make_yard

        yield common, make_yard
    finally:
        sys.path.remove(str(BENCHMARKS))


@pytest.fixture(scope="module")
def problem(bench):
    common, make_yard = bench
    world = make_yard.make_yard(5, seed=0)
    with common.pool_of(1) as pools:
        yield common.make_problem(world, make_yard.PREDICATES, 0, pools)


@pytest.fixture(scope="module")
def scripts(bench):
    sys.path.insert(0, str(BENCHMARKS))
    try:
        import bench_controller
        import bench_parallel

        yield bench_parallel, bench_controller
    finally:
        sys.path.remove(str(BENCHMARKS))


@pytest.fixture(scope="module")
def failure_rates(bench):
    sys.path.insert(0, str(BENCHMARKS))
    try:
        import bench_failure_rates

        yield bench_failure_rates
    finally:
        sys.path.remove(str(BENCHMARKS))


def test_yard_is_seeded_and_sized(bench):
    _, make_yard = bench
    text = make_yard.yard_yaml(50, seed=3)
    assert text == make_yard.yard_yaml(50, seed=3)
    assert text != make_yard.yard_yaml(50, seed=4)
    world = make_yard.make_yard(50, seed=3)
    assert len(world.names) == 50
    assert set(make_yard.CULPRITS) <= set(world.names)


def test_original_yard_fails_with_stuck(problem):
    assert problem.failure.startswith("stuck")
    assert len(problem.reducible) == 5


def test_problem_runs_on_an_in_process_scenario_job_pool(bench, problem):
    common, make_yard = bench
    pool = problem.pool
    assert pool.in_process and pool.size == 1
    assert pool.job.predicates == make_yard.PREDICATES and pool.job.seed == 0
    assert problem.pools.get(make_yard.PREDICATES, 0) is pool  # one pool per (predicates, seed), kept
    before = pool.stats.probes
    result = problem.call(problem.world.select(make_yard.CULPRITS), 0)
    assert result.error is not None and result.error.signature is not None
    assert pool.stats.probes == before + 1
    assert problem.counter.reset() == 1


def test_short_world_for_warm_up(bench):
    common, make_yard = bench
    world = make_yard.make_yard(5, seed=0)
    assert common.short_world(world).scenario.timeout == common.WARM_TIMEOUT
    assert common.short_world(world).names == world.names


def test_our_engine_finds_the_culprit(bench, problem):
    common, make_yard = bench
    row = common.ddenv_reduce(problem, partition="even", priority="sequential", deflake=0,
                              failure_rate_runs=1)
    assert tuple(row.minimal) == make_yard.CULPRITS
    assert row.one_minimal
    assert row.failure_rate == (1, 1)
    assert 0 < row.simulations < 20
    assert row.workers == 1
    assert row.to_dict()["reduction_percent"] == pytest.approx(80.0)


def test_our_engine_with_its_rate_comparison_counts_every_simulation(bench, problem):
    common, make_yard = bench
    row = common.ddenv_reduce(problem, partition="even", priority="sequential", deflake=0,
                              failure_rate_runs=0, rate_check_runs=5)
    assert tuple(row.minimal) == make_yard.CULPRITS
    # the yard's trap fails every run: 5 fresh runs of the minimal world, none of the original (bench_honesty.py)
    assert "fails 5/5 fresh runs" in row.extra["rate_check"] and row.extra["rate_backoffs"] == 0
    assert row.extra["simulations_started"] == row.extra["engine_simulations"] == row.extra["probes"] + 5


def test_picire_adapter_finds_the_culprit(bench, problem):
    pytest.importorskip("picire")
    common, make_yard = bench
    row = common.picire_reduce(problem, config_name="default", deflake=0, failure_rate_runs=0)
    assert tuple(row.minimal) == make_yard.CULPRITS
    assert row.one_minimal and not row.note
    assert row.simulations == row.extra["tests"] - row.extra["skipped"]
    assert row.extra["retests"] >= 1


@pytest.mark.parametrize("rule", [0, "auto"])
def test_failure_rates_of_a_minimal_world_on_fresh_seeds(bench, failure_rates, problem, rule):
    _, make_yard = bench
    fresh = failure_rates.FRESH_FIRST_ATTEMPT
    original = failure_rates.fresh_rate(problem, problem.world.names, 2, fresh, 1)
    assert (original["fails"], original["runs"]) == (2, 2)
    row = failure_rates.measure(problem, scenario="yard", partition="even", priority="sequential", rule=rule,
                                seed=1, workers=1, original=original, fresh_runs=2)
    assert problem.attempt_offset == 0  # the reduction seed's offset is not left behind
    assert tuple(row["minimal"]) == make_yard.CULPRITS
    assert row["one_minimal"] and row["minimal_size"] == 1 and row["original_size"] == 5
    assert row["minimal_fresh"]["runs"] == 2 and row["original_fresh"] == {"fails": 2, "runs": 2}
    assert row["below_half"] is (2 * row["minimal_fresh"]["fails"] < 2)
    assert row["fresh_attempts"] == [fresh, fresh + 1]
    # one worker: no speculation; every simulation is a probe (calibration included) or a fresh run of the
    # rate comparison (the minimal world's, and the original's beyond its calibration runs)
    assert row["rate_check"] == "holds" and row["rate_backoffs"] == 0
    assert row["not_decided_simulations"] == row["simulations"] - row["probes"] >= row["engine_failure_rate"][1] > 0
    if rule == 0:
        assert row["rule_used"] == "0" and row["calibration_runs"] == 0
    else:
        assert row["rule_used"].startswith("auto:") and row["calibration_runs"] >= 3
    cells = failure_rates.table_row(row)
    assert len(cells) == len(failure_rates.HEADERS) and cells[3] == "5 → 1"
    (line,) = failure_rates.summary_lines([row], [rule])
    assert line.startswith(f"rule {rule}: {int(row['below_half'])} of 1 minimal worlds")


def test_failure_rates_fresh_seeds_are_never_a_reductions(failure_rates):
    failure_rates.check_fresh([0, 1, 2], failure_rates.FRESH_FIRST_ATTEMPT)
    with pytest.raises(ValueError, match="reduction seed 1"):
        failure_rates.check_fresh([0, 1, 2], 1000)  # attempt 1000 + k is reduction seed 1's attempt k
    assert failure_rates.parse_rule("3") == 3 and failure_rates.parse_rule("auto") == "auto"
    with pytest.raises(Exception, match="deflake"):
        failure_rates.parse_rule("maybe")


def test_plain_text_table(bench):
    common, _ = bench
    text = common.table(["a", "bb"], [[1, 2], ["xyz", 4]])
    assert text.splitlines()[0] == "| a   | bb |"
    assert len(text.splitlines()) == 4


@pytest.mark.slow  # a real reduction in a worker process: the full tier only
def test_bench_parallel_reduces_through_the_driver(scripts, tmp_path):
    bench_parallel, _ = scripts
    world = bench_parallel.yard(6)
    predicates = (bench_parallel.PredicateSpec("stuck", {"window": 2.0, "min_progress": 0.2}),)
    with bench_parallel.warm_pool(1, world, predicates) as pool:
        outcome, seconds, total = bench_parallel.reduce_on(world, pool, tmp_path / "artifacts")
    assert outcome.status == "reduced"
    assert outcome.reduction.minimal == ("wall",)
    assert 0 < seconds <= total
    assert (tmp_path / "artifacts" / "summary.json").exists()


def test_bench_controller_measures_every_variant(scripts):
    _, bench_controller = scripts
    world = bench_controller.World.from_yaml(TINY)
    samples = bench_controller.measure(world, seeds=[0], repeat=1, timeout=0.25)
    assert [s.variant for s in samples] == list(bench_controller.VARIANTS)
    for sample in samples:
        assert sample.sim_time == pytest.approx(0.25, abs=0.06)
        assert sample.wall_per_sim_second > 0
    by_variant = {s.variant: s for s in samples}
    # the plain function computes the built-in law's command: the same trajectory, bit for bit
    assert by_variant["function"].final_pose == by_variant["builtin"].final_pose
    assert by_variant["scan"].final_pose == by_variant["builtin"].final_pose
    rows = bench_controller.summarize(samples)
    assert {row["variant"] for row in rows} == set(bench_controller.VARIANTS)
    assert next(r for r in rows if r["variant"] == "builtin")["slowdown"] == 0.0


TINY = """
format: 1
name: tiny
scenario: {start: {x: 0, y: 0, yaw: 0}, goal: {x: 4, y: 1}, timeout: 5}
models:
  - {name: box, pose: [1.5, 2.5, 0.25], box: [0.5, 0.5, 0.5]}
"""


def test_bench_stages_parses_the_examples_predicates_and_shortens_findings():
    sys.path.insert(0, str(BENCHMARKS))
    import bench_stages

    assert bench_stages.predicate_specs(("high_centered", "stuck:window=5,min_progress=0.2")) == (
        bench_stages.PredicateSpec("high_centered", {}),
        bench_stages.PredicateSpec("stuck", {"window": 5.0, "min_progress": 0.2}))
    assert bench_stages.short({"findings": ["a: x 1.2 -> 1 (the failure holds)", "b: the failure needs y"]}) == (
        "1 held; b: the failure needs y")
    assert bench_stages.short({"findings": [], "reverted": True}) == "reverted (rate)"


def test_bench_confirm_engines_runs_ddenv_reduce_with_the_other_engine_and_tabulates_its_rows():
    sys.path.insert(0, str(BENCHMARKS))
    try:
        import bench_confirm_engines
    finally:
        sys.path.remove(str(BENCHMARKS))

    words = bench_confirm_engines.command("rubble", 2, "mujoco", Path("out"))
    assert words[words.index("--confirm-engines") + 1] == "pybullet" and words[words.index("--seed") + 1] == "2"
    assert words.count("-p") == 2
    rate = {"engine": "pybullet", "fails": 10, "runs": 10, "errors": 0, "interval": [0.7225, 1.0]}
    other = {**rate, "engine": "mujoco", "fails": 0, "interval": [0.0, 0.2775]}
    row = {"scenario": "ditch", "seed": 0, "size": "43 -> 2", "minimal": [rate, other], "original": [rate, rate],
           "flag": "possibly an artefact of the pybullet physics", "confirm_simulations": 20, "confirm_cpu": 3.0,
           "confirm_wall": 2.5, "reduction_simulations": 40, "reduction_cpu": 9.0, "reduction_wall": 20.0}
    assert ("| ditch | 0 | 43 -> 2 | pybullet 10/10 [0.72, 1.00] | mujoco 0/10 [0.00, 0.28] | pybullet 10/10 "
            "[0.72, 1.00] | pybullet 10/10 [0.72, 1.00] | possibly an artefact of the pybullet physics |"
            ) in bench_confirm_engines.rates_table([row])
    assert "| ditch | 0 | 40, 9.0, 20.0 | 20, 3.0, 2.5 |" in bench_confirm_engines.cost_table([row])


@pytest.fixture(scope="module")
def bench_rate():
    sys.path.insert(0, str(BENCHMARKS))
    try:
        import bench_rate

        yield bench_rate
    finally:
        sys.path.remove(str(BENCHMARKS))


def test_bench_rate_true_rate_and_expected_coverage(bench_rate):
    truth = bench_rate.true_rate(range(2))
    assert truth.runs + truth.errors == 2 and truth.errors == 0
    assert truth.interval[0] <= truth.rate <= truth.interval[1]
    # the chance that a 95 % Wilson interval of 20 runs contains the true rate: about 95 %
    assert 0.9 < bench_rate.expected_coverage(0.3, 20) < 1.0
    words = bench_rate.rate_command(1000, 20, Path("j.xml"), Path("a"))
    assert words[words.index("--ddenv-rate") + 1] == "20" and words[words.index("--ddenv-seed") + 1] == "1000"


def test_bench_rate_dispersion_of_failure_counts(bench_rate):
    rate = bench_rate.Rate
    assert bench_rate.dispersion([rate(5, 20)] * 4) == (0.0, 1.0)  # no spread at all
    statistic, p_value = bench_rate.dispersion([rate(0, 20), rate(20, 20), rate(0, 20), rate(20, 20)])
    assert statistic == pytest.approx(80.0) and p_value < 1e-6  # all or nothing: not independent runs
    assert bench_rate.dispersion([rate(0, 20), rate(0, 20)]) == (0.0, 1.0)  # no failure: nothing to test


@pytest.mark.slow  # a pytest process whose runs go to probe workers: the full tier only
def test_bench_rate_repetition_agrees_with_the_python_api_run_by_run(bench_rate):
    repetition = bench_rate.repeat(1000, 4)
    records = bench_rate.run_records(repetition.properties)
    assert [r["run"] for r in records] == [0, 1, 2, 3]
    assert [r["seed"] for r in records] == [1000 + i * bench_rate.ATTEMPT_SEED_STRIDE for i in range(4)]
    # a run's outcome is its seed's, in a probe worker as in this process (what --api-repetitions relies on)
    assert [r["outcome"] for r in records] == bench_rate.api_repetition(1000, 4)
    assert repetition.runs + repetition.errors == 4
    assert repetition.failures == sum(r["outcome"] == "failed" for r in records)
    assert repetition.interval[0] <= repetition.failures / repetition.runs <= repetition.interval[1]
    assert repetition.verdict == "passed" and repetition.exit_code == 0  # the example allows up to 50 %


def test_the_honesty_verdict_compares_the_seeds_where_picire_returned_a_world(bench) -> None:
    common, _ = bench
    import bench_honesty

    def row(tool: str, seed: int, simulations: int, note: str = "") -> common.Row:
        return common.Row(tool=tool, world="rubble", seed=seed, partition="p", priority="q", deflake="0",
                          original_size=36, final_size=4, minimal=[], simulations=simulations, cache_hits=0,
                          one_minimal=True, failure_rate=(9, 10), wall_time=1.0, workers=1, failure="f", note=note,
                          extra={"simulations_started": simulations})

    ours = [row("ddenv", 0, 31), row("ddenv", 1, 76), row("ddenv", 2, 30)]
    theirs = [row("picire", 0, 52), row("picire", 1, 1, "picire aborted: the original passed"), row("picire", 2, 52)]
    assert bench_honesty.verdict(ours, theirs).startswith("yes on seeds [0, 2] (30.5 vs 52.0)")
    assert bench_honesty.verdict(ours, theirs[:1] + theirs[2:]).startswith("yes on seeds") is False
    assert bench_honesty.verdict(ours[1:2], theirs[1:2]) == "picire reduced nothing"
    slower = [row("ddenv", 0, 60), row("ddenv", 2, 60)]
    assert bench_honesty.verdict(slower, theirs[:1] + theirs[2:]).startswith("NO (+8.0)")
