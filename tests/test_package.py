"""The package installs, registers its pytest plugin and ships its console script."""

from __future__ import annotations

import subprocess
import sys

import pytest

import pytest_ddenv


def test_version_is_the_installed_distribution_version() -> None:
    from importlib.metadata import version

    assert pytest_ddenv.__version__ == version("pytest-ddenv")


def test_pytest_header_lists_the_plugin(pytester: pytest.Pytester) -> None:
    pytester.makepyfile("def test_ok():\n    pass\n")
    result = pytester.runpytest_subprocess()
    result.stdout.fnmatch_lines([f"plugins:*ddenv-{pytest_ddenv.__version__}*"])
    result.assert_outcomes(passed=1)


def test_pytest_header_says_how_to_reproduce_the_reductions(pytester: pytest.Pytester) -> None:
    pytester.makepyfile("def test_ok():\n    pass\n")
    off = pytester.runpytest_subprocess()
    off.stdout.fnmatch_lines(["ddenv: reduction off (--ddenv-reduce to reduce failing robot tests), seed per marker*"])
    on = pytester.runpytest_subprocess("--ddenv-reduce", "--ddenv-seed", "7", "--ddenv-workers", "2",
                                       "--ddenv-media", "none")
    on.stdout.fnmatch_lines([f"ddenv: reduction on, seed 7, workers 2, executor local, media none, "
                             f"artifacts {pytester.path / 'ddenv-artifacts'}"])


def test_markers_are_registered(pytester: pytest.Pytester) -> None:
    result = pytester.runpytest("--markers")
    result.stdout.fnmatch_lines(["@pytest.mark.ddenv(*", "@pytest.mark.robot_failure(*"])


def test_console_script_version_and_help() -> None:
    version = subprocess.run([sys.executable, "-m", "pytest_ddenv.cli", "--version"], capture_output=True, text=True)
    assert version.returncode == 0 and version.stdout.strip() == f"ddenv {pytest_ddenv.__version__}"
    helped = subprocess.run(["ddenv", "--help"], capture_output=True, text=True)
    assert helped.returncode == 0 and "usage: ddenv" in helped.stdout


@pytest.mark.parametrize(
    ("module", "forbidden"),
    [
        ("pytest_ddenv.reduce", ["pybullet", "pytest", "pytest_ddenv.sim", "pytest_ddenv.oracle", "pytest_ddenv.plugin"]),
        ("pytest_ddenv.world", ["pybullet", "pytest", "pytest_ddenv.sim", "pytest_ddenv.reduce"]),
        ("pytest_ddenv.oracle", ["pybullet", "pytest", "pytest_ddenv.reduce", "pytest_ddenv.plugin"]),
        ("pytest_ddenv.sim", ["pytest", "pytest_ddenv.reduce", "pytest_ddenv.plugin"]),
        ("pytest_ddenv.execution", ["pybullet", "pytest", "pytest_ddenv.reduce", "pytest_ddenv.sim", "pytest_ddenv.plugin"]),
        ("pytest_ddenv.driver", ["pytest", "pytest_ddenv.plugin"]),
        ("pytest_ddenv.scenario_job", ["pytest", "pytest_ddenv.plugin"]),
        ("pytest_ddenv.controllers", ["pybullet", "pytest", "pytest_ddenv.reduce"]),
        ("pytest_ddenv.report_text", ["pybullet", "pytest", "pytest_ddenv.sim", "pytest_ddenv.plugin"]),
        ("pytest_ddenv.detail", ["pybullet", "pytest", "pytest_ddenv.sim", "pytest_ddenv.reduce"]),
        ("pytest_ddenv.media", ["pybullet", "pytest", "rerun", "pytest_ddenv.reduce", "pytest_ddenv.plugin"]),
        ("pytest_ddenv.animate", ["pytest", "rerun", "pytest_ddenv.reduce", "pytest_ddenv.plugin"]),
        ("pytest_ddenv.recording", ["pybullet", "pytest", "rerun", "pytest_ddenv.reduce", "pytest_ddenv.plugin"]),
    ],
)
def test_layers_import_only_what_comes_before_them(module: str, forbidden: list[str]) -> None:
    """DESIGN.md section 3: data flows one way; each layer knows only the ones before it."""
    code = f"import sys, {module}; print(sorted(m for m in {forbidden!r} if m in sys.modules))"
    loaded = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert loaded.stdout.strip() == "[]", f"{module} imports {loaded.stdout.strip()}"
