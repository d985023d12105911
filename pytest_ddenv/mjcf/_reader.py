"""Read a MuJoCo MJCF scene as a `World`: MuJoCo itself parses and compiles it, this module reads the result.

Each direct child `<body>` of `<worldbody>` (with its subtree) is one `Model`, in the file's order: static when
its subtree has no joint, else dynamic (a free joint, or an articulated tree simulated as one rigid body),
with the subtree's mass. Its colliding geoms (`contype` or `conaffinity` not 0) are its shapes, placed at the
scene's initial configuration. The one horizontal plane directly in `<worldbody>` is the world's ground; any
other colliding geom directly in `<worldbody>` is part of one static model `worldbody` that is never removed.
Friction: a model's (and the ground's) `mu` and `mu2` are the sliding friction (the first of MuJoCo's three
coefficients) of its first geom. Everything else MuJoCo simulates and pytest-ddenv does not (actuators,
sensors, tendons, equality constraints, cameras, lights, contact pairs and excludes, keyframes, joints) is
named once per world in `World.notes`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from pytest_ddenv.errors import WorldError, shown
from pytest_ddenv.mjcf._files import SceneFiles
from pytest_ddenv.mjcf._mujoco import mujoco_error, mujoco_module
from pytest_ddenv.mjcf._scenario import SCENARIO_TEXT, parse_scenario
from pytest_ddenv.mjcf._shapes import Frame, GeomReader
from pytest_ddenv.sdf._notes import listing
from pytest_ddenv.world.files import is_file
from pytest_ddenv.world.limits import name_problem
from pytest_ddenv.world.model import Ground, Model, Physics, Scenario, World

WORLD_GEOMS = "worldbody"
"""The model of the colliding geoms written directly in `<worldbody>` (other than the ground plane)."""
NOT_SIMULATED = (  # (mjtObj name, what, why)
    ("mjOBJ_ACTUATOR", "actuators", "the scene's actuators are not driven (the robot comes from the scenario)"),
    ("mjOBJ_SENSOR", "sensors", "sensors in the scene do not run (the robot's come from the scenario)"),
    ("mjOBJ_TENDON", "tendons", "not simulated"),
    ("mjOBJ_EQUALITY", "equality constraints", "not simulated"),
    ("mjOBJ_CAMERA", "cameras", "not used"),
    ("mjOBJ_LIGHT", "lights", "lights do not take part in the simulation"),
    ("mjOBJ_PAIR", "contact pairs", "contacts follow pytest-ddenv's own rules"),
    ("mjOBJ_EXCLUDE", "contact excludes", "contacts follow pytest-ddenv's own rules"),
    ("mjOBJ_KEY", "keyframes", "each model starts at the scene's initial configuration (qpos0)"),
)


class UnsupportedMjcfError(WorldError):
    """A body holds something pytest-ddenv cannot simulate (`skip_unsupported` drops the body instead)."""


def load_mjcf(path: str | Path, *, skip_unsupported: bool = False) -> World:
    """The MJCF scene at `path` as a `World` (see the module docstring); WorldError naming file:line otherwise."""
    return read_scene(Path(path), None, skip_unsupported=skip_unsupported)


def read_scene(path: Path, data: bytes | None, *, skip_unsupported: bool = False) -> World:
    """The scene whose main file is `path`; with `data`, that text read as if it were the file at `path`
    (its includes and assets resolved from `path`'s folder)."""
    scene = SceneFiles.read(path, data)
    mujoco = mujoco_module(path)
    text = next(iter(scene.files.values())).decode("utf-8", errors="replace")
    include = {name: scene.files[file] for file, name in scene.included_as.items()}
    try:  # from the text read here (MuJoCo's from_file reads .xml files only), the folder as the file's
        spec = mujoco.MjSpec.from_string(text, include=include)
        spec.modelfiledir = str(path.parent)
    except ValueError as error:
        raise mujoco_error(error, scene, "cannot read the scene") from None
    _check_asset_files(spec, scene, path)
    try:
        model = spec.compile()
    except ValueError as error:
        raise mujoco_error(error, scene, "cannot compile the scene") from None
    state = mujoco.MjData(model)
    mujoco.mj_kinematics(model, state)
    return _SceneReader(mujoco, spec, model, state, scene, skip_unsupported).world(path)


def _check_asset_files(spec: Any, scene: SceneFiles, path: Path) -> None:
    """Every mesh and height-field file is there (MuJoCo's own error names no file or line)."""
    for kind, assets in (("mesh", spec.meshes), ("hfield", spec.hfields)):
        for asset in assets:
            if not asset.file:
                continue
            found = GeomReader.asset_file(asset.file, spec.meshdir, path.parent)
            if not is_file(found):
                line = _line(asset.info)
                raise WorldError(f"{kind} file not found: {shown(asset.file)} (looked for {found}; MuJoCo reads it "
                                 "from the compiler's meshdir or assetdir, relative to the main file's folder)",
                                 source=scene.where(kind, line), line=line, field=f"{kind}/@file")


def _line(info: str) -> int | None:
    """The line in MuJoCo's `info` of an element ("line 12")."""
    number = info.removeprefix("line ").strip()
    return int(number) if number.isdigit() else None


class _SceneReader:
    def __init__(self, mujoco: Any, spec: Any, model: Any, state: Any, scene: SceneFiles,
                 skip_unsupported: bool) -> None:
        self.mujoco, self.spec, self.model, self.state, self.scene = mujoco, spec, model, state, scene
        self.skip_unsupported = skip_unsupported
        self.dropped: list[str] = []
        self.joints: list[str] = []
        self.geoms = GeomReader(mujoco, model, state, spec, scene.main.parent, self.geom_error)

    def geom_error(self, message: str, geom: int, field: str) -> Exception:
        info = self.spec.geoms[geom].info if geom < len(self.spec.geoms) else ""
        line = _line(info)
        body = int(self.model.body_rootid[self.model.geom_bodyid[geom]])
        name = self.model.body(body).name if body else None
        return UnsupportedMjcfError(message, source=self.scene.where("geom", line), line=line, model=name, field=field)

    def world(self, path: Path) -> World:
        ground, world_geoms = self.world_geoms()
        models: list[Model] = []
        if world_geoms:
            models.append(Model(WORLD_GEOMS, tuple(self.geoms.shape(g, self.origin(0)) for g in world_geoms),
                                keep=True, **self.surface(world_geoms[0])))
        if not self.spec.worldbody.bodies:
            file, line = self.scene.first("worldbody")
            raise WorldError("the scene has no body in <worldbody>: nothing to reduce (each direct child body of "
                             "<worldbody> is a model)", source=file, line=line, field="worldbody")
        for body in self.spec.worldbody.bodies:
            model = self.guarded(body)
            if model is not None:
                if model.name == WORLD_GEOMS and world_geoms:  # MuJoCo refuses two bodies of one name itself
                    raise self.body_error(f"the name {WORLD_GEOMS} is taken by the geoms directly in <worldbody>: "
                                          "rename the body", body, "body/@name")
                models.append(model)
        gx, gy, gz = (float(v) for v in self.model.opt.gravity)
        return World(models=tuple(models), scenario=self.scenario(), name=self.spec.modelname or path.stem,
                     physics=Physics(gravity=(gx, gy, gz), engine="mujoco"), ground=ground,
                     source=str(path), notes=(*self.dropped, *self.notes()))

    def guarded(self, body: Any) -> Model | None:
        """The body's model, or None when it cannot be simulated and such bodies are dropped (with a note)."""
        try:
            return self.body_model(body)
        except UnsupportedMjcfError as error:
            if not self.skip_unsupported:
                raise
            where = f" ({error.source}:{error.line})" if error.line else ""
            self.dropped.append(f"dropped {body.name or '(unnamed body)'}: {error.reason}{where}")
            return None

    def body_error(self, message: str, body: Any, field: str, *, kind: type[WorldError] = WorldError) -> WorldError:
        line = _line(body.info)
        return kind(message, source=self.scene.where("body", line), line=line, model=body.name or None, field=field)

    def origin(self, body: int) -> Frame:
        return Frame(self.state.xmat[body].reshape(3, 3).copy(), self.state.xpos[body].copy())

    def collides(self, geom: int) -> bool:
        return bool(self.model.geom_contype[geom] or self.model.geom_conaffinity[geom])

    def world_geoms(self) -> tuple[Ground | None, list[int]]:
        """The ground (the first horizontal colliding plane directly in `<worldbody>`) and the other colliding
        geoms there."""
        ground: Ground | None = None
        others: list[int] = []
        for geom in range(self.model.ngeom):
            if self.model.geom_bodyid[geom] != 0 or not self.collides(geom):
                continue
            normal = self.state.geom_xmat[geom].reshape(3, 3)[:, 2]
            if ground is None and self.geoms.type_name(geom) == "plane" and np.allclose(normal, (0, 0, 1)):
                surface = self.surface(geom)
                ground = Ground(z=float(self.state.geom_xpos[geom][2]), mu=surface["mu"], mu2=surface["mu2"])
            else:
                others.append(geom)
        return ground, others

    def surface(self, geom: int) -> dict[str, Any]:
        """Friction (MuJoCo's sliding coefficient) and colour (the material's when it has one) of a geom."""
        mu = float(self.model.geom_friction[geom][0])
        material = int(self.model.geom_matid[geom])
        rgba = self.model.mat_rgba[material] if material >= 0 else self.model.geom_rgba[geom]
        return {"mu": mu, "mu2": mu, "color": tuple(float(v) for v in rgba)}

    def body_model(self, body: Any) -> Model:
        name = body.name
        if not name:
            raise self.body_error("a top-level body needs a name: pytest-ddenv names each model by it", body,
                                  "body/@name")
        problem = name_problem(name)
        if problem is not None:
            raise self.body_error(f"{problem}; got {shown(name)}", body, "body/@name")
        index = int(self.model.body(name).id)
        subtree = {b for b in range(self.model.nbody) if int(self.model.body_rootid[b]) == index}
        in_subtree = [g for g in range(self.model.ngeom) if int(self.model.geom_bodyid[g]) in subtree]
        geoms = [g for g in in_subtree if self.collides(g)]
        if not geoms:
            why = "no geom" if not in_subtree else "no geom that collides (all have contype and conaffinity 0)"
            raise self.body_error(f"the body has {why}: nothing the robot can touch", body, "body/geom",
                                  kind=UnsupportedMjcfError)
        joints = [j for j in range(self.model.njnt) if int(self.model.jnt_bodyid[j]) in subtree]
        hinged = [j for j in joints if int(self.model.jnt_type[j]) != self.mujoco.mjtJoint.mjJNT_FREE]
        if hinged:
            self.joints.append(f"{name} ({len(hinged)} joint{'s' if len(hinged) != 1 else ''})")
        origin = self.origin(index)
        shapes = tuple(self.geoms.shape(g, origin) for g in geoms)
        mass = float(self.model.body_subtreemass[index]) if joints else None
        return Model(name, shapes, pose=origin.pose(), mass=mass, static=not joints, **self.surface(geoms[0]))

    def scenario(self) -> Scenario | None:
        texts = [text for text in self.spec.texts if text.name == SCENARIO_TEXT]
        if not texts:
            return None
        line = _line(texts[0].info)
        return parse_scenario(texts[0].data, self.scene.where("text", line), line)

    def notes(self) -> list[str]:
        """One line per kind of element that is not simulated, naming them."""
        lines = []
        if self.joints:
            lines.append(f"joints: {listing(self.joints)}; each articulated body tree is simulated as one rigid body")
        counts = {"mjOBJ_ACTUATOR": self.model.nu, "mjOBJ_SENSOR": self.model.nsensor,
                  "mjOBJ_TENDON": self.model.ntendon, "mjOBJ_EQUALITY": self.model.neq,
                  "mjOBJ_CAMERA": self.model.ncam, "mjOBJ_LIGHT": self.model.nlight,
                  "mjOBJ_PAIR": self.model.npair, "mjOBJ_EXCLUDE": self.model.nexclude,
                  "mjOBJ_KEY": self.model.nkey}
        for kind, what, why in NOT_SIMULATED:
            names = [self.mujoco.mj_id2name(self.model, getattr(self.mujoco.mjtObj, kind), i) or f"#{i}"
                     for i in range(int(counts[kind]))]
            if names:
                lines.append(f"{what}: {listing(names)}; {why}")
        visual = sum(1 for g in range(self.model.ngeom) if not self.collides(g))
        if visual:
            lines.append(f"visual geoms: {visual} (contype and conaffinity 0); nothing collides with them")
        return lines
