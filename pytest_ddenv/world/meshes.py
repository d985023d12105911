"""The shapes read from files or made from numbers: mesh files, polylines extruded, heightmap images; each
made once per process, and checked so that a file that is not what it claims is refused when the world is
loaded, not in the simulator."""

from __future__ import annotations

import contextlib
import functools
import math
import sys
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from pytest_ddenv.errors import WorldError, shown_path
from pytest_ddenv.world import geometry
from pytest_ddenv.world.files import read_regular, regular_file_problem
from pytest_ddenv.world.geometry import FloatArray
from pytest_ddenv.world.limits import MAX_MAGNITUDE

if TYPE_CHECKING:
    import PIL.Image
    import shapely


MAX_MESH_BYTES = 256 * 1024 * 1024
"""Largest mesh file read."""
MAX_IMAGE_BYTES = 64 * 1024 * 1024
"""Largest heightmap image file read."""
HEIGHTMAP_SIDE = 1025 if sys.platform != "darwin" else 257
MAX_HEIGHTMAP_PIXELS = HEIGHTMAP_SIDE * HEIGHTMAP_SIDE
"""Most pixels of a heightmap image. pybullet passes a heightfield's heights through a buffer of 8 MiB of float32
(1 MiB on macOS): 2 097 152 heights (262 144); past it the heights it reads are garbage or the process crashes
(measured on Linux, pybullet 3.2.7: 1448 x 1448 and 2048 x 1024 pixels right, 1449 x 1449 and 2049 x 1024
wrong, 4096 x 4096 a segmentation fault). The limit is about half of that (a quarter on macOS)."""


def load_mesh(path: Path, scale: tuple[float, float, float]) -> object:
    """A trimesh.Trimesh of the file's geometry with `scale` applied, loaded once per process for each content
    of the file: the cache is keyed by the file's absolute path, size and modification time, so that a file
    edited (or a relative path read from another folder) is read again (`_load_mesh`)."""
    try:
        status = path.stat()
    except OSError:  # read_regular says what is wrong with it
        return _load_mesh(path, scale, (path.absolute(), None))
    return _load_mesh(path, scale, (path.absolute(), (status.st_size, status.st_mtime_ns, status.st_ino)))


@functools.lru_cache(maxsize=256)
def _load_mesh(path: Path, scale: tuple[float, float, float],
               version: tuple[Path, tuple[int, int, int] | None]) -> object:
    """`load_mesh` of one version of the file: `path` as given (in messages), `version` its absolute path and
    its size, modification time and inode (None: unknown).

    The file is read only if it is a regular file within MAX_MESH_BYTES (`files.read_regular`). Only the
    geometry is read: materials and textures are not loaded (a texture file that is missing or unreadable
    costs nothing and logs nothing). A Collada file goes to trimesh without its appearance elements
    (`pytest_ddenv.sdf.collada_geometry`), since trimesh's Collada reader has no option to skip materials and
    logs a traceback for every texture it cannot open. A vertex that is not a finite number is an error
    (trimesh would drop it with its triangles).
    """
    import io

    import trimesh

    data = None if path.suffix.lower() == ".dae" else read_regular(path, MAX_MESH_BYTES, "mesh file")
    try:
        if data is None:
            from pytest_ddenv.sdf._collada import collada_geometry

            geometry_only = io.BytesIO(collada_geometry(path))
            loaded = trimesh.load(geometry_only, file_type="dae", force="mesh", process=False)
        else:
            loaded = trimesh.load(io.BytesIO(data), file_type=path.suffix.lower().lstrip("."), force="mesh",
                                  skip_materials=True, process=False)
    except Exception as error:  # trimesh raises many types for unreadable files
        raise WorldError(f"cannot read mesh file: {error}", source=str(path)) from error
    if not np.all(np.isfinite(np.asarray(getattr(loaded, "vertices", ()), dtype=float))):
        raise WorldError(f"the mesh file {shown_path(path)} has vertices that are not finite numbers",
                         source=str(path))
    if callable(getattr(loaded, "process", None)):
        loaded.process()  # type: ignore[attr-defined]  # merge duplicate vertices, as trimesh.load does by default
    if math.prod(scale) != 1.0 or scale != (1.0, 1.0, 1.0):
        loaded.apply_scale(np.array(scale))  # type: ignore[no-untyped-call]  # trimesh leaves it unannotated
    return loaded


@functools.lru_cache(maxsize=256)
def cone_mesh(radius: float, length: float, sections: int = 32) -> object:
    """A trimesh.Trimesh of a cone (`Shape` kind "cone": base at z = -length/2, tip at +length/2)."""
    import trimesh

    mesh = trimesh.creation.cone(radius, length, sections=sections)
    mesh.apply_translation([0.0, 0.0, -length / 2.0])
    return mesh

HEIGHTMAP_MODES_16_BIT = ("I;16", "I;16L", "I;16B", "I;16N", "I")


@functools.lru_cache(maxsize=256)
def polyline_polygon(points: tuple[tuple[float, float], ...]) -> shapely.Polygon:
    """The shapely Polygon of a polyline's outline (closed implicitly), cached."""
    import shapely

    return shapely.remove_repeated_points(shapely.Polygon(points))


@functools.lru_cache(maxsize=256)
def polyline_mesh(points: tuple[tuple[float, float], ...], height: float) -> object:
    """A trimesh.Trimesh of the outline `points` extruded along z from 0 to `height` (made once per process).

    A concave outline gives a concave (watertight) mesh; the outline must be a valid simple polygon.
    """
    import trimesh

    problem = polyline_problem(points)
    if problem is not None:
        raise WorldError(f"cannot extrude the polyline: {problem}", field="points")
    return trimesh.creation.extrude_polygon(polyline_polygon(points), height)


def polyline_problem(points: Sequence[Sequence[float]]) -> str | None:
    """What makes `points` an invalid polyline outline, or None: fewer than 3 points, non-finite numbers or
    numbers beyond `limits.MAX_MAGNITUDE`, collinear points (no area), or an outline that crosses itself."""
    import shapely

    if len(points) < 3:
        return f"an outline needs at least 3 points, got {len(points)}"
    try:
        array = np.asarray(points, dtype=float)
    except (TypeError, ValueError, OverflowError):
        array = np.empty(0)
    if array.shape != (len(points), 2) or not np.all(np.isfinite(array)):
        return "every point must be two finite numbers [x, y]"
    if np.abs(array).max() > MAX_MAGNITUDE:
        return (f"every point must be within -1e9 to 1e9 m (the simulator does not handle larger numbers), got "
                f"{np.abs(array).max():g}")
    spread = np.linalg.svd(array - array.mean(axis=0), compute_uv=False)
    if spread[1] <= 1e-9 * max(spread[0], 1e-300):
        return "the points are collinear: the outline has no area"
    polygon = shapely.Polygon(array)
    if not polygon.is_valid:
        return f"the outline crosses or touches itself ({shapely.is_valid_reason(polygon)})"
    return None


@functools.lru_cache(maxsize=16)
def load_heightmap(path: Path) -> FloatArray:
    """The heights (rows, columns) in 0..1 of a grayscale image: black 0, white 1 (8-bit: value / 255,
    16-bit: value / 65535; colour images are converted to grey). Row 0 is the image's top row, which is
    the +y edge of the heightmap seen from above; column 0 is its -x edge. Read once per process, only if it
    is a regular file of at most MAX_IMAGE_BYTES and MAX_HEIGHTMAP_PIXELS pixels (WorldError otherwise)."""
    with _heightmap_image(path, lambda message: WorldError(message, source=path)) as image:
        try:
            if image.mode in HEIGHTMAP_MODES_16_BIT:
                heights = np.asarray(image, dtype=np.float64) / 65535.0
            else:
                heights = np.asarray(image.convert("L"), dtype=np.float64) / 255.0
        except (OSError, ValueError) as error:
            raise WorldError(f"cannot read the heightmap image: {error}", source=path) from error
    if heights.ndim != 2 or min(heights.shape) < 2:
        raise WorldError(f"a heightmap image needs at least 2 x 2 pixels, got {heights.shape[::-1]}", source=path)
    heights = np.clip(heights, 0.0, 1.0)
    heights.setflags(write=False)
    return heights


@contextlib.contextmanager
def _heightmap_image(path: Path, fail: Callable[[str], WorldError]) -> Iterator[PIL.Image.Image]:
    """The image at `path`, opened (its header read, its pixels not yet decoded) from the bytes of a regular
    file, with at least 2 x 2 and at most MAX_HEIGHTMAP_PIXELS pixels; `fail(reason)` otherwise."""
    import io
    import warnings

    from PIL import Image, UnidentifiedImageError

    problem = regular_file_problem(path, "heightmap image file")
    if problem is not None:
        raise fail(problem)
    data = read_regular(path, MAX_IMAGE_BYTES, "heightmap image")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)  # refused below, by its size
            image = Image.open(io.BytesIO(data))
    except Image.DecompressionBombError:
        raise fail(f"the heightmap image {shown_path(path)} has more than {2 * (Image.MAX_IMAGE_PIXELS or 0)} pixels; "
                   f"a heightmap has at most {MAX_HEIGHTMAP_PIXELS}") from None
    except (OSError, UnidentifiedImageError, ValueError) as error:
        raise fail(f"cannot read the heightmap image {shown_path(path)}: {error}") from error
    with image:
        width, height = image.size
        if min(width, height) < 2:
            raise fail(f"a heightmap image needs at least 2 x 2 pixels, {shown_path(path)} has {width} x {height}")
        if width * height > MAX_HEIGHTMAP_PIXELS:
            raise fail(f"the heightmap image {shown_path(path)} has {width} x {height} pixels; a heightmap has at "
                       f"most {MAX_HEIGHTMAP_PIXELS} ({HEIGHTMAP_SIDE} x {HEIGHTMAP_SIDE}): scale the image down")
        yield image


@functools.lru_cache(maxsize=16)
def heightmap_mesh(path: Path, size: tuple[float, float, float]) -> object:
    """A trimesh.Trimesh of the solid under the heightmap image at `path` stretched over `size` (x, y
    centred on the origin, z from 0 up), made once per process."""
    import trimesh

    vertices, faces = geometry.heightmap_solid(load_heightmap(path), size)
    return trimesh.Trimesh(vertices, faces, process=False)


def check_heightmap_image(path: Path, fail: Callable[[str | None, str], WorldError]) -> None:
    """The heightmap image is a regular file that opens (its header) with 2 x 2 to MAX_HEIGHTMAP_PIXELS pixels."""
    with _heightmap_image(path, lambda reason: fail("file", reason)):
        pass


def _no_triangles(path: Path) -> str:
    return f"not a mesh file: {shown_path(path)} holds no triangles (supported: .stl, .obj, .dae)"


def check_mesh_file(path: Path, scale: tuple[float, float, float], fail: Callable[[str], WorldError]) -> None:
    """Raise `fail(reason)` unless `path` is a mesh file with triangles and finite vertices (read now, once per
    process, so that a garbage or non-mesh file is refused when the world is loaded, not in the simulator)."""
    problem = regular_file_problem(path, "mesh file")
    if problem is not None:
        raise fail(problem)
    try:
        size = path.stat().st_size
    except OSError as error:
        raise fail(f"cannot read the mesh file {shown_path(path)}: {error.strerror or error}") from None
    if size > MAX_MESH_BYTES:
        raise fail(f"the mesh file {shown_path(path)} is larger than the {MAX_MESH_BYTES} byte limit")
    try:
        mesh = load_mesh(path, scale)
    except WorldError as error:
        cause = error.__cause__
        if cause is None:  # vertices that are not finite
            raise fail(error.reason) from None
        if isinstance(cause, TypeError):  # (trimesh 4) binary garbage decoded as text with no encoding detector
            raise fail(_no_triangles(path)) from None  # installed; with one, the same file loads with no triangles
        # an optional module missing says nothing about the file
        detail = "" if isinstance(cause, ImportError) else f" ({str(cause).splitlines()[0][:120]})"
        raise fail(f"not a mesh file: {shown_path(path)} cannot be read as {path.suffix or 'a mesh'}{detail}"
                   ) from None
    vertices = np.asarray(getattr(mesh, "vertices", ()), dtype=float)
    faces = np.asarray(getattr(mesh, "faces", ()))
    if len(faces) == 0 or len(vertices) == 0:
        raise fail(_no_triangles(path))
    if not np.all(np.isfinite(vertices)):
        raise fail(f"the mesh file {shown_path(path)} has vertices that are not finite numbers")
