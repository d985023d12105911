"""What identifies the code under test: the project's files a test imported, by content, the files its world
reads (meshes, heightmaps, URDFs), by content, and the third-party packages those files import, by version.

A reduction resumes its run log only under the same code identity (`driver.run_reduction`): an edited
controller, predicate, helper module or module-level constant starts a fresh log, and the note says which
files changed. Files of the user's project are those of the modules loaded in this process that live under
the project's root folder and outside any installed environment; the caller may leave out files that cannot
matter (other test modules, conftests of other folders), and a left-out file that an included one imports
is taken back in.
"""

from __future__ import annotations

import ast
import fnmatch
import hashlib
import site
import sys
import sysconfig
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from types import ModuleType
from typing import Any

DIGEST_LENGTH = 16
"""Hex digits of a file's SHA-256 kept (64 bits: an accidental clash is out of reach)."""
ALWAYS_VERSIONED = ("pytest-ddenv", "pybullet")
"""Distributions whose version is part of every identity (each when installed): the plugin and pybullet. The
engine that runs the world, with its version, is a part of the problem of its own (`problem.ENGINE_PART`): a
run is bit-identical only in the same engine of the same version."""
_OWN_PACKAGE = Path(__file__).resolve().parents[1]
"""The folder of pytest_ddenv (this module is in its `driver/`)."""


@dataclass(frozen=True)
class CodeIdentity:
    """`files`: shown path -> content digest; `packages`: distribution -> version (and "python" -> its version)."""

    files: Mapping[str, str] = field(default_factory=dict)
    packages: Mapping[str, str] = field(default_factory=dict)

    def to_json(self) -> dict[str, dict[str, str]]:
        return {"files": dict(sorted(self.files.items())), "packages": dict(sorted(self.packages.items()))}

    @classmethod
    def from_json(cls, data: Any) -> CodeIdentity | None:
        """The identity a run log's header recorded; None when it recorded none (or something malformed)."""
        if not isinstance(data, Mapping):
            return None
        files, packages = data.get("files"), data.get("packages")
        if not isinstance(files, Mapping) or not isinstance(packages, Mapping) \
                or not _string_mapping(files) or not _string_mapping(packages):
            return None
        return cls(dict(files), dict(packages))

    def changes_since(self, earlier: CodeIdentity) -> list[str]:
        """What differs from `earlier`, in words: "controllers.py (edited)", "numpy 2.1.0 -> 2.2.0", ..."""
        changes = [f"{path} ({_file_change(earlier.files.get(path), self.files.get(path))})"
                   for path in sorted(set(self.files) | set(earlier.files))
                   if earlier.files.get(path) != self.files.get(path)]
        for name in sorted(set(self.packages) | set(earlier.packages)):
            before, now = earlier.packages.get(name), self.packages.get(name)
            if before != now:
                changes.append(f"{name} {before or '(not imported)'} -> {now or '(not imported)'}")
        return changes


def _string_mapping(value: Any) -> bool:
    return isinstance(value, Mapping) and all(isinstance(k, str) and isinstance(v, str) for k, v in value.items())


def _file_change(before: str | None, now: str | None) -> str:
    if before is None:
        return "new"
    if now is None:
        return "no longer imported"
    return "edited"


def identify(roots: Iterable[Path], *, exclude: Iterable[Path] = (), data_files: Iterable[Path] = ()
             ) -> CodeIdentity:
    """The identity of the code loaded in this process from the project folders `roots` (the first names the
    files in notes; see the module's docstring), leaving out the files of `exclude` unless an included file
    imports them, plus `data_files` (by content wherever they are)."""
    folders = [Path(folder).resolve() for folder in roots]
    root = folders[0]
    modules: dict[Path, ModuleType] = {}
    for folder in folders:
        modules.update(project_modules(folder))
    excluded = {path.resolve() for path in exclude}
    included = {path: module for path, module in modules.items() if path not in excluded}
    imported: set[str] = set()
    pending = list(included.items())
    while pending:  # the files the included ones import, excluded or not
        path, module = pending.pop()
        names = _imported_names(path, module)
        imported.update(name.partition(".")[0] for name in names)
        for name in names:
            target = _module_file(name)
            if target is not None and target in modules and target not in included:
                included[target] = modules[target]
                pending.append((target, modules[target]))
    files = {_shown(path, root): digest(path) for path in included}
    for path in data_files:
        resolved = Path(path).expanduser().resolve()
        files[_shown(resolved, root)] = digest(resolved)
    local = {module.__name__.partition(".")[0] for module in included.values()}
    return CodeIdentity(files, package_versions(imported - local))


def project_modules(root: Path) -> dict[Path, ModuleType]:
    """The modules loaded in this process from files under `root`, outside any installed environment and
    outside pytest-ddenv itself, by resolved file path."""
    installed = _installed_folders()
    found: dict[Path, ModuleType] = {}
    for module in list(sys.modules.values()):
        path = _file_of(module)
        if path is None or not path.is_relative_to(root) or path.is_relative_to(_OWN_PACKAGE):
            continue
        if any(path.is_relative_to(folder) for folder in installed if not root.is_relative_to(folder)):
            continue
        found[path] = module
    return found


def _file_of(module: ModuleType | None) -> Path | None:
    name = getattr(module, "__file__", None)
    if not isinstance(name, str) or not name.endswith(".py"):
        return None
    try:
        return Path(name).resolve()
    except OSError:
        return None


def _module_file(name: str) -> Path | None:
    return _file_of(sys.modules.get(name))


@cache
def _installed_folders() -> tuple[Path, ...]:
    """Where installed code lives: the interpreter's prefixes' library folders and site-packages."""
    folders = {sysconfig.get_paths()[key] for key in ("stdlib", "platstdlib", "purelib", "platlib")}
    folders.update(site.getsitepackages() if hasattr(site, "getsitepackages") else [])
    folders.add(site.getusersitepackages())
    return tuple(Path(folder).resolve() for folder in folders if folder)


def _imported_names(path: Path, module: ModuleType) -> set[str]:
    """The absolute module names `path` imports (statically: `import a.b`, `from a import b` gives a and a.b)."""
    try:
        tree = ast.parse(path.read_bytes(), filename=str(path))
    except (OSError, SyntaxError, ValueError):
        return set()
    package = getattr(module, "__package__", None) or ""
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parent = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
                base = f"{parent}.{base}".strip(".") if parent else base
            if base:
                names.add(base)
                names.update(f"{base}.{alias.name}" for alias in node.names if alias.name != "*")
    return names


def _shown(path: Path, root: Path) -> str:
    return path.relative_to(root).as_posix() if path.is_relative_to(root) else str(path)


def digest(path: Path) -> str:
    """A file's content digest ("missing" when it cannot be read: then an edit that restores it shows)."""
    hashed = hashlib.sha256()
    try:
        with path.open("rb") as handle:
            for block in iter(lambda: handle.read(1 << 20), b""):
                hashed.update(block)
    except OSError:
        return "missing"
    return hashed.hexdigest()[:DIGEST_LENGTH]


def package_versions(top_level_names: Iterable[str]) -> dict[str, str]:
    """The versions of the distributions that provide these top-level modules, with `ALWAYS_VERSIONED`
    and Python's own version."""
    from importlib.metadata import PackageNotFoundError, packages_distributions, version

    providers = packages_distributions()
    wanted = set(ALWAYS_VERSIONED)
    for name in top_level_names:
        wanted.update(providers.get(name, ()))
    versions = {"python": ".".join(map(str, sys.version_info[:3]))}
    for distribution in sorted(wanted):
        try:
            versions[distribution.lower()] = version(distribution)
        except PackageNotFoundError:
            continue
    return versions


def collected_elsewhere(test_file: Path, collected: Iterable[Path]) -> set[Path]:
    """What a pytest session loaded that cannot matter to the test in `test_file`: the other collected test
    files, and the conftest.py files of folders that are not the test file's own or its ancestors."""
    test_file = test_file.resolve()
    ancestors = set(test_file.parents)
    others = {path.resolve() for path in collected} - {test_file}
    conftests = {path for path in project_conftests() if path.parent not in ancestors}
    return others | conftests


def scripts_beside(test_file: Path, test_patterns: Iterable[str]) -> list[Path]:
    """The Python files in the test file's own folder that are neither test files (`test_patterns`, pytest's
    `python_files`) nor conftest.py: a simulator, planner or tool the test may run as a program
    (`subprocess`), which is never imported and so not among the loaded modules. Taken by content, as data
    files: an edit of such a script is an edit of the code under test."""
    patterns = list(test_patterns)
    folder = test_file.resolve().parent
    try:
        candidates = sorted(folder.glob("*.py"))
    except OSError:
        return []
    return [path for path in candidates if path.is_file() and path.name != "conftest.py"
            and not any(fnmatch.fnmatch(path.name, pattern) for pattern in patterns)]


def project_conftests() -> set[Path]:
    return {path for module in list(sys.modules.values())
            if (path := _file_of(module)) is not None and path.name == "conftest.py"}

