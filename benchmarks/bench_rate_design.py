"""Operating characteristics of the end-of-run rate comparison, computed exactly (no physics, no sampling).

    python benchmarks/bench_rate_design.py [--calibration 0 3 5] [--level 0.05]     # a few seconds

The comparison (pytest_ddenv/reduce/rates.py) looks after 5, 10 and 20 fresh runs of each world and tests
"the minimal world fails less often than the original" with a one-sided Fisher exact test at 5 % / 3 per
look. For true failure rates (original, minimal) this script sums over every outcome of the runs (binomial)
and prints, for the old procedure (both worlds topped up to every look) and the curtailed one of issue 33
(the minimal world first; the original's runs a look does not need are not started, `rates.settled`):

- P(below): the chance of calling the minimal world significantly rarer (at equal rates: the false "below"
  rate; at 50 % against 100 %: the power),
- the expected fresh runs of the minimal world and of the original beyond its calibration runs (deflake
  "auto" makes `--calibration` runs of the original before the reduction; they are its first fresh runs).

The two procedures make the same decision on every outcome, so P(below) must agree to rounding; only the
runs differ.

Then the drift watch (reduce/rate_check.py `DriftWatch`), per accepted world failing at rate p against an
original failing 100 %. A world is tested when a run that decided it did not fail ("at once") or, its
deciding runs all failing (k of them: 1 under any-of-N, 2 under auto's 2-of-3), when one of its confirming
fresh runs up to its attempt 2 (3 - k runs) does not fail. The old watch (issue 33's second session, w33f-2)
ran the end-of-run comparison there, at the documented level; the new one (w33f-3) makes a search decision:
the world's first 5 fresh runs (the confirming ones included) against the original's first 5 (calibration
included), one-sided Fisher exact at `rates.SEARCH_LEVEL`, one look (`rates.search_below`). Printed: P(back
off) for each (for worlds at 100 %, 90 %, 80 %: a wrong back-off, which costs minimality, never honesty; at
50 %, 40 %: the catch rate) and the new watch's expected runs per accepted world (the world's beyond its
deciding runs + the original's beyond `--calibration`). The end-of-run test is unchanged, so its level and
power above are the guarantee's.
"""

from __future__ import annotations

import argparse
import functools
import math
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import table

from pytest_ddenv.reduce.rate_check import SEARCH_LOOKS
from pytest_ddenv.reduce.rates import LEVEL, LOOKS, SEARCH_LEVEL, Rate, compare, search_below, settled

CASES: tuple[tuple[float, float], ...] = (
    (1.0, 1.0), (0.9, 0.9), (0.8, 0.8), (0.6, 0.6), (0.5, 0.5), (0.3, 0.3),
    (1.0, 0.8), (1.0, 0.5), (1.0, 0.4), (0.5, 0.2),
)
"""(original's rate, minimal world's rate): equal rates (false "below"), then drops (power)."""


@dataclass(frozen=True)
class Characteristics:
    below: float
    """P(decision "below")."""
    holds: float
    reduced_runs: float
    """Expected fresh runs of the minimal world."""
    original_runs: float
    """Expected fresh runs of the original beyond its calibration runs."""


def binomial(runs: int, rate: float) -> Iterator[tuple[int, float]]:
    """(fails, probability) of `runs` runs failing at `rate`, the impossible ones left out."""
    for fails in range(runs + 1):
        chance = math.comb(runs, fails) * rate**fails * (1.0 - rate) ** (runs - fails)
        if chance > 0.0:
            yield fails, chance


@functools.cache
def full_decision(original_fails: int, look: int, reduced_fails: int, level: float = LEVEL) -> str:
    return compare(Rate(original_fails, look), Rate(reduced_fails, look), LOOKS, level).decision


@functools.cache
def settled_decision(original_fails: int, original_runs: int, look: int, reduced_fails: int,
                     level: float = LEVEL) -> str | None:
    early = settled(Rate(original_fails, original_runs), look, Rate(reduced_fails, look), LOOKS, level)
    return None if early is None else early.decision


def old_design(original: float, reduced: float, calibration: int, level: float = LEVEL) -> Characteristics:
    """Both worlds run to every look (the original's first `calibration` runs already made)."""
    below = holds = reduced_runs = original_runs = 0.0
    states = {(0, 0): 1.0}  # (original fails, reduced fails) -> probability, runs = the previous look
    previous = 0
    for look in LOOKS:
        following: dict[tuple[int, int], float] = {}
        for (fo, fr), chance in states.items():
            for more_o, p_o in binomial(look - previous, original):
                for more_r, p_r in binomial(look - previous, reduced):
                    p = chance * p_o * p_r
                    decision = full_decision(fo + more_o, look, fr + more_r, level)
                    if decision == "continue":
                        following[(fo + more_o, fr + more_r)] = following.get((fo + more_o, fr + more_r), 0.0) + p
                        continue
                    below += p if decision == "below" else 0.0
                    holds += p if decision == "holds" else 0.0
                    reduced_runs += p * look
                    original_runs += p * max(0, look - calibration)
        states, previous = following, look
    return Characteristics(below, holds, reduced_runs, original_runs)


def curtailed_design(original: float, reduced: float, calibration: int, level: float = LEVEL,
                     failed_first: int = 0) -> Characteristics:
    """The minimal world first; the original topped up to a look only when `settled` says its runs matter.
    `failed_first`: the minimal world's first runs are known to fail (the conditional characteristics)."""
    below = holds = reduced_runs = original_runs = 0.0
    # (original fails, original runs, reduced fails) -> probability; the original starts with its calibration
    states = {(fo, min(calibration, LOOKS[0]), failed_first): p
              for fo, p in binomial(min(calibration, LOOKS[0]), original)}
    previous = failed_first
    for look in LOOKS:
        following: dict[tuple[int, int, int], float] = {}
        for (fo, made, fr), chance in states.items():
            for more_r, p_r in binomial(look - previous, reduced):
                outcomes: list[tuple[int, int, float, str]] = []
                early = settled_decision(fo, made, look, fr + more_r, level) if made < look else None
                if early is not None:
                    outcomes.append((fo, made, chance * p_r, early))
                else:
                    outcomes += [(fo + more_o, look, chance * p_r * p_o,
                                  full_decision(fo + more_o, look, fr + more_r, level))
                                 for more_o, p_o in binomial(look - made, original)]
                for fo_now, made_now, p, decision in outcomes:
                    if decision == "continue":
                        key = (fo_now, made_now, fr + more_r)
                        following[key] = following.get(key, 0.0) + p
                        continue
                    below += p if decision == "below" else 0.0
                    holds += p if decision == "holds" else 0.0
                    reduced_runs += p * look
                    original_runs += p * max(0, made_now - calibration)
        states, previous = following, look
    return Characteristics(below, holds, reduced_runs, original_runs)


def largest_false_below(level: float = LEVEL) -> tuple[float, float]:
    """(rate, P(below)) of the equal rate 0.05, 0.10, ..., 1.0 called "below" most often."""
    return max(((rate / 20, old_design(rate / 20, rate / 20, 0, level).below) for rate in range(1, 21)),
               key=lambda pair: pair[1])


DRIFT_RATES = (1.0, 0.9, 0.8, 0.5, 0.4)
"""The accepted world's true rate, against an original failing every run: wrongly backed off, then caught."""
WATCHED_RUNS = 3
"""rate_check.WATCHED_RUNS: confirming runs up to an accepted world's attempt 2."""
WATCH_RULES = (("any-of-N", 2), ("auto 2-of-3", 1), ("a pass decided it", 0))
"""(how a world was accepted, its confirming runs): the last is tested at once."""


def old_watch(rate: float, confirming: int, level: float = LEVEL) -> float:
    """P(back off) of the old watch: flagged, then the end-of-run comparison (curtailed) says "below"."""
    below = curtailed_design(1.0, rate, 0, level).below
    unflagged = rate**confirming if confirming else 0.0
    return below - (unflagged * curtailed_design(1.0, rate, 0, level, failed_first=confirming).below
                    if unflagged else 0.0)


def _search_look(reduced: Rate, look: int, known_runs: int, level: float) -> tuple[str, int]:
    """The watch's decision at one look, the original failing every run and having made `known_runs` already:
    (decision, the original's runs made by then)."""
    known = Rate(min(known_runs, look), min(known_runs, look))
    decided = search_below(known, reduced, look, level) or search_below(Rate(look, look), reduced, look, level)
    assert decided is not None
    return decided.decision, known_runs if decided.skipped or known_runs >= look else look


def new_watch(rate: float, confirming: int, calibration: int, level: float = SEARCH_LEVEL,
              looks: tuple[int, ...] = LOOKS[:SEARCH_LOOKS]) -> tuple[float, float]:
    """(P(back off), expected runs) of the search decision (the original fails every run): at each of `looks`
    while it holds and the world showed a non-failing run (`rate_check.DriftWatch.test`)."""
    back_off = runs = 0.0
    for first_fails, p_first in binomial(confirming, rate):
        if confirming and first_fails == confirming:  # not flagged: the confirming runs only
            runs += p_first * confirming
            continue
        # (look index, the world's fails so far, its runs so far, the original's runs so far, chance)
        stack: list[tuple[int, int, int, int, float]] = [(0, first_fails, confirming, calibration, p_first)]
        while stack:
            index, fails, made, original_made, chance = stack.pop()
            look = looks[index]
            for more, p_more in binomial(look - made, rate):
                reduced = Rate(fails + more, look)
                decision, original = _search_look(reduced, look, original_made, level)
                p = chance * p_more
                back_off += p * (decision == "below")
                if decision != "holds" or index == len(looks) - 1 or reduced.fails == look:
                    runs += p * (look + original - calibration)
                else:  # before the next look the original's runs of this one are made (are they all failing?)
                    stack.append((index + 1, reduced.fails, look, max(original, look), p))
    return back_off, runs


def drift_rows(calibration: int, level: float = LEVEL, search_level: float = SEARCH_LEVEL) -> list[list[str]]:
    """The drift watch per accepted world (original 100 %): see the module docstring."""
    lines = []
    for rule, confirming in WATCH_RULES:
        for rate in DRIFT_RATES:
            one_look, one_look_runs = new_watch(rate, confirming, calibration, search_level, LOOKS[:1])
            back_off, runs = new_watch(rate, confirming, calibration, search_level)
            what = "wrong back-off" if rate >= 0.8 else "catch"
            lines.append([rule, f"{rate:.0%}", what, f"{old_watch(rate, confirming, level):.2%}", f"{one_look:.2%}",
                          f"{back_off:.2%}", f"{one_look_runs:.2f}", f"{runs:.2f}"])
    return lines


def rows(calibration: int, level: float = LEVEL) -> list[list[str]]:
    lines = []
    for original, reduced in CASES:
        old = old_design(original, reduced, calibration, level)
        new = curtailed_design(original, reduced, calibration, level)
        what = "false below" if original == reduced else "power"
        lines.append([f"{original:.0%} / {reduced:.0%}", what, f"{old.below:.2%}", f"{new.below:.2%}",
                      f"{old.reduced_runs:.2f} + {old.original_runs:.2f}",
                      f"{new.reduced_runs:.2f} + {new.original_runs:.2f}",
                      f"{old.reduced_runs + old.original_runs - new.reduced_runs - new.original_runs:.2f}"])
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calibration", type=int, nargs="+", default=[0, 3, 5],
                        help="runs of the original made before the comparison (deflake=auto: 3 or 5; else 0)")
    parser.add_argument("--level", type=float, default=LEVEL,
                        help=f"overall level, split evenly over the looks (default {LEVEL}: the engine's)")
    parser.add_argument("--search-level", type=float, default=SEARCH_LEVEL,
                        help=f"the drift watch's search level (default {SEARCH_LEVEL}: the engine's)")
    args = parser.parse_args(argv)
    print(f"looks {LOOKS}, one-sided Fisher exact, {args.level:.3g} overall ({args.level / len(LOOKS):.3g} per "
          "look, Bonferroni); exact sums over every outcome")
    rate, worst = largest_false_below(args.level)
    print(f"largest false-below rate over equal rates 0.05, 0.10, ..., 1.0: {worst:.2%} (at {rate:.2f})")
    for calibration in args.calibration:
        print(f"\ncalibration runs of the original already made: {calibration}\n")
        print(table(["original / minimal rate", "", "P(below) old", "P(below) new",
                     "runs old (minimal + original)", "runs new (minimal + original)", "saved"],
                    rows(calibration, args.level)))
    print(f"\nthe drift watch, per accepted world, original failing 100 %: old (the end-of-run comparison, "
          f"{args.level:.3g} overall), a search decision at {args.search_level:.3g} on the first look (w33f-3), and on "
          f"up to {SEARCH_LOOKS} looks (now)")
    for calibration in args.calibration:
        print(f"\ncalibration runs of the original already made: {calibration}\n")
        print(table(["accepted on", "world's rate", "", "P(back off): end-of-run test", "one look",
                     f"{SEARCH_LOOKS} looks", "runs, one look (world + original)", f"runs, {SEARCH_LOOKS} looks"],
                    drift_rows(calibration, args.level, args.search_level)))
    print("\na world failing every run is never backed off; its confirming runs are spent unless it is the minimal "
          "world (they are the first runs of the minimal world's comparison)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
