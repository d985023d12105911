"""Exported worlds load in libsdformat, the SDF parser Gazebo itself uses (when it is installed).

`.ci/run` installs Debian's libsdformat-dev when it can; elsewhere this test is skipped with the reason.
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from pytest_ddenv import World

ROOT = Path(__file__).resolve().parent.parent
CHECKER = ROOT / "tests" / "data" / "sdf" / "sdformat_check.cc"


@pytest.fixture(scope="module")
def sdformat_check(tmp_path_factory: pytest.TempPathFactory) -> Path:
    if shutil.which("g++") is None or shutil.which("pkg-config") is None:
        pytest.skip("needs g++ and pkg-config to build the libsdformat checker")
    flags = subprocess.run(["pkg-config", "--cflags", "--libs", "sdformat12"], capture_output=True, text=True)
    if flags.returncode != 0:
        pytest.skip("libsdformat 12 is not installed (Debian: apt-get install libsdformat-dev)")
    binary = tmp_path_factory.mktemp("sdformat") / "sdformat_check"
    subprocess.run(["g++", "-std=c++17", str(CHECKER), "-o", str(binary), *flags.stdout.split()], check=True)
    return binary


@pytest.mark.parametrize("name", ["ditch", "rubble", "friction"])
def test_shipped_and_freshly_exported_worlds_load_without_errors(
    sdformat_check: Path, tmp_path: Path, name: str
) -> None:
    world = World.load(ROOT / "worlds" / f"{name}.yaml")
    exported = tmp_path / f"{name}.world"
    world.select(world.names[:3]).save(exported)  # a minimal world as the plugin writes it
    result = subprocess.run(
        [str(sdformat_check), str(ROOT / "worlds" / f"{name}.world"), str(exported)],
        capture_output=True, text=True,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    assert f"ok, {len(world) + 1} models" in result.stdout  # + the ground plane model
    assert "ok, 4 models" in result.stdout
