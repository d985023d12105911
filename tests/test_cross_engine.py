"""Cross-engine confirmation (issue 30, point 6): `--ddenv-confirm-engines`, its ini key, `ddenv reduce
--confirm-engines` and the marker's `confirm_engines=`; after a reduction the minimal and the original worlds
run in the other engine, both rates are reported with Wilson intervals, a failure the other engine does not
reproduce is flagged, every run is counted and logged by engine, and a resumed reduction reuses a run only in
the same engine and version. Real PyBullet and MuJoCo runs; pytester for the pytest front end."""

from __future__ import annotations

import json
import re
import sys
import textwrap
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("mujoco", reason="needs mujoco: pip install \"pytest-ddenv[mujoco]\"")
pytest.importorskip("pybullet", reason="confirms in pybullet and in mujoco: needs pybullet")

from pytest_ddenv.cli import main as cli
from pytest_ddenv.driver.cross_engine import EngineRate, WorldRates
from pytest_ddenv.driver.markers import MarkerError, parse_ddenv_marker
from pytest_ddenv.reduce import events
from pytest_ddenv.reduce.rates import Rate, clearly_below

DATA = Path(__file__).resolve().parent / "data"
TURN_WALL = DATA / "turn_wall.yaml"
"""Fails (the robot hits the wall) in PyBullet, and not in MuJoCo, where the Husky turns faster."""
INSTALL_HINT = 'the mujoco physics engine is not installed: pip install "pytest-ddenv[mujoco]"'


# -- the setting, in each front end -------------------------------------------------------------------------


def test_the_marker_argument_takes_one_engine_a_list_or_comma_separated_names() -> None:
    assert parse_ddenv_marker((), {"confirm_engines": "mujoco"}).confirm_engines == ("mujoco",)
    assert parse_ddenv_marker((), {"confirm_engines": "pybullet, mujoco"}).confirm_engines == ("pybullet", "mujoco")
    assert parse_ddenv_marker((), {"confirm_engines": ["mujoco", "mujoco"]}).confirm_engines == ("mujoco",)
    assert parse_ddenv_marker((), {}).confirm_engines == ()


@pytest.mark.parametrize(("value", "message"), [
    ("ode", "ddenv(confirm_engines=...): expected one of pybullet, mujoco, got 'ode'"),
    ("mujoco,", "ddenv(confirm_engines=...): expected one of pybullet, mujoco, got ''"),
    (3, "ddenv(confirm_engines=...): expected a comma-separated string or a list of engine names, got 3"),
])
def test_an_unknown_engine_in_the_marker_is_one_error_naming_the_argument(value: object, message: str) -> None:
    with pytest.raises(MarkerError) as raised:
        parse_ddenv_marker((), {"confirm_engines": value})
    assert str(raised.value) == message


def test_an_engine_that_is_not_installed_is_one_error_with_the_install_hint(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "mujoco", None)  # what `import mujoco` sees where it is not installed
    with pytest.raises(MarkerError) as raised:
        parse_ddenv_marker((), {"confirm_engines": "mujoco"})
    assert str(raised.value) == f"ddenv(confirm_engines=...): {INSTALL_HINT}"
    with pytest.raises(cli._ArgumentError, match=re.escape(f"argument --confirm-engines: {INSTALL_HINT}")):
        cli.build_parser().parse_args(["reduce", "w.yaml", "-p", "stuck", "--confirm-engines", "mujoco"])


def test_ddenv_reduce_takes_the_flag_and_refuses_an_unknown_engine_naming_it() -> None:
    parsed = cli.build_parser().parse_args(["reduce", "w.yaml", "-p", "stuck", "--confirm-engines", "mujoco,pybullet"])
    assert parsed.confirm_engines == ("mujoco", "pybullet")
    with pytest.raises(cli._ArgumentError, match=r"argument --confirm-engines: expected one of pybullet, mujoco, "
                                                 r"got 'bullet'"):
        cli.build_parser().parse_args(["reduce", "w.yaml", "-p", "stuck", "--confirm-engines", "bullet"])


@pytest.mark.parametrize("how", ["option", "ini"])
def test_an_unknown_engine_in_the_option_or_ini_key_is_one_usage_error_naming_it(pytester: pytest.Pytester,
                                                                                  how: str) -> None:
    pytester.makepyfile(test_nothing="def test_nothing():\n    pass\n")
    if how == "ini":
        pytester.makeini("[pytest]\nddenv_confirm_engines = mujoco, ode\n")
        result = pytester.runpytest_subprocess("-p", "no:cacheprovider")
        where = "ddenv_confirm_engines in tox.ini"
    else:
        result = pytester.runpytest_subprocess("-p", "no:cacheprovider", "--ddenv-confirm-engines", "ode")
        where = "--ddenv-confirm-engines"
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines([f"*{where}: expected one of pybullet, mujoco, got 'ode'*"])


# -- the rule that flags a failure (rates.clearly_below) and its words ---------------------------------------


def test_another_engine_clearly_below_the_reduction_s_engine_is_flagged() -> None:
    world = WorldRates("minimal", EngineRate("pybullet", "3.2.7", 10, 10), (EngineRate("mujoco", "3.3.0", 0, 10),))
    assert world.not_reproduced_in == ("mujoco",)
    assert world.flag == "possibly an artefact of the pybullet physics"
    assert world.describe() == ("fails in pybullet 10/10 [0.72, 1.00], in mujoco 0/10 [0.00, 0.28]: possibly an "
                                "artefact of the pybullet physics (mujoco does not reproduce it)")


@pytest.mark.parametrize(("other", "flagged"), [
    ((9, 10), False),  # within chance
    ((5, 10), True),  # one-sided Fisher p = 0.016
    ((0, 3), False),  # 0/3 against 3/3: p = 0.05, not below 5 %: too few runs to tell
    ((0, 0), False),  # no runs (every one errored): nothing to compare
])
def test_the_flag_is_the_one_sided_fisher_test_at_five_percent(other: tuple[int, int], flagged: bool) -> None:
    main = (10, 10) if other[1] != 3 else (3, 3)
    assert clearly_below(Rate(*other), Rate(*main)) is flagged
    world = WorldRates("original", EngineRate("mujoco", "3.3.0", *main), (EngineRate("pybullet", "3.2.7", *other),))
    assert (world.flag == "possibly an artefact of the mujoco physics") is flagged


def test_an_engine_run_event_reads_back_as_written() -> None:
    event = events.EngineRun(engine="mujoco 3.3.0", world="minimal", candidate=("wall",), attempt=2, seed=7,
                             outcome="fail", signature=None, sim_time=1.5, wall_time=0.2)
    assert events.decode(events.encode(event)) == event


# -- real reductions ---------------------------------------------------------------------------------------


def _reduce(out: Path, *extra: str) -> dict[str, Any]:
    argv = ["reduce", str(TURN_WALL), "-p", "collided:models=[wall]", "--tolerance", "1.5", "--engine", "pybullet", "--confirm-engines",
            "mujoco", "--workers", "1", "--media", "none", "--out", str(out), "--json", *extra]
    assert cli.main(argv) == 0
    return dict(json.loads((out / "summary.json").read_text(encoding="utf-8")))


def _logged(out: Path) -> list[events.Event]:
    read = [events.decode(line) for line in (out / "runs.jsonl").read_text(encoding="utf-8").splitlines()]
    return [event for event in read if isinstance(event, events.Event)]


@pytest.mark.slow
def test_a_failure_the_other_engine_does_not_reproduce_is_flagged_counted_and_resumed_by_engine(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "artifacts"
    summary = _reduce(out)
    crossed = summary["cross_engine"]
    pybullet, mujoco = crossed["minimal"]["rates"]
    assert (pybullet["engine"], mujoco["engine"]) == ("pybullet", "mujoco")
    assert (pybullet["fails"], pybullet["runs"]) == (summary["failure_rate"]["fails"], summary["failure_rate"]["runs"])
    assert mujoco["runs"] == pybullet["runs"] > 0 and mujoco["fails"] < pybullet["fails"]  # MuJoCo turns clear
    assert crossed["flag"] == crossed["minimal"]["flag"] == "possibly an artefact of the pybullet physics"
    original_mujoco = crossed["original"]["rates"][1]
    assert original_mujoco["runs"] == summary["original_failure_rate"]["runs"]
    # every cross-engine run is a simulation of the reduction, logged by engine (with workers 1 nothing is
    # speculative: the count is exact)
    logged = _logged(out)
    engine_runs = [event for event in logged if isinstance(event, events.EngineRun)]
    assert len(engine_runs) == crossed["simulations"] == mujoco["runs"] + original_mujoco["runs"]
    assert {event.engine.split()[0] for event in engine_runs} == {"mujoco"}
    probes = [event for event in logged if isinstance(event, events.Probe)]
    assert summary["simulations"] == len(probes) + len(engine_runs)  # ddenv reduce's run of the original is a probe line
    assert "possibly an artefact of the pybullet physics" in capsys.readouterr().out

    # resumed: the completed runs are reused in the same engine and version, none made again
    again = _reduce(out)["cross_engine"]
    assert again["simulations"] == 0
    assert sum(rate["reused"] for world in ("minimal", "original") for rate in again[world]["rates"]) == \
        len(engine_runs)
    assert again["minimal"]["rates"] == [pybullet, {**mujoco, "reused": mujoco["runs"]}]

    # a run of another version of the engine is not reused
    log = out / "runs.jsonl"
    log.write_text(log.read_text(encoding="utf-8").replace('"engine": "mujoco ', '"engine": "mujoco 0.0.0-'),
                   encoding="utf-8")
    third = _reduce(out)["cross_engine"]
    assert third["simulations"] == len(engine_runs)

    # killed after some of its cross-engine runs: the log ends after them; run again, only the rest are made
    lines = log.read_text(encoding="utf-8").splitlines(keepends=True)
    kept_runs = 3
    cut = [index for index, line in enumerate(lines) if '"event": "engine-run"' in line][-len(engine_runs) + kept_runs]
    log.write_text("".join(lines[:cut]), encoding="utf-8")
    resumed = _reduce(out)["cross_engine"]
    assert resumed["simulations"] == len(engine_runs) - kept_runs
    assert sum(rate["reused"] for world in ("minimal", "original") for rate in resumed[world]["rates"]) == kept_runs
    assert [(rate["fails"], rate["runs"]) for world in ("minimal", "original") for rate in resumed[world]["rates"]] \
        == [(rate["fails"], rate["runs"]) for world in ("minimal", "original") for rate in crossed[world]["rates"]]


PYTEST_PROJECT_TEST = textwrap.dedent(
    """\
    import pytest

    @pytest.mark.ddenv(world="wall.yaml", deflake=1)
    @pytest.mark.robot_failure("stuck", window=2.0, min_progress=0.2)
    def test_crosses(robot_world):
        try:
            robot_world.run()
        finally:  # a run that fails raises RobotFailure
            with open(ENGINES, "a") as engines:
                engines.write(robot_world.runs[-1].engine + "\\n")
    """
)


@pytest.mark.slow
@pytest.mark.parametrize(("workers", "how"), [("1", "option"), ("2", "ini"), ("2", "marker")])
def test_a_pytest_reduction_reports_both_engines_rates(pytester: pytest.Pytester, workers: str, how: str) -> None:
    pytester.makefile(".yaml", wall=(DATA / "wall.yaml").read_text(encoding="utf-8"))
    engines = pytester.path / "engines.txt"
    source = PYTEST_PROJECT_TEST.replace("ENGINES", repr(str(engines)))
    if how == "marker":
        source = source.replace("deflake=1)", "deflake=1, confirm_engines='mujoco')")
    pytester.makepyfile(test_wall=source)
    if how == "ini":
        pytester.makeini("[pytest]\nddenv_confirm_engines = mujoco\n")
    given = ["--ddenv-confirm-engines", "mujoco"] if how == "option" else []
    result = pytester.runpytest_subprocess(
        "-p", "no:cacheprovider", "--ddenv-reduce", "--ddenv-engine", "pybullet", *given,
        "--ddenv-workers", workers, "--ddenv-media", "none")
    result.assert_outcomes(failed=1)  # never turned into a pass
    result.stdout.fnmatch_lines([
        "*cross-engine: minimal world fails in pybullet */* [[]*, *[]], in mujoco */* [[]*, *[]]*",
        "*cross-engine: original world fails in pybullet */* [[]*, *[]], in mujoco */* [[]*, *[]]*",
        "*test_crosses: * -> * models *fails in pybullet */* [[]*], in mujoco */* [[]*]*",
    ])
    summary = json.loads(next((pytester.path / "ddenv-artifacts").glob("*/summary.json")).read_text())
    crossed = summary["cross_engine"]
    assert [rate["engine"] for rate in crossed["minimal"]["rates"]] == ["pybullet", "mujoco"]
    mujoco_runs = crossed["minimal"]["rates"][1]["runs"] + crossed["original"]["rates"][1]["runs"]
    # deflake=1 and a minimal world failing 5/5: the rate comparison made no run of the original (its outcomes
    # could not change the decision), so the original runs in pybullet here too, as often as the minimal world
    assert summary["original_failure_rate"] is None
    pybullet_original = crossed["original"]["rates"][0]["runs"]
    assert pybullet_original == crossed["minimal"]["rates"][0]["runs"] == crossed["original"]["rates"][1]["runs"]
    assert crossed["simulations"] == mujoco_runs + pybullet_original > 0
    # the probes of the other engine ran in it, though --ddenv-engine names pybullet
    ran = engines.read_text().split()
    assert ran.count("mujoco") == mujoco_runs and ran.count("pybullet") > mujoco_runs
