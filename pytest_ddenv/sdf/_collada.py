"""Collada (.dae) files read safely: the unit Gazebo applies, and the geometry alone for trimesh."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

from pytest_ddenv.sdf._xml import Lines, local_name, parse_xml, read_limited

APPEARANCE = frozenset({"library_images", "library_effects", "library_materials", "bind_material"})
"""Collada elements that only say how a mesh looks: textures, effects, materials and their bindings."""


def collada_unit(path: Path) -> float:
    """The `<asset><unit meter>` of a Collada file in metres (trimesh does not apply it; Gazebo does)."""
    root = parse_xml(read_limited(path, what="Collada mesh"), str(path), Lines())
    for element in root.iter():
        if local_name(element.tag) == "unit" and element.get("meter") is not None:
            try:
                meter = float(element.get("meter", "1"))
            except ValueError:
                return 1.0
            return meter if meter > 0 and math.isfinite(meter) else 1.0
    return 1.0


def collada_geometry(path: Path) -> bytes:
    """The Collada file at `path` without its appearance (images, effects, materials), as bytes for trimesh.

    The collision geometry is all the simulation needs. trimesh resolves a material's texture files on load and
    logs a traceback for each it cannot read (Gazebo models keep textures in `../materials/textures/`, outside
    the folder trimesh may read from), so `load_mesh` gives trimesh this text instead of the file. The file is
    parsed with defusedxml (no DTDs, no entities) and refused above the size limit, like every SDF file.
    """
    root = parse_xml(read_limited(path, what="Collada mesh"), str(path), Lines())
    for parent in list(root.iter()):
        for child in [c for c in parent if local_name(c.tag) in APPEARANCE]:
            parent.remove(child)
    return ET.tostring(root)
