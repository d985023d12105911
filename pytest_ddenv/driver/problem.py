"""Which problem a run log belongs to: the world, the reduction settings, the test, the code under test and
the failure being reduced. A log is resumed only for the same problem (`artifacts.prepare`); when it is not,
`Problem.differences` says what changed, in words, for the note that the old log was moved aside.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pytest_ddenv.driver.code_identity import CodeIdentity, digest
from pytest_ddenv.reduce import events
from pytest_ddenv.world.formats import FORMATS
from pytest_ddenv.world.limits import engine_version
from pytest_ddenv.world.yaml_format import WRITTEN_DEFAULT_ENGINE

if TYPE_CHECKING:
    from pytest_ddenv.world.model import World

PARTS = {"world": "the world", "settings": "the reduction settings", "test": "the test function's source"}
"""The parts of a problem besides the code, and how a note names them."""
ENGINE_PART = "engine"
"""The part that names the physics engine and its version ("pybullet 3.2.7"), as text: a run is bit-identical
only in the same engine of the same version, so a log is never resumed in another."""


@dataclass(frozen=True)
class Problem:
    """One reduction problem. `fingerprint` covers every part; `parts` are the digests of the world, settings
    and test source (to say which changed); `reference` is the failure being reduced, as plain data."""

    fingerprint: str
    test_id: str = ""
    parts: Mapping[str, str] = field(default_factory=dict)
    code: CodeIdentity = field(default_factory=CodeIdentity)
    reference: Mapping[str, Any] | None = None

    def header(self) -> events.Problem:
        """The first event of its run log."""
        reference = None if self.reference is None else dict(self.reference)
        return events.Problem(fingerprint=self.fingerprint, test=self.test_id, parts=dict(self.parts),
                              code=self.code.to_json(), reference=reference)

    def differences(self, header: events.Problem) -> list[str]:
        """What differs between this problem and the one a log's `header` names, in words (empty when the
        header says too little to tell)."""
        said: list[str] = []
        earlier = CodeIdentity.from_json(header.code)
        if earlier is not None:
            changes = self.code.changes_since(earlier)
            if changes:
                said.append("the code under test changed: " + _listing(changes))
        said += [f"{name} changed" for key, name in PARTS.items() if header.parts.get(key) != self.parts.get(key)]
        logged = str(header.parts.get(ENGINE_PART, "pybullet"))  # a log from before engines were named: pybullet
        engine = str(self.parts.get(ENGINE_PART, ""))
        if logged not in (engine, engine.partition(" ")[0]):
            said.append(f"the physics engine changed: {logged} -> {engine}")
        return said


def problem_of(world: World, settings: Mapping[str, Any], test_source: str, code: CodeIdentity, *,
               test_id: str = "", reference: Mapping[str, Any] | None = None) -> Problem:
    """The problem of a reduction (`reference`, the failure reduced, is checked apart from the fingerprint:
    a resumed log must have reduced the same failure, under the same-failure rule, not an identical one)."""
    engine = world.physics.engine
    unnamed = world.with_engine(WRITTEN_DEFAULT_ENGINE)  # the engine is its own part
    parts = {"world": _digest(FORMATS["yaml"].dump(unnamed, None)), "settings": _digest(settings),
             "test": _digest(test_source)}
    code = CodeIdentity({**code.files, **{_shown(path): digest(path) for path in world_files(world)}}, code.packages)
    fingerprint = _digest({**parts, "code": code.to_json(), engine: engine_version(engine)})
    return Problem(fingerprint, test_id, {**parts, ENGINE_PART: f"{engine} {engine_version(engine)}"}, code,
                   reference)


def _digest(value: Any) -> str:
    text = value if isinstance(value, str) else json.dumps(value, sort_keys=True, default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def _shown(path: Path) -> str:
    """A path relative to the working folder when it is inside it."""
    resolved = path.resolve()
    return resolved.relative_to(Path.cwd()).as_posix() if resolved.is_relative_to(Path.cwd()) else str(resolved)


def _listing(items: list[str], limit: int = 6) -> str:
    shown = ", ".join(items[:limit])
    return shown if len(items) <= limit else f"{shown} and {len(items) - limit} more"


def world_files(world: World) -> list[Path]:
    """The files a world's simulation reads besides the world file itself: its meshes and heightmap images
    and its robot's URDF (given in the world file, or registered with `register_robot` as a description)."""
    from pytest_ddenv.sim.robot import ROBOTS
    from pytest_ddenv.world.files import resolve_mesh_path, resolve_relative
    from pytest_ddenv.world.model import RobotDescription

    files = {resolve_mesh_path(shape.mesh, world.source) for model in world.models for shape in model.shapes
             if shape.mesh is not None}
    robot = None if world.scenario is None else world.scenario.robot
    if isinstance(robot, RobotDescription):
        files.add(resolve_relative(robot.urdf, world.source))
    elif isinstance(robot, str):
        registered = getattr(ROBOTS.get(robot), "args", ())  # a description registered by name
        files.update(Path(arg.urdf).expanduser() for arg in registered if isinstance(arg, RobotDescription))
    return sorted(files)
