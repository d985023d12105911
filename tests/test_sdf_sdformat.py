"""pytest-ddenv against libsdformat, the SDF parser Gazebo itself uses (when it is installed).

* Exported worlds load in libsdformat.
* Every file of the SDF corpus (tests/data/sdf/corpus) that libsdformat loads without error is loaded by us,
  or refused with an "unsupported <element>" error; and what we load agrees with libsdformat: the same
  top-level models, static exactly when all their links are static in Gazebo (a model, or any model around it,
  is static), and every box, cylinder, sphere, capsule and mesh collision at the pose libsdformat resolves.
* The lenient-text variants (byte-order mark, CRLF, Latin-1 bytes, ...) load in both.
* Gazebo worlds as shipped (issue 28): a world of Fuel URIs read from a Fuel cache laid out by the test, a bare
  include name, an SDF 1.5 model with a link and a joint of the same name, cones, and a misspelt geometry
  (which libsdformat loads as an empty geometry with a warning, and pytest-ddenv refuses).

`.ci/run` installs Debian's libsdformat-dev when it can; elsewhere these tests are skipped with the reason.
"""

from __future__ import annotations

import math
import os
import shutil
import subprocess
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

from pytest_ddenv import World
from pytest_ddenv.world import geometry
from pytest_ddenv.errors import WorldError
from pytest_ddenv.sdf import MODEL_PATH_VARIABLES, UnsupportedSdfError, load_sdf
from pytest_ddenv.sdf._includes import BUILTIN_GROUND

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT / "tests" / "data" / "sdf"
CORPUS = DATA / "corpus"
MODELS = DATA / "models"
COMPARED_GEOMETRY = ("box", "cylinder", "sphere", "capsule", "mesh")
STATE_MOVES = ("surgical_insertions",)
"""Corpus worlds whose <state> moves models: Gazebo applies it on load, libsdformat alone does not (poses not
compared)."""
STOCK_SUN = """<?xml version="1.0"?><sdf version="1.6"><light type="directional" name="sun">
<pose>0 0 10 0 0 0</pose><direction>-0.5 0.1 -0.9</direction></light></sdf>"""


@pytest.fixture(scope="module")
def stock_models(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Gazebo's stock `sun` and `ground_plane` models (which pytest-ddenv has built in), for libsdformat."""
    folder = tmp_path_factory.mktemp("stock")
    for name, text in (("sun", STOCK_SUN), ("ground_plane", BUILTIN_GROUND)):
        (folder / name).mkdir()
        (folder / name / "model.sdf").write_text(text, encoding="utf-8")
        (folder / name / "model.config").write_text(
            f'<?xml version="1.0"?><model><name>{name}</name><sdf version="1.6">model.sdf</sdf></model>',
            encoding="utf-8")
    return folder


@pytest.fixture(autouse=True)
def no_model_path_from_the_environment(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    for variable in MODEL_PATH_VARIABLES:
        monkeypatch.delenv(variable, raising=False)
    monkeypatch.setenv("GZ_FUEL_CACHE_PATH", str(tmp_path / "empty-fuel-cache"))  # whatever this machine caches


# -- exported worlds --------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["ditch", "rubble", "friction"])
def test_shipped_and_freshly_exported_worlds_load_without_errors(
    sdformat_check: Path, tmp_path: Path, name: str
) -> None:
    world = World.load(ROOT / "worlds" / f"{name}.yaml")
    exported = tmp_path / f"{name}.world"
    world.select(world.names[:3]).save(exported)  # a minimal world as the plugin writes it
    result = subprocess.run(
        [str(sdformat_check), str(ROOT / "worlds" / f"{name}.world"), str(exported)],
        capture_output=True, text=True, check=False,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    assert f"ok, {len(world) + 1} models" in result.stdout  # + the ground plane model
    assert "ok, 4 models" in result.stdout


# -- the corpus -------------------------------------------------------------------------------------------
@dataclass
class SdformatModel:
    """A top-level model as libsdformat loads it."""

    name: str
    links: list[tuple[str, bool, int]] = field(default_factory=list)  # scoped name, static in Gazebo, collisions
    collisions: list[tuple[str, str, np.ndarray]] = field(default_factory=list)  # name, geometry, world pose


@dataclass
class SdformatWorld:
    errors: list[str]
    models: dict[str, SdformatModel]
    console: str


def run_dump(binary: Path, path: Path, stock: Path) -> SdformatWorld:
    environment = {**os.environ, "SDF_PATH": os.pathsep.join([str(MODELS), str(stock)])}
    result = subprocess.run([str(binary), str(path)], capture_output=True, text=True, env=environment, timeout=60,
                            check=False)
    errors: list[str] = []
    models: dict[str, SdformatModel] = {}
    statics: dict[str, bool] = {}
    for line in result.stdout.splitlines():
        kind, _, rest = line.partition(" ")
        if kind == "ERROR":
            errors.append(rest)
        elif kind in ("MODEL", "LINK", "COLLISION"):
            name, *attributes = rest.split(" ")
            values = dict(item.split("=", 1) for item in attributes if "=" in item)
            top = name.split("::")[0]
            if kind == "MODEL":
                parent = name.rsplit("::", 1)[0] if "::" in name else None
                statics[name] = values["static"] == "1" or (parent is not None and statics[parent])
                models.setdefault(top, SdformatModel(top))
            elif kind == "LINK":
                models[top].links.append((name, statics[name.rsplit("::", 1)[0]], int(values["collisions"])))
            else:
                numbers = [float(v) for v in rest.split("pose=")[1].split()]
                models[top].collisions.append((name, values["geometry"], np.array(numbers)))
    return SdformatWorld(errors, models, result.stderr)


CORPUS_DUMPS: dict[Path, SdformatWorld] = {}
"""What libsdformat reads of each corpus file, read once per session (two tests read every file)."""


def corpus_dump(binary: Path, path: Path, stock: Path) -> SdformatWorld:
    if path not in CORPUS_DUMPS:
        CORPUS_DUMPS[path] = run_dump(binary, path, stock)
    return CORPUS_DUMPS[path]


def corpus_files() -> list[Path]:
    """The corpus's files, not the `_surgical_cut_*` files another test (under xdist, at the same time) writes
    beside them for a moment."""
    files = sorted(CORPUS.glob("*.world")) + sorted(CORPUS.glob("*.sdf"))
    return [path for path in files if not path.name.startswith("_")]


def assert_same_pose(ours: np.ndarray, theirs: np.ndarray, what: str) -> None:
    """Two poses [x y z roll pitch yaw] equal to 1e-9 (rotations compared as matrices)."""
    assert np.allclose(ours[:3], theirs[:3], atol=1e-9), f"{what}: position {ours[:3]} != {theirs[:3]}"
    ours_rotation = geometry.rotation_matrix(*ours[3:])
    their_rotation = geometry.rotation_matrix(*theirs[3:])
    assert np.allclose(ours_rotation, their_rotation, atol=1e-9), f"{what}: rotation {ours[3:]} != {theirs[3:]}"


def compare(world: World, theirs: SdformatWorld, path: Path) -> None:
    notes = " ".join(world.notes)
    for name, model in theirs.models.items():
        solid = [static for _, static, count in model.links if count]
        if name not in world:
            geometries = {geometry_kind for _, geometry_kind, _ in model.collisions}
            assert (geometries == {"plane"} and world.ground is not None) or not solid or f"dropped {name}:" in notes, (
                f"{path.name}: libsdformat has model {name!r}, we do not")
            continue
        ours = world.model(name)
        assert ours.static == all(solid), f"{path.name}: {name} static: ours {ours.static}, Gazebo's links {solid}"
        kinds = [kind for _, kind, _ in model.collisions]
        if set(kinds) - set(COMPARED_GEOMETRY) or path.name.endswith(tuple(f"{stem}.world" for stem in STATE_MOVES)):
            continue  # planes, heightmaps and polylines are placed by their own tests; state poses by ours
        placed = [ours.pose.compose(shape.pose) for shape in ours.shapes]
        assert len(placed) == len(model.collisions), f"{path.name}: {name}: {len(placed)} shapes, {kinds}"
        for shape_pose, (collision, _, pose) in zip(placed, model.collisions, strict=True):
            assert_same_pose(np.array(shape_pose.as_list()), pose, f"{path.name}: {collision}")


@pytest.mark.parametrize("path", corpus_files(), ids=lambda path: path.name)
def test_corpus_files_libsdformat_loads_are_loaded_alike(
    sdformat_dump: Path, stock_models: Path, path: Path
) -> None:
    theirs = corpus_dump(sdformat_dump, path, stock_models)
    if theirs.errors and path.name.startswith("bad_"):  # refused by both, on purpose
        with pytest.raises(WorldError):
            load_sdf(path, model_paths=[MODELS])
        return
    if path.name.startswith("misspelt_"):  # libsdformat: a warning and an empty geometry; pytest-ddenv: an error
        assert not theirs.errors and {kind for model in theirs.models.values() for _, kind, _ in model.collisions} == {
            "other"}
        with pytest.raises(WorldError, match="unknown geometry <bx>") as refused:
            load_sdf(path, model_paths=[MODELS])
        assert not isinstance(refused.value, UnsupportedSdfError)
        return
    if theirs.errors:
        pytest.skip(f"libsdformat refuses {path.name}: {theirs.errors[0]}")
    try:
        world = load_sdf(path, model_paths=[MODELS])
    except UnsupportedSdfError as error:
        assert str(error).startswith(f"{error.source}:{error.line}") and f"unsupported <{error.element}>" in str(error)
        world = load_sdf(path, model_paths=[MODELS], skip_unsupported=True)
        assert any(note.startswith("dropped ") and f"<{error.element}>" in note for note in world.notes)
    compare(world, theirs, path)


def test_corpus_holds_what_libsdformat_refuses_only_on_purpose(sdformat_dump: Path, stock_models: Path) -> None:
    refused = {path.name for path in corpus_files() if corpus_dump(sdformat_dump, path, stock_models).errors}
    bad = {path.name for path in corpus_files() if path.name.startswith("bad_")}  # refused by both, on purpose
    assert refused - bad == {"fuel_include.world", "merge_in_world.world", "surgical_fuel.world"}  # no network
    assert bad <= refused


# -- Gazebo worlds as shipped (issue 28) --------------------------------------------------------------------
def test_cones_are_placed_where_libsdformat_places_their_collisions(sdformat_dump: Path, stock_models: Path) -> None:
    """libsdformat 12 predates `<cone>` (libsdformat 14): it loads the world with an empty geometry there, at the
    collision pose it resolves, which is where the cone is."""
    path = CORPUS / "cone.world"
    theirs = run_dump(sdformat_dump, path, stock_models)
    assert not theirs.errors
    world = load_sdf(path)
    for name in ("traffic_cone", "toppled"):
        (collision, kind, pose), = theirs.models[name].collisions
        ours = world.model(name)
        assert kind == "other" and [shape.kind for shape in ours.shapes] == ["cone"]
        assert_same_pose(np.array(ours.pose.compose(ours.shapes[0].pose).as_list()), pose, collision)
    assert (world.model("toppled").shapes[0].radius, world.model("toppled").shapes[0].length) == (1.0, 1.0)


def test_a_world_of_fuel_uris_reads_the_fuel_cache_as_libsdformat_reads_the_cached_models(
    sdformat_dump: Path, stock_models: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The cache is laid out as `gz fuel download` lays it out, in a home folder of the test. libsdformat (which
    does not read the Fuel cache itself: Gazebo's fuel tools give it the folder) loads the same world with each
    Fuel URI replaced by the cached version folder the fuel tools pick, Ground Plane and Sun by the stock ones."""
    home = tmp_path / "home"
    cone = home / ".gz" / "fuel" / "fuel.gazebosim.org" / "openrobotics" / "models" / "construction cone"
    shutil.copytree(MODELS / "static_block", cone / "1")
    shutil.copytree(MODELS / "cone_barrel", cone / "2")
    monkeypatch.setenv("HOME", str(home))
    monkeypatch.delenv("GZ_FUEL_CACHE_PATH")
    original = DATA / "fuel_cache.world"
    world = load_sdf(original)
    assert world.names == ("cone_latest", "cone_first", "cone_tip") and world.ground is not None
    assert [len(world.model(name).shapes) for name in world.names] == [2, 1, 2]  # version 2 (a barrel), 1, tip: 2
    text = original.read_text()
    for fuel, local in (
        ("https://fuel.gazebosim.org/1.0/OpenRobotics/models/Ground Plane", "model://ground_plane"),
        ("https://fuel.gazebosim.org/1.0/OpenRobotics/models/Sun", "model://sun"),
        ("https://fuel.gazebosim.org/1.0/OpenRobotics/models/Construction Cone<", f"{cone / '2'}<"),
        ("https://fuel.gazebosim.org/1.0/OpenRobotics/models/Construction%20Cone/1", str(cone / "1")),
        ("https://fuel.ignitionrobotics.org/1.0/openrobotics/models/construction cone/tip", str(cone / "2")),
    ):
        assert fuel in text
        text = text.replace(fuel, local)
    resolved = tmp_path / "fuel_cache_resolved.world"
    resolved.write_text(text)
    theirs = run_dump(sdformat_dump, resolved, stock_models)
    assert not theirs.errors, theirs.errors
    assert set(theirs.models) == {*world.names, "ground_plane"}
    compare(world, theirs, resolved)


# -- lenient text ------------------------------------------------------------------------------------------
def lenient_variants(tmp_path: Path) -> list[Path]:
    """The lenient-text corpus file with a byte-order mark, CRLF line ends and Latin-1 bytes."""
    text = (CORPUS / "lenient_text.world").read_bytes()
    variants = {
        "bom.world": b"\xef\xbb\xbf" + text,
        "crlf.world": text.replace(b"\n", b"\r\n"),
        "latin1.world": text.replace(b"<name>cafe</name>", "<name>caf\xe9</name>".encode("latin-1")),
        "cr.world": text.replace(b"\n", b"\r"),
    }
    assert b"<name>cafe</name>" in text
    paths = []
    for name, data in variants.items():
        (tmp_path / name).write_bytes(data)
        paths.append(tmp_path / name)
    return paths


def test_lenient_text_variants_load_in_both(sdformat_dump: Path, stock_models: Path, tmp_path: Path) -> None:
    for path in lenient_variants(tmp_path):
        theirs = run_dump(sdformat_dump, path, stock_models)
        assert not theirs.errors, f"{path.name}: {theirs.errors}"
        compare(load_sdf(path, model_paths=[MODELS]), theirs, path)


def test_the_dump_tool_reads_nested_statics(sdformat_dump: Path, stock_models: Path) -> None:
    theirs = run_dump(sdformat_dump, CORPUS / "static_nesting.world", stock_models)
    assert theirs.models["nested_static_3"].links == [("nested_static_3::a::b::c::l", True, 1)]
    assert not math.isnan(float(theirs.models["dynamic_3"].collisions[0][2][0]))


# -- the surgical export ------------------------------------------------------------------------------------
def test_a_surgical_export_loads_in_libsdformat_as_the_minimal_world(
    sdformat_dump: Path, stock_models: Path, tmp_path: Path
) -> None:
    from pytest_ddenv.sdf import cut_models

    original = CORPUS / "surgical.world"
    world = load_sdf(original, model_paths=[MODELS])
    cut = original.with_name("_surgical_cut_for_libsdformat.world")  # beside the original: its paths hold
    cut.write_text(cut_models(original, {"block_right", "crate"}, model_paths=[MODELS]))
    try:
        theirs = run_dump(sdformat_dump, cut, stock_models)
        assert not theirs.errors, theirs.errors
        compare(world.without(["block_right", "crate"]), theirs, cut)
    finally:
        cut.unlink()


SURGICAL_CUTS = [("surgical_insertions.world", {"box_b"}), ("surgical_frames.world", {"crate"}),
                 ("surgical_frames.world", {"crate", "hill"})]
"""The new surgical corpus worlds' cuts (surgical_fuel.world's Fuel include does not load here, cut or not)."""


@pytest.mark.parametrize(("name", "removed"), SURGICAL_CUTS, ids=lambda value: "-".join(sorted(value))
                         if isinstance(value, set) else value)
@pytest.mark.parametrize("with_scenario", [False, True], ids=["as_written", "scenario_given"])
def test_the_surgical_corpus_cuts_load_in_libsdformat_as_the_minimal_world(
    sdformat_dump: Path, stock_models: Path, name: str, removed: set[str], with_scenario: bool
) -> None:
    from pytest_ddenv.sdf._surgical import KEEP, cut_file
    from pytest_ddenv.world import Pose, Scenario

    original = CORPUS / name
    world = load_sdf(original, model_paths=[MODELS])
    scenario = Scenario(start=Pose(x=1.0, y=-2.0), goal=(9.0, 1.0, None)) if with_scenario else KEEP
    cut = original.with_name(f"_surgical_cut_{os.getpid()}_{name}")  # beside the original: its paths hold
    cut.write_bytes(cut_file(original, removed, model_paths=[MODELS], scenario=scenario).data)
    try:
        theirs = run_dump(sdformat_dump, cut, stock_models)
        assert not theirs.errors, theirs.errors
        assert set(theirs.models) == set(world.without(removed).names) | {"ground_plane"} & set(theirs.models)
        compare(load_sdf(cut, model_paths=[MODELS]), theirs, cut)
    finally:
        cut.unlink()


@pytest.mark.slow
def test_the_minimal_sdf_of_a_real_reduction_loads_in_libsdformat(
    sdformat_dump: Path, stock_models: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """`ddenv reduce` of a Gazebo world with a scenario from the command line: minimal.sdf is cut, carries that
    scenario, and (beside the original, as the summary says) loads in libsdformat as the minimal world."""
    import json

    from pytest_ddenv.cli import main as cli

    shutil.copy(DATA / "features.world", tmp_path / "features.world")
    shutil.copytree(DATA / "meshes", tmp_path / "meshes")
    monkeypatch.chdir(tmp_path)
    code = cli.main(["reduce", "features.world", "--model-path", str(MODELS), "--start=-4,5", "--goal", "4,5",
                     "--timeout", "15", "-p", "stuck:window=2", "--workers", "1", "--json", "--quiet", "--out", "art"])
    summary = json.loads(capsys.readouterr().out)
    assert code == 0 and summary["minimal_models"] == ["outer"]
    how = summary["minimal_sdf"]
    assert how == "cut from features.world; its ddenv:scenario written from the reduction's scenario (not the file's)"
    beside = tmp_path / "minimal.sdf"
    shutil.copy(tmp_path / "art" / "minimal.sdf", beside)
    theirs = run_dump(sdformat_dump, beside, stock_models)
    assert not theirs.errors, theirs.errors
    reread = load_sdf(beside, model_paths=[MODELS])
    assert reread.names == ("outer",) and reread.scenario is not None and reread.scenario.goal == (4.0, 5.0, None)
    compare(reread, theirs, beside)


def test_an_export_with_the_new_shapes_loads_in_libsdformat(sdformat_check: Path, tmp_path: Path) -> None:
    shutil.copy(CORPUS / "media" / "hill.png", tmp_path / "hill.png")
    world = World.from_yaml(
        "format: 1\nmodels:\n"
        "  - {name: pill, pose: [1, 0, 0.5], capsule: {radius: 0.2, length: 0.6}, mass: 2}\n"
        "  - {name: ell, pose: [3, 0, 0], polyline: {points: [[0, 0], [2, 0], [2, 0.3], [0.3, 0.3], [0.3, 1], "
        "[0, 1]], height: 0.5}}\n"
        "  - {name: hill, pose: [0, 6, 0], heightmap: {file: hill.png, size: [4, 4, 0.5]}}\n",
        source=str(tmp_path / "shapes.yaml"),
    )
    exported = tmp_path / "shapes.world"
    world.save(exported)
    result = subprocess.run([str(sdformat_check), str(exported)], capture_output=True, text=True, check=False)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "ok, 4 models" in result.stdout  # + the ground plane model
    reread = load_sdf(exported)
    assert [m.shapes[0].kind for m in reread.models] == ["capsule", "polyline", "heightmap"]
    assert reread.models[:2] == world.models[:2]
    assert Path(reread.model("hill").shapes[0].mesh or "") == tmp_path / "hill.png"  # written as an absolute URI
