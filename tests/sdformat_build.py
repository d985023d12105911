"""Build a small libsdformat 12 program of tests/data/sdf (the checker, the dumper) for the tests that compare
with Gazebo's own SDF parser; the test is skipped where libsdformat or a compiler is missing.

A build is kept in a cache folder (the pytest cache: tests/conftest.py's `sdformat_cache`) under a name
made of the source's content, the compiler's version and libsdformat's version and flags: a session builds
each program at most once, a later run on the same machine reuses it, and a changed source, compiler or
library makes a new one. A lock file makes concurrent sessions (pytest-xdist workers) build it once."""

from __future__ import annotations

import fcntl
import hashlib
import os
import shutil
import subprocess
from pathlib import Path

import pytest

PACKAGE = "sdformat12"


def _output(*command: str) -> str:
    """What `command` printed; skips the calling test when it fails."""
    done = subprocess.run(command, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        pytest.skip(f"libsdformat 12 is not installed (Debian: apt-get install libsdformat-dev): "
                    f"`{' '.join(command)}` says {done.stderr.strip() or done.returncode}")
    return done.stdout


def build_key(source: Path, compiler_version: str, flags: str, library_version: str) -> str:
    """The name of a build: what makes its binary, hashed."""
    digest = hashlib.sha256()
    for part in (source.read_bytes(), compiler_version.encode(), flags.encode(), library_version.encode()):
        digest.update(len(part).to_bytes(8, "big") + part)
    return digest.hexdigest()[:20]


def build_sdformat_tool(source: Path, cache: Path) -> Path:
    """`source` (a .cc file) compiled into `cache`, or the build already there; skips the calling test when it
    cannot be built here."""
    if shutil.which("g++") is None or shutil.which("pkg-config") is None:
        pytest.skip("needs g++ and pkg-config to build the libsdformat checker")
    flags = _output("pkg-config", "--cflags", "--libs", PACKAGE).strip()
    key = build_key(source, _output("g++", "--version"), flags, _output("pkg-config", "--modversion", PACKAGE))
    binary = cache / f"{source.stem}-{key}"
    cache.mkdir(parents=True, exist_ok=True)
    with (cache / f"{source.stem}.lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # another session building the same program: wait for its binary
        if not binary.exists():
            partial = binary.with_name(f"{binary.name}.{os.getpid()}.partial")
            subprocess.run(["g++", "-std=c++17", str(source), "-o", str(partial), *flags.split()], check=True)
            partial.replace(binary)
    return binary
