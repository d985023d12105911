"""MuJoCo MJCF scenes: read a scene as a `World` (MuJoCo itself parses and compiles it) and cut a reduction's
removed bodies out of it (the surgical `minimal.xml`).

`load_mjcf(path, skip_unsupported=...)` reads a scene: each direct child body of `<worldbody>` is a model;
`World.notes` names what is not simulated. `cut_bodies(path, removed)` is the scene's text with those top-level
bodies (and the elements that name something inside them) cut out, nothing else changed. Needs MuJoCo
(`pip install "pytest-ddenv[mujoco]"`). See docs/mjcf.md.

Modules: `_files` (the scene's files read safely: includes, limits, where each element is), `_mujoco` (the
import and MuJoCo's errors as ours), `_reader` (the compiled scene as a `World`), `_shapes` (geoms as shapes),
`_scenario` (the `ddenv:scenario` custom text), `_cut` (the surgical export and its check).
"""

from __future__ import annotations

from pytest_ddenv.mjcf._cut import cut_bodies, minimal_xml
from pytest_ddenv.mjcf._files import MAX_BODIES, MAX_FILE_BYTES, MAX_GEOMS, MAX_INCLUDES, MAX_NESTING
from pytest_ddenv.mjcf._reader import UnsupportedMjcfError, load_mjcf

__all__ = [
    "MAX_BODIES",
    "MAX_FILE_BYTES",
    "MAX_GEOMS",
    "MAX_INCLUDES",
    "MAX_NESTING",
    "UnsupportedMjcfError",
    "cut_bodies",
    "load_mjcf",
    "minimal_xml",
]
