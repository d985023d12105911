"""A project that has the plugin installed and does not use it: no header line, no hook of ours around its tests.
The reduction's hooks are a plugin object registered only under --ddenv-reduce."""

from __future__ import annotations

import pytest

PER_TEST_HOOKS = """\
def test_list_our_per_test_hooks(request):
    hook = request.config.pluginmanager.hook
    ours = sorted({
        name for name in dir(hook) if name.startswith(("pytest_runtest_", "pytest_pyfunc_call", "pytest_fixture_"))
        for impl in getattr(hook, name).get_hookimpls()
        if (getattr(impl.function, "__module__", None) or "").startswith("pytest_ddenv")
    })
    print("our per-test hooks:", ",".join(ours) or "none")
"""


def test_a_project_that_does_not_reduce_gets_no_header_line(pytester: pytest.Pytester) -> None:
    pytester.makepyfile("def test_ok():\n    pass\n")
    plain = pytester.runpytest_subprocess()
    plain.assert_outcomes(passed=1)
    assert not [line for line in plain.outlines if line.startswith("ddenv")], plain.outlines
    verbose = pytester.runpytest_subprocess("-v")
    verbose.stdout.fnmatch_lines(["ddenv: reduction off (--ddenv-reduce to reduce failing robot tests), seed per*"])


def test_a_world_given_shows_the_header_line(pytester: pytest.Pytester) -> None:
    pytester.makepyfile("def test_ok():\n    pass\n")
    world = pytester.makefile(".yaml", world="format: 1\nmodels: []\n")
    given = pytester.runpytest_subprocess("--ddenv-world", str(world))
    given.stdout.fnmatch_lines([f"ddenv: reduction off (--ddenv-reduce to reduce failing robot tests), seed per "
                                f"marker (default 0), world {world}"])


def test_a_project_that_does_not_reduce_runs_no_hook_of_ours_per_test(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(PER_TEST_HOOKS)
    plain = pytester.runpytest("-s", "-p", "no:cacheprovider")
    plain.assert_outcomes(passed=1)
    plain.stdout.fnmatch_lines(["*our per-test hooks: none"])
    reducing = pytester.runpytest("-s", "-p", "no:cacheprovider", "--ddenv-reduce", "--ddenv-media", "none")
    reducing.assert_outcomes(passed=1)
    reducing.stdout.fnmatch_lines(["*our per-test hooks: pytest_pyfunc_call,pytest_runtest_logreport,"
                                   "pytest_runtest_makereport"])
