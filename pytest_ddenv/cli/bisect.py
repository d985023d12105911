"""`ddenv bisect`: the first commit at which a reduction's minimal world (or a test id and a world) fails the
same way, between a good and a bad git revision (`pytest_ddenv.driver.bisect`; docs/cli.md, "ddenv bisect").

Exit codes: 0 the first bad commit found; 1 no single first bad commit (skipped or undecided commits leave a
range), or the bad revision does not fail like the reference; 2 usage or input error (not a git repository,
an unknown revision, good not an ancestor of bad, a folder without summary.json, a missing world).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from pytest_ddenv.driver.artifacts import artifact_dir_name
from pytest_ddenv.driver.bisect import (
    DEFAULT_BAD_RATE,
    DEFAULT_GOOD_RATE,
    DEFAULT_LEVEL,
    DEFAULT_MAX_RUNS,
    DEFAULT_RUN_TIMEOUT,
    BadRevisionPasses,
    BisectError,
    BisectSettings,
    CommitVerdict,
    SequentialTest,
    bisect,
    target_from_artifacts,
    target_from_test,
)

EXIT_FOUND = 0
EXIT_NOT_FOUND = 1


def _fraction(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number between 0 and 1, got {text!r}") from None
    if not 0 < value < 1:
        raise argparse.ArgumentTypeError(f"expected a number between 0 and 1 (both excluded), got {text!r}")
    return value


def _count(text: str) -> int:
    if not text.isdigit() or int(text) < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {text!r}")
    return int(text)


def _seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not value > 0:
        raise argparse.ArgumentTypeError(f"expected seconds > 0, got {text!r}")
    return value


def _seed(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None


def add_bisect(commands: Any, common: argparse.ArgumentParser) -> None:
    parser = commands.add_parser("bisect", parents=[common],
                                 help="find the first commit at which a reduction's minimal world fails the same way")
    parser.add_argument("artifacts", metavar="ARTIFACT_DIR", nargs="?",
                        help="a folder written by pytest --ddenv-reduce (its summary.json names the test, "
                             "minimal.yaml is the world); or give --test and --world")
    parser.add_argument("--test", metavar="ID", help="the pytest test id, relative to the repository's root")
    parser.add_argument("--world", metavar="FILE", help="the world the test runs on (--ddenv-world)")
    parser.add_argument("--good", metavar="REV", required=True, help="a revision at which the test passes")
    parser.add_argument("--bad", metavar="REV", default="HEAD", help="a revision at which it fails (default HEAD)")
    parser.add_argument("--repo", metavar="DIR", default=".", help="the git repository (default: .)")
    parser.add_argument("--folder", metavar="DIR",
                        help="the bisect's folder (journal, worktrees): default ARTIFACT_DIR/bisect, or "
                             "ddenv-bisect/<test>-seed<S>-<hash> with --test")
    parser.add_argument("--seed", type=_seed, metavar="S",
                        help="the seed of run 0 (default: the reduction's, else 0); run i uses S + i * 1000003")
    parser.add_argument("--max-runs", type=_count, default=DEFAULT_MAX_RUNS, metavar="N",
                        help=f"runs per commit at most; undecided then: skipped (default {DEFAULT_MAX_RUNS})")
    parser.add_argument("--good-rate", type=_fraction, default=DEFAULT_GOOD_RATE, metavar="P",
                        help=f"the failure rate of a good commit in the sequential test (default {DEFAULT_GOOD_RATE})")
    parser.add_argument("--bad-rate", type=_fraction, default=DEFAULT_BAD_RATE, metavar="P",
                        help=f"the failure rate of a bad commit (default {DEFAULT_BAD_RATE})")
    parser.add_argument("--level", type=_fraction, default=DEFAULT_LEVEL, metavar="A",
                        help=f"each error level of the sequential test (default {DEFAULT_LEVEL})")
    parser.add_argument("--run-timeout", type=_seconds, default=DEFAULT_RUN_TIMEOUT, metavar="S",
                        help=f"seconds one pytest batch may take; a hung commit is skipped (default "
                             f"{DEFAULT_RUN_TIMEOUT:g})")


def cmd_bisect(arguments: argparse.Namespace) -> int:
    if (arguments.artifacts is None) == (arguments.test is None):
        raise BisectError("give an artifacts folder, or --test ID and --world FILE (not both)")
    if arguments.artifacts is not None:
        if arguments.world is not None:
            raise BisectError("--world goes with --test; an artifacts folder brings its minimal world")
        target = target_from_artifacts(Path(arguments.artifacts), arguments.seed)
        folder = Path(arguments.folder or Path(arguments.artifacts) / "bisect")
    else:
        if arguments.world is None:
            raise BisectError("--test needs --world FILE")
        target = target_from_test(arguments.test, Path(arguments.world), arguments.seed)
        folder = Path(arguments.folder or Path("ddenv-bisect") / artifact_dir_name(target.test, target.seed))
    settings = BisectSettings(arguments.good, arguments.bad, Path(arguments.repo), folder.resolve(),
                              SequentialTest(arguments.good_rate, arguments.bad_rate, arguments.level),
                              arguments.max_runs, arguments.run_timeout)

    def progress(verdict: CommitVerdict) -> None:
        print(f"ddenv bisect: {verdict.describe()}", file=sys.stderr, flush=True)

    try:
        result = bisect(target, settings, progress)
    except BadRevisionPasses as error:
        print(f"ddenv: error: {error}", file=sys.stderr)
        if arguments.json:
            print(json.dumps({"ok": False, "error": str(error), "exit_code": EXIT_NOT_FOUND}, indent=2))
        return EXIT_NOT_FOUND
    if arguments.json:
        print(json.dumps(result.to_dict(), indent=2))
    else:
        print("\n".join(result.lines()))
    return EXIT_FOUND if result.first_bad is not None else EXIT_NOT_FOUND
