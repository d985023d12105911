"""A wheeled robot's URDF measured where pybullet is not installed: compiled by MuJoCo (which reads URDF), posed
at the origin, and measured as `urdf_geometry` measures it in pybullet: the collision shapes' bounds, each
wheel's collision shape, the wheels' lateral positions, the mass and the base's centre of mass.

MuJoCo's URDF reader refuses xacro leftovers such as `$(optenv NAME default)` (each becomes its default), and
a `<mujoco><compiler .../></mujoco>` element keeps every link a body of its own (`fusestatic` off), drops the
visual shapes and finds collision meshes beside the URDF.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pytest_ddenv.errors import ScenarioError


@dataclass(frozen=True)
class UrdfBounds:
    """What the URDF's collision shapes measure, the robot at the origin: `low`/`high` the bounds (m), one
    radius per wheel, the mean lateral position of the left and right wheels' centres, the total mass (a link
    without `<inertial>` weighs what MuJoCo gives it, pybullet 1 kg) and the base's centre of mass."""

    low: tuple[float, float, float]
    high: tuple[float, float, float]
    wheel_radii: tuple[float, ...]
    left_y: float
    right_y: float
    mass: float
    base: tuple[float, float, float]


def measure_in_mujoco(urdf: str, left: tuple[str, ...], right: tuple[str, ...], *,
                      source: str | None = None) -> UrdfBounds:
    """`urdf` compiled by MuJoCo and measured; ScenarioError naming the world file `source` and the field when
    MuJoCo cannot read it or a wheel has no collision shape."""
    import mujoco

    try:
        model = mujoco.MjModel.from_xml_string(mujoco_readable_urdf(urdf))
    except (ValueError, OSError) as error:
        raise ScenarioError(f"MuJoCo cannot load the URDF {urdf}: {error}", source=source,
                            field="scenario.robot.urdf") from None
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    lows, highs = _geom_bounds(model, data)
    bodies = np.arange(1, model.nbody)
    wheels = {side: [int(model.jnt_bodyid[model.joint(name).id]) for name in names]
              for side, names in (("left_wheels", left), ("right_wheels", right))}
    radii = [_wheel_radius(model, body, lows, highs, side, urdf, source)
             for side, side_bodies in wheels.items() for body in side_bodies]

    def mean_y(side_bodies: list[int]) -> float:
        centres = [(lows[model.geom_bodyid == body, 1].min() + highs[model.geom_bodyid == body, 1].max()) / 2.0
                   for body in side_bodies]
        return float(sum(centres) / len(centres))

    return UrdfBounds(
        low=(float(lows[:, 0].min()), float(lows[:, 1].min()), float(lows[:, 2].min())),
        high=(float(highs[:, 0].max()), float(highs[:, 1].max()), float(highs[:, 2].max())),
        wheel_radii=tuple(radii), left_y=mean_y(wheels["left_wheels"]), right_y=mean_y(wheels["right_wheels"]),
        mass=float(model.body_mass[bodies].sum()),
        base=_base_centre_of_mass(model, data),
    )


def _base_centre_of_mass(model: object, data: object) -> tuple[float, float, float]:
    """The centre of mass of the root link and the links fixed to it (pybullet's base, its fixed links merged)."""
    merged = [False] * model.nbody  # type: ignore[attr-defined]
    for body in range(1, model.nbody):  # type: ignore[attr-defined]  # a parent comes before its children
        parent = int(model.body_parentid[body])  # type: ignore[attr-defined]
        merged[body] = int(model.body_jntnum[body]) == 0 and (parent == 0 or merged[parent])  # type: ignore[attr-defined]
    bodies = np.flatnonzero(merged)
    masses = np.asarray(model.body_mass)[bodies]  # type: ignore[attr-defined]
    positions = np.asarray(data.xipos)[bodies]  # type: ignore[attr-defined]
    centre = masses @ positions / masses.sum() if masses.sum() > 0 else positions[0]
    return float(centre[0]), float(centre[1]), float(centre[2])


def mujoco_readable_urdf(urdf: str) -> str:
    """The URDF's text as MuJoCo can read it: each xacro leftover `$(optenv NAME default)` (the Husky's IMU pose)
    becomes `default`, and a `<mujoco><compiler .../></mujoco>` element keeps MuJoCo from welding the root to the
    world (`fusestatic` off), drops the visual meshes (`discardvisual`) and finds meshes beside the URDF. Also
    what `sim/mujoco/robot_spec.py` compiles."""
    text = Path(urdf).read_text(encoding="utf-8")
    text = re.sub(r"\$\(optenv\s+\S+\s+([^)]*)\)", r"\1", text)
    folder = str(Path(urdf).resolve().parent).replace('"', "&quot;")
    compiler = (f'<mujoco><compiler discardvisual="true" fusestatic="false" strippath="false" '
                f'meshdir="{folder}"/></mujoco>')
    return re.sub(r"(<robot\b[^>]*>)", lambda match: match.group(1) + compiler, text, count=1)


def _geom_bounds(model: object, data: object) -> tuple[np.ndarray, np.ndarray]:
    """Each geom's bounds in the world frame (low, high: one row per geom), from MuJoCo's own box around it."""
    centre = np.asarray(model.geom_aabb[:, :3])  # type: ignore[attr-defined]
    half = np.asarray(model.geom_aabb[:, 3:])  # type: ignore[attr-defined]
    rotations = np.asarray(data.geom_xmat).reshape(-1, 3, 3)  # type: ignore[attr-defined]
    middle = np.asarray(data.geom_xpos) + np.einsum("gij,gj->gi", rotations, centre)  # type: ignore[attr-defined]
    reach = np.einsum("gij,gj->gi", np.abs(rotations), half)
    return middle - reach, middle + reach


def _wheel_radius(model: object, body: int, lows: np.ndarray, highs: np.ndarray, side: str, urdf: str,
                  source: str | None) -> float:
    """From the wheel body's first collision shape: a cylinder's, capsule's or sphere's radius, else half the
    body's height."""
    import mujoco

    geoms = np.flatnonzero(model.geom_bodyid == body)  # type: ignore[attr-defined]
    if geoms.size == 0:
        link = model.body(body).name  # type: ignore[attr-defined]
        joint = model.joint(int(model.body_jntadr[body])).name  # type: ignore[attr-defined]
        raise ScenarioError(f"{urdf}: the link {link!r} of wheel joint {joint!r} has no collision shape, so it "
                            "cannot touch the ground; give it a <collision> or name the joint of a wheel that "
                            "has one", source=source, field=f"scenario.robot.{side}")
    first = int(geoms[0])
    if int(model.geom_type[first]) in (mujoco.mjtGeom.mjGEOM_CYLINDER, mujoco.mjtGeom.mjGEOM_CAPSULE,  # type: ignore[attr-defined]
                                       mujoco.mjtGeom.mjGEOM_SPHERE):
        return float(model.geom_size[first][0])  # type: ignore[attr-defined]
    return float(highs[geoms, 2].max() - lows[geoms, 2].min()) / 2.0
