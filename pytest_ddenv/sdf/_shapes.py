"""SDF `<geometry>` to `Shape`s: box, cylinder, sphere, capsule, cone, polyline, heightmap, mesh; planes apart.

A missing size element takes its default from the SDF specification, as libsdformat fills it in (a `<box>`
without `<size>` is 1 x 1 x 1 m in Gazebo); an empty or unreadable one is an error, as in libsdformat. An
element of `<geometry>` that is no geometry (`<bx>`, a typo) is an error: libsdformat warns and simulates no
collision at all. A mesh or heightmap file that is missing or cannot be read makes the model unavailable
(`UnavailableSdfError`: `skip_unsupported` drops it).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pytest_ddenv.errors import PATH_CHARACTERS, WorldError, shown, shown_path
from pytest_ddenv.sdf import _poses
from pytest_ddenv.sdf._collada import collada_unit
from pytest_ddenv.sdf._paths import UnresolvedURI, resolve_uri
from pytest_ddenv.sdf._values import Values
from pytest_ddenv.world.files import is_file
from pytest_ddenv.world.meshes import check_mesh_file
from pytest_ddenv.world.model import Pose, Shape
from pytest_ddenv.world.values import check_shape

MESH_SUFFIXES = (".stl", ".obj", ".dae")
HEIGHTMAP_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp")
SUPPORTED_GEOMETRY = ("box", "cylinder", "sphere", "capsule", "cone", "polyline", "heightmap", "mesh", "plane")
UNSUPPORTED_GEOMETRY = {
    "ellipsoid": "ellipsoids are not simulated",
    "image": "image-extruded geometry is not simulated",
}
SDF_GEOMETRY = (*SUPPORTED_GEOMETRY, *UNSUPPORTED_GEOMETRY, "empty")
PLANE_THICKNESS = 0.1
"""Thickness (m) of the box that stands for a plane that is not the ground, under the plane's surface."""


@dataclass
class Geometry:
    """What one `<geometry>` holds: shapes in the collision frame, or a plane (normal, size)."""

    shapes: list[Shape] = field(default_factory=list)
    normal: tuple[float, float, float] | None = None
    plane_size: tuple[float, float] = (1.0, 1.0)
    holes: int = 0  # polyline outlines inside another one (Gazebo cuts them out; here they are solid)


class GeometryReader:
    def __init__(self, values: Values, search_paths: Sequence[Path]) -> None:
        self.values = values
        self.search_paths = search_paths

    def read(self, geometry: ET.Element, where: str, base_dir: Path | None, model: str) -> Geometry | None:
        """The shapes of a `<geometry>`, or None when it holds none (`<empty/>` or nothing: no collision)."""
        unknown = next((child for child in geometry if child.tag not in SDF_GEOMETRY and "}" not in child.tag), None)
        if unknown is not None:
            raise self.values.error(f"unknown geometry <{shown(unknown.tag)[1:-1]}>; expected one of: "
                                    f"{', '.join(SDF_GEOMETRY)}", unknown, model=model, field=f"{where}/geometry")
        kinds = [child for child in geometry if child.tag in SDF_GEOMETRY]
        if not kinds or all(child.tag == "empty" for child in kinds):
            return None
        if len({child.tag for child in kinds}) > 1 or (len(kinds) > 1 and kinds[0].tag != "polyline"):
            names = ", ".join(child.tag for child in kinds)
            raise self.values.error(f"a geometry holds exactly one shape, got {names}", geometry, model=model,
                                    field=f"{where}/geometry")
        element = kinds[0]
        where = f"{where}/geometry/{element.tag}"
        if element.tag == "polyline":
            return self.polylines(kinds, where, model)
        if element.tag in UNSUPPORTED_GEOMETRY:
            raise self.values.unsupported(element.tag, UNSUPPORTED_GEOMETRY[element.tag], element, model=model,
                                          field=where)
        if element.tag == "plane":
            normal = self.values.child_floats(element, "normal", 3, where, model, (0.0, 0.0, 1.0))
            if float(np.linalg.norm(normal)) == 0.0:
                raise self.values.error("a plane's normal must not be zero", element, model=model,
                                        field=f"{where}/normal")
            size = self.values.child_floats(element, "size", 2, where, model, (1.0, 1.0))
            if min(size) <= 0:
                raise self.values.error(f"plane sizes must be positive, got {size}", element, model=model,
                                        field=f"{where}/size")
            return Geometry(normal=(normal[0], normal[1], normal[2]), plane_size=(size[0], size[1]))
        if element.tag == "mesh":
            return Geometry([self.mesh(element, where, base_dir, model)])
        if element.tag == "heightmap":
            return Geometry([self.heightmap(element, where, base_dir, model)])
        return Geometry([self.primitive(element, where, model)])

    def primitive(self, element: ET.Element, where: str, model: str) -> Shape:
        values = self.values
        if element.tag == "box":
            size = values.child_floats(element, "size", 3, where, model, (1.0, 1.0, 1.0))
            if min(size) <= 0:
                raise values.error(f"box sizes must be positive, got {size}", element.find("size"), model=model,
                                   field=f"{where}/size")
            return Shape("box", size=(size[0], size[1], size[2]))
        if element.tag == "sphere":
            radius = values.child_number(element, "radius", where, model, positive=True, default=1.0)
            return Shape("sphere", radius=radius)
        if element.tag == "cone":  # SDF 1.11: its base at -length/2, its tip at +length/2
            radius = values.child_number(element, "radius", where, model, positive=True, default=1.0)
            length = values.child_number(element, "length", where, model, positive=True, default=1.0)
            return Shape("cone", radius=radius, length=length)
        default_radius = 0.5 if element.tag == "capsule" else 1.0
        radius = values.child_number(element, "radius", where, model, positive=True, default=default_radius)
        length = values.child_number(element, "length", where, model, default=1.0)
        assert length is not None
        if length < 0 or (length == 0 and element.tag == "cylinder"):
            raise values.error(f"expected a {'positive' if element.tag == 'cylinder' else 'non-negative'} length, "
                               f"got {length}", element.find("length"), model=model, field=f"{where}/length")
        if length == 0:  # a capsule without a cylinder part: what Gazebo draws is a sphere
            return Shape("sphere", radius=radius)
        return Shape("cylinder" if element.tag == "cylinder" else "capsule", radius=radius, length=length)

    def polylines(self, elements: list[ET.Element], where: str, model: str) -> Geometry:
        """One extruded shape per `<polyline>`; outlines inside another are counted as (filled) holes."""
        shapes = []
        for element in elements:
            points = [self.values.floats(point, (2,), f"{where}/point", model) for point in element.findall("point")]
            if len(points) > 1 and points[-1] == points[0]:
                points.pop()  # an outline closed explicitly
            if len(points) < 3:
                raise self.values.error(f"a polyline needs at least 3 points, got {len(points)}", element,
                                        model=model, field=f"{where}/point")
            height = self.values.child_number(element, "height", where, model, positive=True, default=1.0)
            shape = Shape("polyline", points=tuple((p[0], p[1]) for p in points), height=height)
            try:  # the world model's own rules (a simple outline: no self-intersection, not all on a line)
                check_shape(shape, model=model, field=where, keys={"points": "point"})
            except WorldError as error:
                raise self.values.error(error.reason, element, model=model, field=error.field) from None
            shapes.append(shape)
        holes = sum(
            1 for index, inner in enumerate(shapes)
            if any(_inside(inner, outer) for other, outer in enumerate(shapes) if other != index)
        )
        return Geometry(shapes, holes=holes)

    def heightmap(self, element: ET.Element, where: str, base_dir: Path | None, model: str) -> Shape:
        path = self.file(element, where, base_dir, model, "heightmap", HEIGHTMAP_SUFFIXES,
                         "only grayscale images are simulated (not DEM files)")
        size = self.values.child_floats(element, "size", 3, where, model, (1.0, 1.0, 1.0))
        if min(size) <= 0:
            raise self.values.error(f"heightmap sizes must be positive, got {size}", element.find("size"), model=model,
                                    field=f"{where}/size")
        pos = self.values.child_floats(element, "pos", 3, where, model, (0.0, 0.0, 0.0))
        return Shape("heightmap", mesh=str(path.resolve()), size=(size[0], size[1], size[2]),
                     pose=Pose(pos[0], pos[1], pos[2]))

    def mesh(self, element: ET.Element, where: str, base_dir: Path | None, model: str) -> Shape:
        submesh = element.find("submesh")
        if submesh is not None:
            raise self.values.unsupported("submesh", "a part of a mesh file is not simulated; use a mesh file with "
                                          "only that part", submesh, model=model, field=f"{where}/submesh")
        path = self.file(element, where, base_dir, model, "mesh", MESH_SUFFIXES, "")
        scale = self.values.child_floats(element, "scale", 3, where, model, (1.0, 1.0, 1.0))
        if min(scale) <= 0:
            raise self.values.error(f"mesh scales must be positive, got {scale}", element.find("scale"), model=model,
                                    field=f"{where}/scale")
        uri = element.find("uri")
        try:
            unit = collada_unit(path) if path.suffix.lower() == ".dae" else 1.0
        except WorldError as error:
            raise self.values.unavailable("mesh", f"cannot read {shown_path(path)}: {error.reason}", uri,
                                          model=model, field=f"{where}/uri") from None
        shape = Shape("mesh", mesh=str(path.resolve()), scale=(scale[0] * unit, scale[1] * unit, scale[2] * unit))
        check_mesh_file(path.resolve(), shape.scale, lambda reason: self.values.unavailable(
            "mesh", reason, uri, model=model, field=f"{where}/uri"))
        return shape

    def file(
        self, element: ET.Element, where: str, base_dir: Path | None, model: str, tag: str,
        suffixes: Sequence[str], why: str,
    ) -> Path:
        """The local file a mesh or heightmap `<uri>` names."""
        uri_element = element.find("uri")
        uri = (uri_element.text or "").strip() if uri_element is not None else ""
        if uri_element is None or not uri:
            raise self.values.error(f"a <{tag}> needs a <uri>", element if uri_element is None else uri_element,
                                    model=model, field=f"{where}/uri")
        shown_uri = shown(uri, PATH_CHARACTERS)
        try:
            path = resolve_uri(uri, base_dir, self.search_paths)
        except UnresolvedURI as unresolved:
            raise self.values.unavailable(tag, f"missing {tag} file {unresolved.describe()}", uri_element,
                                          model=model, field=f"{where}/uri") from None
        if not is_file(path):
            raise self.values.unavailable(tag, f"{tag} {shown_uri} is not a file: {shown_path(path)}", uri_element,
                                          model=model, field=f"{where}/uri")
        if path.suffix.lower() not in suffixes:
            suffix = shown(path.suffix or "(no extension)")
            detail = f"format {suffix} of {shown_uri}; supported: {', '.join(suffixes)}"
            raise self.values.unsupported(tag, f"{detail}{'; ' + why if why else ''}", uri_element, model=model,
                                          field=f"{where}/uri")
        return path


def plane_box(normal: tuple[float, float, float], size: tuple[float, float]) -> Shape:
    """The box that stands for a plane: the plane's size, PLANE_THICKNESS thick, its top face on the plane.

    The plane's own x and y axes are those of Gazebo's plane: the shortest rotation from +z to the normal.
    """
    rotation = _rotation_from_z(np.asarray(normal, dtype=float))
    centre = rotation @ np.array([0.0, 0.0, -PLANE_THICKNESS / 2.0])
    pose = _poses.from_matrix(centre, rotation)
    return Shape("box", size=(size[0], size[1], PLANE_THICKNESS), pose=pose)


def _rotation_from_z(normal: np.ndarray) -> np.ndarray:
    axis = normal / np.linalg.norm(normal)
    z = np.array([0.0, 0.0, 1.0])
    cross = np.cross(z, axis)
    sine, cosine = float(np.linalg.norm(cross)), float(axis @ z)
    if sine < 1e-12:
        return np.eye(3) if cosine > 0 else np.diag([1.0, -1.0, -1.0])
    k = cross / sine
    skew = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    result: np.ndarray = np.eye(3) + sine * skew + (1.0 - cosine) * (skew @ skew)
    return result


def _inside(inner: Shape, outer: Shape) -> bool:
    """Whether every point of `inner`'s outline lies inside `outer`'s outline (even-odd rule)."""
    assert inner.points is not None and outer.points is not None
    return all(_point_in_polygon(point, outer.points) for point in inner.points)


def _point_in_polygon(point: tuple[float, float], polygon: Sequence[tuple[float, float]]) -> bool:
    x, y = point
    inside = False
    for (x1, y1), (x2, y2) in zip(polygon, (*polygon[1:], polygon[0]), strict=True):
        if (y1 > y) != (y2 > y) and x < x1 + (y - y1) * (x2 - x1) / (y2 - y1):
            inside = not inside
    return inside
