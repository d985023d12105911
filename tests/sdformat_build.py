"""Build a small libsdformat 12 program of tests/data/sdf (the checker, the dumper) for the tests that compare
with Gazebo's own SDF parser; the test is skipped where libsdformat or a compiler is missing."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest


def build_sdformat_tool(source: Path, folder: Path) -> Path:
    """`source` (a .cc file) compiled into `folder`; skips the calling test when it cannot be built here."""
    if shutil.which("g++") is None or shutil.which("pkg-config") is None:
        pytest.skip("needs g++ and pkg-config to build the libsdformat checker")
    flags = subprocess.run(["pkg-config", "--cflags", "--libs", "sdformat12"], capture_output=True, text=True,
                           check=False)
    if flags.returncode != 0:
        pytest.skip("libsdformat 12 is not installed (Debian: apt-get install libsdformat-dev)")
    binary = folder / source.stem
    subprocess.run(["g++", "-std=c++17", str(source), "-o", str(binary), *flags.stdout.split()], check=True)
    return binary
