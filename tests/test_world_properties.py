"""Properties of the world model, checked with generated worlds and points."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pytest_ddenv import Ground, Model, Pose, Scenario, Shape, World
from pytest_ddenv.world.geometry import to_local

# Tag values may hold any character but control characters other than tab and newline (docs/reliability.md).
TAG_CHARACTERS = st.characters(blacklist_categories=("Cc", "Cs")) | st.sampled_from("\t\n")

finite = st.floats(min_value=-50, max_value=50, allow_nan=False, allow_infinity=False)
angle = st.floats(min_value=-math.pi, max_value=math.pi, allow_nan=False)
positive = st.floats(min_value=0.01, max_value=5, allow_nan=False)
poses = st.builds(Pose, finite, finite, finite, angle, angle, angle)

boxes = st.builds(lambda size, pose: Shape("box", size=size, pose=pose), st.tuples(positive, positive, positive), poses)
cylinders = st.builds(lambda r, h, pose: Shape("cylinder", radius=r, length=h, pose=pose), positive, positive, poses)
spheres = st.builds(lambda r, pose: Shape("sphere", radius=r, pose=pose), positive, poses)
capsules = st.builds(lambda r, h, pose: Shape("capsule", radius=r, length=h, pose=pose), positive, positive, poses)


@st.composite
def polylines(draw: st.DrawFn) -> Shape:
    """A star-shaped outline around the local origin (every fan triangle from the origin is inside it): the
    angle between consecutive points stays below 180 degrees (for 3 points: (1 + 2 x 0.24) x 120 < 180)."""
    count = draw(st.integers(3, 8))
    jitter = st.floats(-0.24, 0.24, allow_nan=False)
    angles = [2 * math.pi * (k + draw(jitter)) / count for k in range(count)]
    radii = [draw(st.floats(0.05, 3.0, allow_nan=False)) for _ in range(count)]
    points = tuple((r * math.cos(a), r * math.sin(a)) for r, a in zip(radii, angles, strict=True))
    return Shape("polyline", points=points, height=draw(positive), pose=draw(poses))


shapes = st.one_of(boxes, cylinders, spheres, capsules, polylines())


@st.composite
def models(draw: st.DrawFn, name: str) -> Model:
    mass = draw(st.one_of(st.none(), positive))
    mu = draw(st.floats(min_value=0, max_value=1000, allow_nan=False))
    return Model(
        name=name,
        shapes=tuple(draw(st.lists(shapes, min_size=1, max_size=3))),
        pose=draw(poses),
        mass=mass,
        static=mass is None or draw(st.booleans()),
        mu=mu,
        mu2=draw(st.one_of(st.just(mu), st.floats(min_value=0, max_value=10, allow_nan=False))),
        restitution=draw(st.floats(min_value=0, max_value=1, allow_nan=False)),
        color=draw(st.tuples(*[st.floats(min_value=0, max_value=1, allow_nan=False)] * 4)),
        keep=draw(st.booleans()),
        tags=draw(st.dictionaries(st.sampled_from(["kind", "note"]), st.one_of(st.text(TAG_CHARACTERS, max_size=5), st.integers()))),
    )


@st.composite
def worlds(draw: st.DrawFn) -> World:
    names = draw(st.lists(st.text("abcdefgh_0123456789", min_size=1, max_size=8), unique=True, max_size=8))
    scenario = draw(
        st.one_of(
            st.none(),
            st.builds(
                lambda x, y, yaw, gx, gy, t, z: Scenario(
                    start=Pose(x, y, 0.0 if z is None else z, 0, 0, yaw), start_z_given=z is not None,
                    goal=(gx, gy, None), timeout=t,
                ),
                finite, finite, angle, finite, finite, positive, st.one_of(st.none(), finite),
            ),
        )
    )
    ground = draw(st.one_of(st.none(), st.builds(Ground, finite, positive, positive, st.just(0.0))))
    return World(models=tuple(draw(models(name)) for name in names), scenario=scenario, ground=ground, name="gen")


@given(worlds())
@settings(max_examples=60, deadline=None)
def test_save_then_load_gives_the_same_world(world: World) -> None:
    assert World.from_yaml(world.to_yaml()) == world


@given(worlds(), st.data())
@settings(max_examples=60, deadline=None)
def test_select_and_without_are_complementary_and_keep_order(world: World, data: st.DataObject) -> None:
    chosen = data.draw(st.sets(st.sampled_from(world.names)) if world.names else st.just(set()))
    selected, rest = world.select(chosen), world.without(chosen)
    assert set(selected.names) | set(rest.names) == set(world.names)
    assert not set(selected.names) & set(rest.names)
    order = {name: i for i, name in enumerate(world.names)}
    for part in (selected, rest):
        assert [order[n] for n in part.names] == sorted(order[n] for n in part.names)
        assert all(part.model(n) == world.model(n) for n in part.names)


def brute_force_distance(shape: Shape, local_points: np.ndarray) -> np.ndarray:
    """Distance to a densely sampled solid (surface and interior grid), independent of the analytic code."""
    u = np.linspace(-0.5, 0.5, 41)
    if shape.kind == "box":
        grid = np.stack(np.meshgrid(u, u, u, indexing="ij"), axis=-1).reshape(-1, 3) * np.array(shape.size)
    elif shape.kind == "capsule":
        cylinder = brute_force_grid(Shape("cylinder", radius=shape.radius, length=shape.length))
        ball = brute_force_grid(Shape("sphere", radius=shape.radius))
        ends = [ball + [0.0, 0.0, sign * shape.length / 2] for sign in (-1, 1)]
        grid = np.vstack([cylinder, *ends])
    elif shape.kind == "polyline":
        grid = polyline_grid(shape)
    else:
        grid = brute_force_grid(shape)
    return np.min(np.linalg.norm(local_points[:, None, :] - grid[None, :, :], axis=2), axis=1)


def brute_force_grid(shape: Shape) -> np.ndarray:
    """Points filling a centred sphere or cylinder."""
    if shape.kind == "cylinder":
        theta = np.linspace(0, 2 * np.pi, 120, endpoint=False)
        rings = [np.column_stack([r * np.cos(theta), r * np.sin(theta)]) for r in np.linspace(0, shape.radius, 12)]
        disk = np.vstack(rings)
        return np.vstack([np.column_stack([disk, np.full(len(disk), z * shape.length)])
                          for z in np.linspace(-0.5, 0.5, 41)])
    phi, theta = np.meshgrid(np.linspace(0, np.pi, 60), np.linspace(0, 2 * np.pi, 120), indexing="ij")
    unit = np.stack([np.sin(phi) * np.cos(theta), np.sin(phi) * np.sin(theta), np.cos(phi)], -1).reshape(-1, 3)
    return np.vstack([unit * r for r in np.linspace(0, shape.radius, 20)])  # shells r/19 apart: error < 0.06 r


def polyline_grid(shape: Shape) -> np.ndarray:
    """Points filling a star-shaped polyline prism: its fan triangles from the origin, at heights 0..height."""
    outline = np.array(shape.points)
    a, b = np.meshgrid(np.linspace(0, 1, 61), np.linspace(0, 1, 61), indexing="ij")
    keep = a + b <= 1
    a, b = a[keep], b[keep]
    flat = np.vstack([np.outer(a, outline[k]) + np.outer(b, outline[(k + 1) % len(outline)])
                      for k in range(len(outline))])
    return np.vstack([np.column_stack([flat, np.full(len(flat), z)]) for z in np.linspace(0, shape.height, 21)])


@given(shapes, poses, st.lists(st.tuples(finite, finite, finite), min_size=1, max_size=5))
@settings(max_examples=40, deadline=None)
def test_distances_match_a_brute_force_reference(shape: Shape, pose: Pose, raw_points: list) -> None:
    model = Model("m", (dataclasses.replace(shape, pose=Pose()),), pose=pose)
    world = World(models=(model,))
    points = pose.position + (np.array(raw_points) / 10.0)  # near the shape, so the tolerance is meaningful
    computed = world.distances(points)[:, 0]
    reference = brute_force_distance(model.shapes[0], to_local(points, pose.position, pose.rotation))
    if shape.kind == "box":
        largest = max(shape.size or (0,))
    elif shape.kind == "polyline":
        largest = max(float(np.max(np.abs(shape.points))), shape.height or 0)
    else:
        largest = max(shape.radius or 0, shape.length or 0)
    assert np.all(computed >= 0)
    assert np.all(computed <= reference + 1e-9)  # the sampled solid is inside the true one
    assert np.allclose(computed, reference, atol=0.06 * largest + 1e-9)


@given(shapes, poses, st.lists(st.tuples(*[st.floats(-0.49, 0.49)] * 3), min_size=1, max_size=10))
@settings(max_examples=60, deadline=None)
def test_points_inside_a_shape_are_at_distance_zero(shape: Shape, pose: Pose, fractions: list) -> None:
    model = Model("m", (shape,), pose=pose)
    f = np.array(fractions)
    if shape.kind == "box":
        local = f * np.array(shape.size)
    elif shape.kind in ("cylinder", "capsule"):
        local = np.column_stack([f[:, 0] * shape.radius, f[:, 1] * shape.radius, f[:, 2] * shape.length])
    elif shape.kind == "polyline":  # in each fan triangle from the origin, between 1 % and 99 % of the height
        outline = np.array(shape.points)
        a, b = f[:, 0] + 0.5, f[:, 1] + 0.5
        flip = a + b > 1
        a, b = np.where(flip, 1 - a, a), np.where(flip, 1 - b, b)
        z = (f[:, 2] + 0.5) * shape.height
        local = np.vstack([np.column_stack([np.outer(a, outline[k]) + np.outer(b, outline[(k + 1) % len(outline)]),
                                            z]) for k in range(len(outline))])
    else:
        local = f * shape.radius
    placed = pose.compose(shape.pose)
    points = placed.position + local @ placed.rotation.T
    assert np.allclose(World(models=(model,)).distances(points), 0.0, atol=1e-9)


def test_a_robot_driving_on_a_20m_slab_is_at_distance_zero_from_it() -> None:
    slab = Model("asphalt", (Shape("box", size=(20.0, 20.0, 1.43)),), pose=Pose(-8.5, 2.3, 0.165))
    world = World(models=(slab,))
    trajectory = np.column_stack([np.linspace(-17, 1, 50), np.linspace(-7, 12, 50), np.full(50, 0.88)])
    assert world.distances(trajectory).max() == pytest.approx(0.0, abs=1e-3)
    assert world.centroid("asphalt") == pytest.approx([-8.5, 2.3, 0.165])
    low, high = world.bounds("asphalt")
    assert low == pytest.approx([-18.5, -7.7, 0.165 - 0.715]) and high == pytest.approx([1.5, 12.3, 0.88])


def test_bounds_of_rotated_cylinder_are_exact() -> None:
    lying = Model("barrel", (Shape("cylinder", radius=0.3, length=1.0),), pose=Pose(0, 0, 0.3, math.pi / 2, 0, 0))
    low, high = World(models=(lying,)).bounds("barrel")
    assert low == pytest.approx([-0.3, -0.5, 0.0]) and high == pytest.approx([0.3, 0.5, 0.6])
