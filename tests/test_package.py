"""The package installs, registers its pytest plugin and ships its console script."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

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
    """`python -m pytest_ddenv.cli` (`-m pytest_ddenv` once the package has a `__main__`), and the `ddenv` script
    installed beside this interpreter: found there, not on PATH, which need not hold the environment's bin."""
    version = subprocess.run([sys.executable, "-m", "pytest_ddenv.cli", "--version"], capture_output=True, text=True)
    assert version.returncode == 0 and version.stdout.strip() == f"ddenv {pytest_ddenv.__version__}"
    script = Path(sys.executable).parent / "ddenv"
    assert script.is_file(), f"no ddenv console script beside {sys.executable}"
    helped = subprocess.run([str(script), "--help"], capture_output=True, text=True)
    assert helped.returncode == 0 and "usage: ddenv" in helped.stdout


@pytest.mark.parametrize(
    ("module", "forbidden"),
    [
        ("pytest_ddenv.reduce", ["pybullet", "pytest", "pytest_ddenv.sim", "pytest_ddenv.oracle", "pytest_ddenv.plugin"]),
        ("pytest_ddenv.world", ["pybullet", "pytest", "pytest_ddenv.sim", "pytest_ddenv.reduce"]),
        ("pytest_ddenv.oracle", ["pybullet", "pytest", "pytest_ddenv.reduce", "pytest_ddenv.plugin"]),
        ("pytest_ddenv.sim", ["pytest", "pytest_ddenv.oracle", "pytest_ddenv.reduce", "pytest_ddenv.plugin"]),
        ("pytest_ddenv.predicates", ["pybullet", "pytest", "pytest_ddenv.sim", "pytest_ddenv.oracle",
                                     "pytest_ddenv.reduce"]),
        ("pytest_ddenv.execution", ["pybullet", "pytest", "pytest_ddenv.reduce", "pytest_ddenv.sim", "pytest_ddenv.plugin"]),
        ("pytest_ddenv.driver", ["pytest", "pytest_ddenv.plugin"]),
        ("pytest_ddenv.scenario_job", ["pytest", "pytest_ddenv.plugin"]),
        ("pytest_ddenv.controllers", ["pybullet", "pytest", "pytest_ddenv.reduce"]),
        ("pytest_ddenv.report_text", ["pybullet", "pytest", "pytest_ddenv.sim", "pytest_ddenv.plugin"]),
        ("pytest_ddenv.plugin", ["pybullet", "pytest_ddenv.sim", "sklearn", "matplotlib", "scipy", "trimesh"]),
        ("pytest_ddenv.detail", ["pybullet", "pytest", "pytest_ddenv.sim", "pytest_ddenv.reduce"]),
        ("pytest_ddenv.media", ["pybullet", "pytest", "rerun", "pytest_ddenv.reduce", "pytest_ddenv.plugin"]),
        ("pytest_ddenv.animate", ["pytest", "rerun", "pytest_ddenv.reduce", "pytest_ddenv.plugin"]),
        ("pytest_ddenv.recording", ["pybullet", "pytest", "rerun", "pytest_ddenv.reduce", "pytest_ddenv.plugin"]),
    ],
)
def test_layers_load_only_what_comes_before_them(module: str, forbidden: list[str]) -> None:
    """DESIGN.md section 3: data flows one way; each layer knows only the ones before it."""
    code = f"import sys, {module}; print(sorted(m for m in {forbidden!r} if m in sys.modules))"
    loaded = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert loaded.stdout.strip() == "[]", f"{module} imports {loaded.stdout.strip()}"


LAYERS: list[tuple[str, tuple[str, ...]]] = [
    # DESIGN.md section 3, in order: each module may import its own layer and the ones above it only
    ("foundations", ("errors", "validation", "defaults", "outcome", "bounded_yaml", "geometry", "detail",
                     "alarm", "code_identity")),
    ("world model", ("world", "world_files", "world_values", "world_yaml", "world_robot", "sdf", "strategies")),
    ("simulation", ("predicates", "sim", "controllers")),
    ("oracle verdict and the test's view", ("oracle", "robot_world", "gym_env", "reported")),
    ("reduction", ("reduce",)),
    ("execution", ("execution",)),
    ("probes, stages, driver, presentation", ("probe", "stages", "markers", "driver", "artifacts", "render",
                                             "media", "animate", "recording", "reduction_report", "report_text",
                                             "progress", "replay", "scenario_job", "user_code", "other_failures",
                                             "problem")),
    ("front ends and pytest glue", ("plugin", "pytest_options", "pytest_progress", "reduction_session",
                                    "pytest_worker", "given_example", "cli", "cli_world")),
]
PACKAGE = Path(pytest_ddenv.__file__).parent


def layer_of(module: str) -> int:
    """The index in LAYERS of a module `pytest_ddenv.NAME[.sub]` (its top-level name decides)."""
    name = module.split(".")[1]
    return next(index for index, (_, names) in enumerate(LAYERS) if name in names)


def imports_of(path: Path) -> list[tuple[str, int]]:
    """Every pytest_ddenv module `path` imports, at module level or inside a function (lazy imports)."""
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and (node.module or "").startswith("pytest_ddenv."):
            found.append((node.module or "", node.lineno))
        elif isinstance(node, ast.ImportFrom) and node.module == "pytest_ddenv":
            found += [(f"pytest_ddenv.{alias.name}", node.lineno) for alias in node.names
                      if (PACKAGE / alias.name).exists() or (PACKAGE / f"{alias.name}.py").exists()]
        elif isinstance(node, ast.Import):
            found += [(alias.name, node.lineno) for alias in node.names if alias.name.startswith("pytest_ddenv.")]
    return found


def test_every_module_imports_only_its_layer_and_the_ones_above_it_lazy_imports_included() -> None:
    modules = [path for path in sorted(PACKAGE.rglob("*.py")) if path != PACKAGE / "__init__.py"]
    assert len(modules) > 80
    backwards = []
    for path in modules:
        importer = "pytest_ddenv." + ".".join(path.relative_to(PACKAGE).with_suffix("").parts)
        for imported, line in imports_of(path):
            if layer_of(imported) > layer_of(importer):
                backwards.append(f"{path.relative_to(PACKAGE.parent)}:{line} ({LAYERS[layer_of(importer)][0]}) "
                                 f"imports {imported} ({LAYERS[layer_of(imported)][0]})")
    assert backwards == []
