"""The package installs, registers its pytest plugin and ships its console script."""

from __future__ import annotations

import ast
import importlib
import re
import subprocess
import sys
from collections.abc import Mapping
from dataclasses import dataclass
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
    off = pytester.runpytest_subprocess("-v")  # without -v, no line: tests/plugin/test_plugin_inactive.py
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


def test_python_dash_m_pytest_ddenv_runs_the_ddenv_command() -> None:
    version = subprocess.run([sys.executable, "-m", "pytest_ddenv", "--version"], capture_output=True, text=True)
    assert version.returncode == 0 and version.stdout.strip() == f"ddenv {pytest_ddenv.__version__}"
    helped = subprocess.run([sys.executable, "-m", "pytest_ddenv", "check", "--help"], capture_output=True, text=True)
    assert helped.returncode == 0 and helped.stdout.startswith("usage: ddenv check")


@pytest.mark.parametrize("package", ["pytest_ddenv", "pytest_ddenv.world", "pytest_ddenv.oracle", "pytest_ddenv.sim",
                                     "pytest_ddenv.driver", "pytest_ddenv.reduce", "pytest_ddenv.execution",
                                     "pytest_ddenv.sdf", "pytest_ddenv.render", "pytest_ddenv.strategies"])
def test_every_name_a_package_exports_is_there(package: str) -> None:
    """The facade and the sub-packages the docs import from: every name of `__all__` resolves (the lazy ones
    too: the facade's and the driver's are imported on first use)."""
    module = importlib.import_module(package)
    assert [name for name in module.__all__ if not hasattr(module, name)] == []


PLUGIN = "pytest_ddenv.pytest_plugin"


@pytest.mark.parametrize(
    ("module", "forbidden"),
    [
        ("pytest_ddenv.reduce", ["pybullet", "pytest", "pytest_ddenv.sim", "pytest_ddenv.oracle", PLUGIN]),
        ("pytest_ddenv.world", ["pybullet", "pytest", "trimesh", "yaml", "pytest_ddenv.sdf", "pytest_ddenv.sim",
                                "pytest_ddenv.reduce"]),
        ("pytest_ddenv.oracle", ["pybullet", "pytest", "pytest_ddenv.sim", "pytest_ddenv.reduce", PLUGIN]),
        ("pytest_ddenv.sim", ["pytest", "pytest_ddenv.reduce", "pytest_ddenv.scenario", PLUGIN]),
        ("pytest_ddenv.execution", ["pybullet", "pytest", "pytest_ddenv.reduce", "pytest_ddenv.sim", PLUGIN]),
        ("pytest_ddenv.driver.run", ["pytest", PLUGIN, "pytest_ddenv.cli"]),
        ("pytest_ddenv.driver.scenario_job", ["pytest", PLUGIN]),
        ("pytest_ddenv.sim.controllers", ["pybullet", "pytest", "pytest_ddenv.reduce"]),
        ("pytest_ddenv.driver.report_text", ["pybullet", "pytest", "pytest_ddenv.sim", PLUGIN]),
        ("pytest_ddenv.pytest_plugin.hooks", ["pybullet", "pytest_ddenv.sim", "pytest_ddenv.driver.run",
                                              "pytest_ddenv.stages", "pytest_ddenv.media", "sklearn", "matplotlib",
                                              "scipy", "trimesh"]),
        ("pytest_ddenv.detail", ["pybullet", "pytest", "pytest_ddenv.sim", "pytest_ddenv.reduce"]),
        ("pytest_ddenv.media.writer", ["pybullet", "pytest", "rerun", "pytest_ddenv.reduce", PLUGIN]),
        ("pytest_ddenv.media.animate", ["pytest", "rerun", "pytest_ddenv.reduce", PLUGIN]),
        ("pytest_ddenv.media.recording", ["pybullet", "pytest", "rerun", "pytest_ddenv.reduce", PLUGIN]),
    ],
)
def test_layers_load_only_what_comes_before_them(module: str, forbidden: list[str]) -> None:
    """What importing a layer loads at run time (its package `__init__`s included): no library and no layer it
    does not need, so that loading the pytest plugin stays cheap."""
    code = f"import sys, {module}; print(sorted(m for m in {forbidden!r} if m in sys.modules))"
    loaded = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert loaded.stdout.strip() == "[]", f"{module} imports {loaded.stdout.strip()}"


PACKAGE = Path(pytest_ddenv.__file__).parent
ARCHITECTURE = PACKAGE.parent / "docs" / "architecture.md"
MAX_ROOT_FILES = 10


@dataclass(frozen=True)
class Layer:
    number: int
    name: str
    rooms: frozenset[str]
    """Its folders and root modules, by top-level name ("world", "errors", "__init__")."""
    imports_from: frozenset[int]


def layers() -> list[Layer]:
    """The table under docs/architecture.md's "The layers": `| # | layer | folders and root modules | imports
    from |`, one row per layer, its folders and modules written `name/` and `name.py`, the layers it imports
    from written as numbers and ranges ("1, 2, 4-6"; "-" for none). Its own layer is always allowed."""
    found = []
    text = ARCHITECTURE.read_text().partition("\n## The layers\n")[2].partition("\n## ")[0]
    for line in text.splitlines():
        cells = [cell.strip() for cell in line.strip().strip("|").split("|")]
        if len(cells) != 4 or not cells[0].isdigit():
            continue
        rooms = re.findall(r"`([A-Za-z_]\w*)(?:/|\.py)`", cells[2])
        allowed: set[int] = set()
        for low, high in re.findall(r"(\d+)(?:\s*[-\u2013]\s*(\d+))?", cells[3]):
            allowed.update(range(int(low), int(high or low) + 1))
        found.append(Layer(int(cells[0]), cells[1], frozenset(rooms), frozenset(allowed)))
    return found


def modules() -> dict[str, Path]:
    """Every module of the package by dotted name (a package by its own name)."""
    named = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        named[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return named


def imports_of(name: str, path: Path, known: Mapping[str, Path]) -> set[tuple[str, int]]:
    """Every package module `name` imports, and the line: `import` and `from ... import` statements at module
    level, in functions and under TYPE_CHECKING, absolute and relative, and strings that name a package module
    (`importlib.import_module`, a lazy facade's table, a forkserver's preload list)."""

    def resolve(dotted: str) -> str | None:
        while dotted and dotted not in known:
            dotted = dotted.rpartition(".")[0]
        return dotted or None

    here = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: set[tuple[str | None, int]] = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found |= {(resolve(alias.name), node.lineno) for alias in node.names
                      if alias.name.partition(".")[0] == "pytest_ddenv"}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:  # relative: from the package `here`, up `level - 1` packages
                parts = here.split(".")[: len(here.split(".")) - node.level + 1]
                base = ".".join([*parts, base] if base else parts)
            if base.partition(".")[0] == "pytest_ddenv":
                found |= {(f"{base}.{alias.name}" if f"{base}.{alias.name}" in known else resolve(base), node.lineno)
                          for alias in node.names}
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value in known:
            found.add((node.value, node.lineno))
    return {(module, line) for module, line in found if module is not None and module != name}


def room_of(module: str) -> str:
    parts = module.split(".")
    return "__init__" if len(parts) == 1 else parts[1]


def import_graph() -> dict[str, set[tuple[str, int]]]:
    known = modules()
    return {name: imports_of(name, path, known) for name, path in known.items()}


def cycles(graph: Mapping[str, set[tuple[str, int]]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found = []

    def visit(module: str) -> None:
        index[module] = low[module] = len(index)
        stack.append(module)
        for imported, _ in graph[module]:
            if imported not in index:
                visit(imported)
                low[module] = min(low[module], low[imported])
            elif imported in stack:
                low[module] = min(low[module], index[imported])
        if low[module] == index[module]:
            component = []
            while True:
                member = stack.pop()
                component.append(member)
                if member == module:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for module in sorted(graph):
        if module not in index:
            visit(module)
    return found


def test_the_import_reader_sees_every_kind_of_import(tmp_path: Path) -> None:
    source = tmp_path / "reader.py"
    source.write_text(
        "from __future__ import annotations\n"
        "from typing import TYPE_CHECKING\n"
        "import pytest_ddenv.sim.run as run\n"                         # 3
        "from pytest_ddenv.world import geometry\n"                    # 4: a module of a package
        "from pytest_ddenv.oracle import classify\n"                   # 5: a name of a package
        "from . import limits\n"                                       # 6: relative
        "from .model import World\n"                                   # 7
        "if TYPE_CHECKING:\n"
        "    from pytest_ddenv.driver.run import ReductionPlan\n"      # 9
        "def later() -> None:\n"
        "    from pytest_ddenv.media import animate\n"                 # 11
        "    importlib.import_module('pytest_ddenv.render')\n"         # 12
        "    print('pytest_ddenv.cli: not a module name alone')\n"
    )
    found = imports_of("pytest_ddenv.world.reader", source, modules())
    assert sorted(found) == [
        ("pytest_ddenv.driver.run", 9), ("pytest_ddenv.media.animate", 11), ("pytest_ddenv.oracle", 5),
        ("pytest_ddenv.render", 12), ("pytest_ddenv.sim.run", 3), ("pytest_ddenv.world.geometry", 4),
        ("pytest_ddenv.world.limits", 6), ("pytest_ddenv.world.model", 7),
    ]
    assert cycles({"a": {("b", 1)}, "b": {("c", 2)}, "c": {("a", 3)}, "d": {("a", 4)}}) == [["a", "b", "c"]]


def test_no_import_cycle_among_the_package_modules_of_any_import_kind() -> None:
    graph = import_graph()
    assert len(graph) > 100
    assert cycles(graph) == []


def test_every_folder_and_root_module_is_in_one_layer_of_the_architecture_page() -> None:
    table = layers()
    assert [layer.number for layer in table] == list(range(1, len(table) + 1))
    listed = [room for layer in table for room in layer.rooms]
    present = {room_of(module) for module in modules()}
    assert sorted(listed) == sorted(set(listed)), "a folder or module is in two layers"
    assert set(listed) == present


def test_every_import_points_to_its_own_layer_or_one_it_may_import_from_lazy_imports_included() -> None:
    layer_of = {room: layer for layer in layers() for room in layer.rooms}
    nowhere = Layer(0, "in no layer", frozenset(), frozenset())
    wrong = []
    for importer, imported_lines in sorted(import_graph().items()):
        mine = layer_of.get(room_of(importer), nowhere)
        for imported, line in sorted(imported_lines):
            theirs = layer_of.get(room_of(imported), nowhere)
            if theirs.number != mine.number and theirs.number not in mine.imports_from:
                wrong.append(f"{modules()[importer].relative_to(PACKAGE.parent)}:{line} ({mine.name}) imports "
                             f"{imported} ({theirs.name})")
    assert wrong == []


def test_the_package_root_holds_the_facade_and_the_foundations_only() -> None:
    root = sorted(path.name for path in PACKAGE.glob("*.py"))
    assert len(root) <= MAX_ROOT_FILES, root


def test_the_code_under_test_never_counts_the_packages_own_modules() -> None:
    """In pytest-ddenv's own checkout (a project folder that holds the package's source), the code under test
    is identified without the package's modules, whichever sub-package they are in."""
    from pytest_ddenv.driver.code_identity import project_modules

    importlib.import_module("pytest_ddenv.sim")
    importlib.import_module("pytest_ddenv.world.yaml_format")
    assert [path for path in project_modules(PACKAGE.parent) if path.is_relative_to(PACKAGE)] == []
