"""Gazebo SDF interoperability: import SDF 1.2-1.11 worlds and models as Gazebo simulates them, export SDF 1.6.

`load_sdf(path, model_paths=..., skip_unsupported=...)` / `parse_sdf(text)` read a world (applying its first
`<state>` block) or a single-model file; `World.notes` says what is not simulated. `dump_sdf(world)` writes a
world Gazebo loads; `cut_models(path, removed)` is an SDF file with some of its models cut out, nothing else
changed (the surgical export of a reduction). `collada_geometry(path)` is a Collada file without its materials, for
trimesh. See docs/sdf.md for what is supported.
"""

from __future__ import annotations

from pytest_ddenv.sdf._bodies import MAX_COLLISIONS
from pytest_ddenv.sdf._collada import collada_geometry
from pytest_ddenv.sdf._fuel import FUEL_CACHE_VARIABLES
from pytest_ddenv.sdf._includes import MAX_INCLUDES
from pytest_ddenv.sdf._paths import MODEL_PATH_VARIABLES, model_search_paths
from pytest_ddenv.sdf._reader import DDENV_NS, load_sdf, parse_sdf
from pytest_ddenv.sdf._surgical import SurgeryError, cut_models
from pytest_ddenv.sdf._tree import MAX_LINKS, MAX_MODELS
from pytest_ddenv.sdf._values import UnsupportedSdfError
from pytest_ddenv.sdf._writer import dump_sdf
from pytest_ddenv.sdf._xml import MAX_FILE_BYTES

__all__ = [
    "DDENV_NS",
    "FUEL_CACHE_VARIABLES",
    "MAX_COLLISIONS",
    "MAX_FILE_BYTES",
    "MAX_INCLUDES",
    "MAX_LINKS",
    "MAX_MODELS",
    "MODEL_PATH_VARIABLES",
    "SurgeryError",
    "UnsupportedSdfError",
    "collada_geometry",
    "cut_models",
    "dump_sdf",
    "load_sdf",
    "model_search_paths",
    "parse_sdf",
]
