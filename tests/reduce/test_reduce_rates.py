"""The sequential comparison of a reduced world's failure rate with the original's (`reduce.rates`)."""

from __future__ import annotations

import numpy as np
import pytest

from pytest_ddenv.reduce.rates import LEVEL, LOOKS, Rate, compare, next_look


def run_sequential(rng: np.random.Generator, original_rate: float, reduced_rate: float) -> tuple[str, int]:
    """The procedure the engine follows: top both worlds up to each look, stop at the first decision."""
    original = reduced = np.zeros(0, dtype=bool)
    while True:
        look = next_look(len(reduced))
        original = np.concatenate([original, rng.random(look - len(original)) < original_rate])
        reduced = np.concatenate([reduced, rng.random(look - len(reduced)) < reduced_rate])
        result = compare(Rate(int(original.sum()), look), Rate(int(reduced.sum()), look))
        if result.decision != "continue":
            return result.decision, look


@pytest.mark.parametrize("rate", [1.0, 0.9, 0.6, 0.3])
def test_an_equally_failing_world_is_called_below_at_most_at_the_level(rate: float) -> None:
    rng = np.random.default_rng(7)
    decisions = [run_sequential(rng, rate, rate)[0] for _ in range(1000)]
    assert decisions.count("below") / len(decisions) <= LEVEL


def test_a_world_failing_less_than_half_as_often_is_caught() -> None:
    rng = np.random.default_rng(11)
    decisions = [run_sequential(rng, 1.0, 0.4)[0] for _ in range(500)]
    assert decisions.count("below") / len(decisions) > 0.95


def test_a_world_failing_as_often_usually_stops_at_the_first_look() -> None:
    rng = np.random.default_rng(3)
    looks = [run_sequential(rng, 1.0, 1.0)[1] for _ in range(50)]
    assert set(looks) == {LOOKS[0]}


def test_decisions_at_each_look() -> None:
    assert compare(Rate(5, 5), Rate(5, 5)).decision == "holds"
    assert compare(Rate(5, 5), Rate(2, 5)).decision == "continue"  # p = 0.083: not yet
    below = compare(Rate(10, 10), Rate(4, 10))
    assert below.decision == "below" and below.p_value == pytest.approx(1001 / 184756)
    assert "significantly below" in below.describe() and "4/10" in below.describe()
    assert compare(Rate(20, 20), Rate(15, 20)).decision == "holds"  # last look, p = 0.024 > 0.05 / 3
    assert compare(Rate(5, 10), Rate(5, 5)).decision == "holds"  # more often than the original
    assert compare(Rate(0, 0), Rate(0, 0)).decision == "continue"


def test_bad_arguments_are_refused() -> None:
    with pytest.raises(ValueError, match="fails <= runs"):
        Rate(3, 2)
    with pytest.raises(ValueError, match="increasing"):
        compare(Rate(1, 1), Rate(1, 1), looks=(10, 5))
    assert next_look(0) == 5 and next_look(5) == 10 and next_look(20) == 0


# -- in the engine: a minimal world that fails rarely is caught, the reduction backs off -----------------


def rare_without_b(salt: int):  # type: ignore[no-untyped-def]
    """f always with both 'a' and 'b'; with 'a' alone f only 30 % of the runs (a lucky deflake rule accepts it)."""
    from pytest_ddenv.reduce import Outcome, ProbeObservation

    from .conftest import uniform

    def probe(candidate: tuple[str, ...], attempt: int) -> ProbeObservation:
        present = set(candidate)
        fails = {"a", "b"} <= present or ("a" in present and uniform(candidate, attempt, salt) < 0.3)
        return ProbeObservation(Outcome.FAIL if fails else Outcome.PASS, signature={"kind": "stuck"}, seed=attempt)

    return probe


ELEMENTS = ("a", "b", "c", "d", "e", "f")


def test_a_rarely_failing_minimal_world_is_backed_off_from(tmp_path) -> None:  # type: ignore[no-untyped-def]
    from pytest_ddenv.reduce import ProbeLog, reduce

    # deflake=3 accepts {'a'} (30 % per run, 4 runs) about three times in four: find a salt where it does
    for salt in range(20):
        log = tmp_path / f"runs-{salt}.jsonl"
        result = reduce(ELEMENTS, rare_without_b(salt), deflake=3, partition="even", priority="sequential",
                        log=log)
        if result.rate_backoffs:
            break
    else:
        pytest.fail("deflake=3 never accepted the rarely failing world")
    assert result.minimal == ("a", "b") and result.one_minimal
    assert result.rate_check is not None and result.rate_check.decision == "holds"
    assert any(note.startswith("back-off 1: a 1-element ") and "less often than the original" in note
               for note in result.notes), "caught by the drift watch (during the reduction) or at its end"
    events = [line for line in log.read_text().splitlines() if '"rate-below"' in line or '"back-off"' in line]
    assert any('"candidate": ["a"]' in line and '"rate-below"' in line for line in events)
    # resumed from its log: the rejection holds, nothing decided is simulated again
    calls: list[tuple[tuple[str, ...], int]] = []
    probe = rare_without_b(salt)

    def counting(candidate: tuple[str, ...], attempt: int):  # type: ignore[no-untyped-def]
        calls.append((candidate, attempt))
        return probe(candidate, attempt)

    again = reduce(ELEMENTS, counting, deflake=3, partition="even", priority="sequential", log=ProbeLog.load(log))
    # the same path: the undone acceptance is accepted and undone again, from the logged runs
    assert again.minimal == ("a", "b") and again.rate_backoffs == result.rate_backoffs and calls == []


def test_the_budget_stopping_the_comparison_is_reported() -> None:
    from pytest_ddenv.reduce import reduce

    from .conftest import SetOracle

    full = reduce(ELEMENTS, SetOracle(frozenset({"a"})), deflake=0, partition="even", priority="sequential")
    short = reduce(ELEMENTS, SetOracle(frozenset({"a"})), deflake=0, partition="even", priority="sequential",
                   max_probes=full.probes + 3)
    assert short.minimal == ("a",) and short.rate_check is not None and short.rate_check.decision == "continue"
    assert short.simulations == full.probes + 3
