"""Every code example in docs/*.md runs, so the docs cannot rot (issue 9).

How a fenced block in a page is treated:

* ```python: executed with `exec` in a fresh namespace, in a temporary folder that holds the repository's
  `worlds/` (a copy) and the small files the page's table entry below creates. `PAGES[page].checks` can
  assert on the namespace a block leaves behind.
* ```console (commands after `$ `, the rest is their output) and ```shell / ```bash / ```sh (every line a
  command): executable when every command is `ddenv ...`, `pytest ...` or `echo $?`. `ddenv` runs
  in-process through `pytest_ddenv.cli.main`; `pytest` through `pytester.runpytest_subprocess`. The
  exit code must be the documented one: the output of a following `$ echo $?`, else 2 when the shown output
  has a `ddenv: error:` line, 1 when it has a `: FAILED (` line, 0 otherwise. The shown output lines must
  appear, in order, in what the command printed (stderr, then stdout); timings (`1.04 s wall`, `00:06`,
  `errors; 10.0 s`, pytest's `in 0.12s`) may differ, and a `...` line stands for omitted output.
* ```text (output, pseudo-code), ```yaml and ```ini: not executed; YAML and ini blocks must parse.
* A block right after `<!-- not executed: REASON -->` is not executed (commands that install or need a
  cluster, partial signatures); one after `<!-- checked by tests/FILE.py::TEST -->` is run by that test,
  which must exist.

Any other block (no language, an unknown language, or a console block running something else without a
marker) fails `test_every_code_block_is_executed_or_marked`.

docs/benchmarks.md is not covered here.
"""

from __future__ import annotations

import ast
import configparser
import os
import re
import shlex
import shutil
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from engines import NOT_INSTALLED, installed

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
NOT_COVERED = {"benchmarks.md"}  # maintained separately

PYTHON = {"python", "py"}
SHELL = {"console", "shell", "bash", "sh"}
INERT = {"text", "yaml", "ini"}
COMMANDS = {"ddenv", "pytest"}

FENCE = re.compile(r"^(?P<indent> {0,3})(?P<fence>`{3,}|~{3,})\s*(?P<lang>[^\s`]*)[^`]*$")
MARKER = re.compile(r"^\s*<!--\s*(?P<kind>not executed|checked by)\s*:?\s*(?P<what>.*?)\s*-->\s*$")
PROMPT = re.compile(r"^(?:[\w.-]*)\$ (?P<command>.*)$")
# Parts of the output that change from run to run: wall times and elapsed clocks (ddenv and pytest).
VOLATILE = re.compile(r"\d+(?:\.\d+)? s wall|\b\d\d:\d\d\b|errors; \d+(?:\.\d+)? s|\bin \d+(?:\.\d+)?s\b")


@dataclass(frozen=True)
class Page:
    """What a page's examples need: files to create in the working folder, checks after python blocks."""

    files: dict[str, str] = field(default_factory=dict)
    """Relative path -> text ("" for the tiny world below); a path ending in "/" is a folder; "~/..." is in a
    temporary home folder (HOME is set to it for that page only)."""
    checks: dict[str, tuple[str, ...]] = field(default_factory=dict)
    """A snippet of a python block -> expressions that must be true in that block's namespace afterwards."""
    slow: bool = False
    """Real simulations of the shipped (not tiny) worlds."""
    engine: str = ""
    """The physics engine whose outputs the page shows (its worlds name none): skipped where it is not installed."""


MODEL_SDF = """\
<?xml version="1.0"?>
<sdf version="1.6">
  <model name="crate">
    <static>true</static>
    <link name="body">
      <collision name="box"><geometry><box><size>0.6 0.6 0.6</size></box></geometry></collision>
    </link>
  </model>
</sdf>
"""

ARENA_WORLD = """\
<?xml version="1.0"?>
<sdf version="1.6">
  <world name="arena">
    <include><uri>model://ground_plane</uri></include>
    <include><uri>model://crate</uri><name>crate_1</name><pose>3 2 0.3 0 0 0</pose></include>
    <include><uri>model://crate</uri><name>crate_2</name><pose>3 -2 0.3 0 0 0</pose></include>
    <include><uri>model://crate</uri><name>crate_3</name><pose>6 0 0.3 0 0 0</pose></include>
  </world>
</sdf>
"""

YARD_WORLD = """\
<?xml version="1.0"?>
<sdf version="1.7">
  <world name="yard">
    <include><uri>model://sun</uri></include>
    <include><uri>model://ground_plane</uri></include>
    <plugin filename="libgazebo_ros_state.so" name="state"/>
    <model name="wall"><static>true</static><pose>2 0 0.5 0 0 0</pose>
      <link name="l"><collision name="c"><geometry><box><size>0.3 4 1</size></box></geometry></collision></link>
    </model>
    <model name="crate"><static>true</static><pose>-3 3 0.25 0 0 0</pose>
      <link name="l"><collision name="c"><geometry><box><size>0.5 0.5 0.5</size></box></geometry></collision></link>
    </model>
  </world>
</sdf>
"""

PAGES: dict[str, Page] = {
    "algorithm.md": Page(
        checks={"result = reduce(": (
            "result.minimal == ('asphalt_plane', 'asphalt_plane_clone')",
            "result.one_minimal",
            "result.failure_rate == (5, 5)",
            "result.rate_check.decision == 'holds'",
            "Path('ddenv-artifacts/ditch/runs.jsonl').is_file()",
        ), "log = ProbeLog.load(": (
            "len(probes) == len(log.probes('reduce')) > 0",
            "adopted[-1] == ('asphalt_plane', 'asphalt_plane_clone')",
        )},
        slow=True,
    ),
    "cli.md": Page(
        engine="pybullet",
        files={
            "docs/images/": "",
            # the user module the page shows (its block is marked "not executed": `ddenv --import` imports it)
            "lab_control.py": re.search(r'```python\n("""Our robot\'s software.*?)```',
                                        (DOCS / "cli.md").read_text(encoding="utf-8"), flags=re.DOTALL)[1],
            "yard.world": YARD_WORLD,
            "rover.yaml": re.search(r"```yaml\n(format: 1\nscenario:\n  robot: \{urdf: robots/diffbot.*?)```",
                                    (DOCS / "cli.md").read_text(encoding="utf-8"), flags=re.DOTALL)[1],
            "robots/diffbot.urdf": (ROOT / "examples" / "robots" / "diffbot.urdf").read_text(encoding="utf-8"),
        },
        checks={"summary.json": (
            "recorded == (['lab_control'], 'lab_control:Avoider', [{'name': 'trapped', 'params': {'seconds': 15}}])",
            "summary['minimal_models'] == ['back_wall', 'left_wall', 'right_wall']",
            # the last checks also forget what lab_control registered (as a new process would)
            "__import__('pytest_ddenv.oracle', fromlist=['PREDICATES']).PREDICATES.pop('trapped').__module__"
            " == 'lab_control'",
            "__import__('sys').modules.pop('lab_control').__name__ == 'lab_control'",
        )},
        slow=True,
    ),
    "mjcf.md": Page(
        files={"scene.xml": (ROOT / "tests/data/mjcf/wall_in_the_way.xml").read_text(),
               "not_simulated.xml": (ROOT / "tests/data/mjcf/not_simulated.xml").read_text()},
        checks={"load_mjcf(": (
            "world.names == ('crate_left', 'wall', 'crate_right', 'post')",
            "world.physics.engine == 'mujoco'",
        )},
    ),
    "oracle.md": Page(checks={
        "class TooFast": (
            "simulate(World.load('worlds/tiny.yaml'), predicates=[TooFast()], timeout=1.0).failure is None",
            "isinstance(strict, TooFast) and strict.limit == 1.0",
            # the last check also forgets the registration (as a new process would)
            "__import__('pytest_ddenv.oracle', fromlist=['PREDICATES']).PREDICATES.pop('too_fast') is TooFast",
        ),
        "def tipped": (
            "tipped.name == 'tipped'",
            "simulate(World.load('worlds/tiny.yaml'), predicates=[tipped], timeout=1.0).failure is None",
        ),
    }, files={"worlds/tiny.yaml": ""}),
    "pictures.md": Page(checks={"render.plot_world": ("Path('ditch.png').stat().st_size > 10_000",)}),
    "scaling.md": Page(checks={"LocalPool(": (
        "result.error.signature.predicate == 'stuck'",
        "pool.stats.probes == 1",
    )}, slow=True),
    "architecture.md": Page(),
    "sdf.md": Page(
        files={"~/my_models/crate/model.sdf": MODEL_SDF, "arena.world": ARENA_WORLD,
               "not_simulated.world": (ROOT / "tests/data/sdf/corpus/not_simulated.world").read_text()},
        checks={"load_sdf(": (
            "world.names == ('crate_1', 'crate_2', 'crate_3')",
            "load_sdf('minimal.world').names == ('crate_1', 'crate_2')",
        )},
    ),
    "simulation.md": Page(checks={
        "sim.run(": ("run.failure.predicate == 'stuck'", "run2.seed == 3", "slow.seed == 3 and slow.sim_time <= 20",
                     "slow.robot == 'husky' and slow.footprint == (0.99, 0.67) and slow.wheel_contacts.shape[1] == 4"),
        "(0.5, 0.0)": ("message.startswith('controller <lambda> returned tuple (0.5, 0.0) at t = 0.00 s')",),
        "sim.start(": ("episode.finished and manual.sim_time == 10.0 and manual.seed == 3",
                       "len(observation.wheel_speeds) == 4"),
        "RobotDescription(": ("round(measured.wheel_radius, 3) == 0.178 and round(measured.track, 3) == 0.571",
                              "tuple(round(v, 2) for v in measured.footprint) == (1.01, 0.69)",
                              "ROBOTS['measured_husky']().name == 'husky'"),
        "register_robot(\"rover\"": ("ROBOTS['rover'] is MyRover", "MyRover().mass == 20.0",
                                    "not MyRover().has_laser or MyRover().laser.min_range == 0.5"),
    }, slow=True),
    "world-format.md": Page(
        files={"far.yaml": "format: 1\nmodels:\n  - {name: crate, pose: [1e20, 0, 0], box: [1, 1, 1]}\n"},
        checks={"world.distances(": (
            "world.distances(points).shape == (len(points), len(world))",
            "'cinder_block' not in World.load('minimal.yaml')",
        )}),
}

# A tiny world for checks that simulate: a bare ground, the goal 2 m ahead.
TINY_WORLD = """\
format: 1
name: tiny
scenario:
  start: {x: 0.0, y: 0.0, yaw: 0.0}
  goal: {x: 2.0, y: 0.0}
  timeout: 5
models:
  - {name: far_box, pose: [-4, 4, 0.25], box: [0.5, 0.5, 0.5]}
"""


# -- reading the pages ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Block:
    page: str
    line: int
    """1-based line of the first line of code (after the opening fence)."""
    lang: str
    code: str
    marker: tuple[str, str] | None
    """("not executed", reason) or ("checked by", "tests/FILE.py::TEST")."""

    @property
    def where(self) -> str:
        return f"docs/{self.page}:{self.line - 1}"


def read_blocks(page: str, text: str | None = None) -> list[Block]:
    lines = (DOCS / page).read_text(encoding="utf-8").splitlines() if text is None else text.splitlines()
    blocks: list[Block] = []
    index = 0
    while index < len(lines):
        opening = FENCE.match(lines[index])
        if not opening:
            index += 1
            continue
        fence = opening["fence"]
        end = index + 1
        while end < len(lines) and not re.match(rf"^ {{0,3}}{fence[0]}{{{len(fence)},}}\s*$", lines[end]):
            end += 1
        previous = next((lines[i] for i in range(index - 1, -1, -1) if lines[i].strip()), "")
        marker = MARKER.match(previous)
        blocks.append(Block(
            page=page,
            line=index + 2,
            lang=opening["lang"].lower(),
            code="\n".join(lines[index + 1:end]) + "\n",
            marker=(marker["kind"], marker["what"]) if marker else None,
        ))
        index = end + 1
    return blocks


def pages() -> list[str]:
    return sorted(p.name for p in DOCS.glob("*.md") if p.name not in NOT_COVERED)


@dataclass
class Command:
    argv: list[str]
    text: str
    output: list[str] = field(default_factory=list)
    exit_code: int | None = None
    """From a following `echo $?`."""

    @property
    def expected_exit_code(self) -> int:
        if self.exit_code is not None:
            return self.exit_code
        if any(line.startswith("ddenv: error:") for line in self.output):
            return 2
        if any(": FAILED (" in line for line in self.output):
            return 1
        return 0


def commands_of(block: Block) -> list[Command]:
    """The commands of a shell block with the output shown under each (console blocks only)."""
    commands: list[Command] = []
    pending = ""
    for raw in block.code.splitlines():
        if block.lang == "console":
            prompt = PROMPT.match(raw)
            if prompt is None and not pending:
                if commands and raw.strip():
                    commands[-1].output.append(raw)
                continue
            line = raw if pending else prompt["command"]  # type: ignore[index]
        else:
            line = raw
            if not line.strip() or line.lstrip().startswith("#"):
                continue
        if line.rstrip().endswith("\\"):
            pending += line.rstrip()[:-1] + " "
            continue
        text, pending = (pending + line).strip(), ""
        commands.append(Command(shlex.split(text, comments=True), text))
    # fold `echo $?` into the command before it
    folded: list[Command] = []
    for command in commands:
        if command.argv == ["echo", "$?"] and folded:
            code = command.output[0].strip() if command.output else ""
            if not code.isdigit():
                raise AssertionError(f"{block.where}: `echo $?` must be followed by the exit code, got {code!r}")
            folded[-1].exit_code = int(code)
        else:
            folded.append(command)
    return folded


def runnable(command: Command) -> bool:
    return bool(command.argv) and command.argv[0] in COMMANDS and not any(
        token in ("&&", "||", "|", ";", ">", "<") for token in command.argv
    )


def plan(block: Block) -> str:
    """"python", "shell", "marked" or "inert"; AssertionError naming the block when it is neither."""
    if block.marker is not None:
        kind, what = block.marker
        if not what:
            raise AssertionError(f"{block.where}: `<!-- {kind}: ... -->` needs a reason or a test")
        if kind == "checked by":
            path, _, test = what.partition("::")
            file = ROOT / path
            if not (file.is_file() and re.search(rf"^def {re.escape(test)}\(", file.read_text(), flags=re.MULTILINE)):
                raise AssertionError(f"{block.where}: marked as checked by {what}, which does not exist")
        return "marked"
    if block.lang in PYTHON:
        return "python"
    if block.lang in SHELL:
        commands = commands_of(block)
        if not commands:
            raise AssertionError(f"{block.where}: a ```{block.lang} block without commands; use ```text for output")
        strangers = [c.text for c in commands if not runnable(c)]
        if strangers:
            raise AssertionError(
                f"{block.where}: runs {strangers[0]!r}, which this test cannot execute; only `ddenv`/`pytest` "
                "commands are run. Mark the block with `<!-- not executed: REASON -->` on the line before it."
            )
        return "shell"
    if block.lang in INERT:
        return "inert"
    if not block.lang:
        raise AssertionError(
            f"{block.where}: a fence without a language. Use ```text for output or pseudo-code, ```console "
            "for `$ ddenv ...` / `$ pytest ...` sessions, ```python for code (all executed by "
            "tests/test_docs_run.py), or put `<!-- not executed: REASON -->` on the line before it."
        )
    raise AssertionError(f"{block.where}: unknown block language {block.lang!r} (see tests/test_docs_run.py)")


# -- the tests --------------------------------------------------------------------------------------------
def test_every_code_block_is_executed_or_marked() -> None:
    problems = []
    for page in pages():
        for block in read_blocks(page):
            try:
                kind = plan(block)
            except AssertionError as error:
                problems.append(str(error))
                continue
            if kind == "inert" and block.lang == "yaml":
                import yaml

                yaml.safe_load(block.code)
            elif kind == "inert" and block.lang == "ini":
                configparser.ConfigParser().read_string(block.code)
    assert not problems, "\n".join(problems)


def test_the_page_table_names_existing_pages() -> None:
    assert set(PAGES) <= set(pages()), set(PAGES) - set(pages())


def test_unmarked_blocks_are_refused() -> None:
    page = (
        "```\n$ ddenv check worlds/ditch.yaml\n```\n\n"
        "```console\n$ pip install pytest-ddenv\n```\n\n"
        "```rust\nfn main() {}\n```\n\n"
        "<!-- not executed: needs a cluster -->\n```console\n$ dask scheduler\n```\n\n"
        "<!-- checked by tests/test_docs_examples.py::test_no_such_test -->\n```python\npass\n```\n\n"
        "```console\n$ ddenv check worlds/ditch.yaml\nworlds/ditch.yaml: 43 models\n$ echo $?\n0\n```\n"
    )
    outcomes = []
    for block in read_blocks("synthetic.md", page):
        try:
            outcomes.append(plan(block))
        except AssertionError as error:
            outcomes.append(str(error))
    expected = [
        "docs/synthetic.md:1: a fence without a language",
        "docs/synthetic.md:5: runs 'pip install pytest-ddenv', which this test cannot execute",
        "docs/synthetic.md:9: unknown block language 'rust'",
        "marked",
        "docs/synthetic.md:19: marked as checked by tests/test_docs_examples.py::test_no_such_test, which does",
        "shell",
    ]
    assert len(outcomes) == len(expected)
    for outcome, start in zip(outcomes, expected, strict=True):
        assert outcome.startswith(start), (outcome, start)


def test_reference_signatures_match_the_code() -> None:
    """Signature blocks (`name(args) -> Type`) marked as checked by this test match the real functions."""
    import importlib
    import inspect

    targets = {"reduce": "pytest_ddenv.reduce", "ReductionSettings": "pytest_ddenv.reduce"}
    checked = 0
    for page in pages():
        for block in read_blocks(page):
            if block.marker != ("checked by", f"tests/test_docs_run.py::{test_reference_signatures_match_the_code.__name__}"):
                continue
            documented = ast.parse(f"def {block.code.strip()}: ...").body[0]
            assert isinstance(documented, ast.FunctionDef)
            target = getattr(importlib.import_module(targets[documented.name]), documented.name)
            real = inspect.signature(target)
            arguments = documented.args
            positional = [a.arg for a in arguments.posonlyargs + arguments.args]
            keyword = [a.arg for a in arguments.kwonlyargs]
            kinds = {name: p.kind for name, p in real.parameters.items()}
            assert positional + keyword == list(real.parameters), f"{block.where}: parameters differ from {real}"
            assert all(kinds[name] is inspect.Parameter.KEYWORD_ONLY for name in keyword), block.where
            defaults = dict(zip(positional[len(positional) - len(arguments.defaults):], arguments.defaults))
            defaults |= {a.arg: d for a, d in zip(arguments.kwonlyargs, arguments.kw_defaults) if d is not None}
            for name, default in defaults.items():
                assert ast.literal_eval(default) == real.parameters[name].default, (
                    f"{block.where}: {name}={ast.unparse(default)}, the code says {real.parameters[name].default!r}")
            assert set(defaults) == {n for n, p in real.parameters.items() if p.default is not p.empty}, block.where
            returns = target.__name__ if inspect.isclass(target) else real.return_annotation
            assert documented.returns is not None and ast.unparse(documented.returns) == getattr(
                returns, "__name__", returns), f"{block.where}: returns {returns}"
            checked += 1
    assert checked, "no signature block is marked as checked by this test"


@pytest.fixture
def workdir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """A folder with a copy of the repository's worlds/, as the current directory; custom robots undone."""
    from pytest_ddenv.sim import ROBOTS

    shutil.copytree(ROOT / "worlds", tmp_path / "worlds")
    monkeypatch.chdir(tmp_path)
    robots = dict(ROBOTS)
    yield tmp_path
    ROBOTS.clear()
    ROBOTS.update(robots)


def _page_params() -> list:
    return [
        pytest.param(page, marks=[pytest.mark.slow] if PAGES.get(page, Page()).slow else [], id=page)
        for page in pages()
    ]


@pytest.mark.parametrize("page", _page_params())
def test_page_examples_run(page: str, workdir: Path, request: pytest.FixtureRequest,
                           capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    spec = PAGES.get(page, Page())
    if spec.engine and not installed(spec.engine):
        pytest.skip(f"docs/{page} shows what {spec.engine} simulates: {NOT_INSTALLED[spec.engine]}")
    run_page(page, spec, workdir, request, capsys, monkeypatch)


def run_page(page: str, spec: Page, workdir: Path, request: pytest.FixtureRequest,
             capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, text: str | None = None) -> None:
    """Create the page's files in `workdir` (the current folder), then run its blocks in order."""
    for relative, content in spec.files.items():
        target = workdir / relative
        if relative.startswith("~/"):
            monkeypatch.setenv("HOME", str(workdir / "home"))
            target = workdir / "home" / relative[2:]
        if relative.endswith("/"):
            target.mkdir(parents=True, exist_ok=True)
        else:
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_text(content or TINY_WORLD, encoding="utf-8")
    used: set[str] = set()
    for block in read_blocks(page, text):
        kind = plan(block)
        if kind == "python":
            run_python(block, spec, used)
        elif kind == "shell":
            for command in commands_of(block):
                run_command(block, command, request, capsys)
    unused = set(spec.checks) - used
    assert not unused, f"docs/{page}: no python block contains {sorted(unused)} (update PAGES in this test)"


def test_the_harness_compares_output_and_exit_codes(workdir: Path, request: pytest.FixtureRequest,
                                                    capsys: pytest.CaptureFixture[str],
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """A synthetic page: shown output must be printed, exit codes must match, `pytest` runs in a subprocess."""
    good = (
        "```console\n$ ddenv check worlds/tiny.yaml\nworlds/tiny.yaml: 1 model (1 reducible)\n"
        "$ ddenv check worlds/nothing.yaml\nddenv: error: worlds/nothing.yaml: no such world file\n```\n\n"
        "```python\nfrom pytest_ddenv import World\n\nworld = World.load('worlds/tiny.yaml')\n```\n\n"
        "```console\n$ pytest -q test_tiny.py\n...\n1 passed in 0.01s\n$ echo $?\n0\n```\n"
    )
    spec = Page(files={"worlds/tiny.yaml": "", "test_tiny.py": "def test_tiny():\n    assert True\n"},
                checks={"World.load": ("world.names == ('far_box',)",)})
    run_page("synthetic.md", spec, workdir, request, capsys, monkeypatch, good)
    wrong_output = "```console\n$ ddenv check worlds/tiny.yaml\nworlds/tiny.yaml: 2 models (2 reducible)\n```\n"
    with pytest.raises(AssertionError, match="the page shows the line"):
        run_page("synthetic.md", spec, workdir, request, capsys, monkeypatch, wrong_output)
    wrong_code = "```console\n$ ddenv check worlds/tiny.yaml\n$ echo $?\n1\n```\n"
    with pytest.raises(AssertionError, match="exited with 0, the page says 1"):
        run_page("synthetic.md", spec, workdir, request, capsys, monkeypatch, wrong_code)
    wrong_check = "```python\nfrom pytest_ddenv import World\nworld = World.load('worlds/ditch.yaml')\n```\n"
    with pytest.raises(AssertionError, match="world.names == .'far_box',. is false"):
        run_page("synthetic.md", spec, workdir, request, capsys, monkeypatch, wrong_check)


def run_python(block: Block, spec: Page, used: set[str]) -> None:
    tree = ast.parse("\n" * (block.line - 1) + block.code, filename=f"docs/{block.page}")  # the page's lines
    namespace: dict[str, object] = {"__name__": f"docs_{Path(block.page).stem.replace('-', '_')}"}
    exec(compile(tree, f"docs/{block.page}", "exec"), namespace)  # noqa: S102 - the docs' own examples
    for snippet, expressions in spec.checks.items():
        if snippet not in block.code:
            continue
        used.add(snippet)
        scope = {**_check_globals(), **namespace}
        for expression in expressions:
            assert eval(expression, scope), f"{block.where}: after the example, {expression} is false"


def _check_globals() -> dict[str, object]:
    from pytest_ddenv.sdf import load_sdf
    from pytest_ddenv.sim import ROBOTS, simulate
    from pytest_ddenv.world import World

    return {"Path": Path, "World": World, "load_sdf": load_sdf, "simulate": simulate, "ROBOTS": ROBOTS}


def run_command(block: Block, command: Command, request: pytest.FixtureRequest,
                capsys: pytest.CaptureFixture[str]) -> None:
    where = f"{block.where}: `{command.text}`"
    if command.argv[0] == "ddenv":
        from pytest_ddenv.cli.main import main

        capsys.readouterr()
        code = main(command.argv[1:])
        captured = capsys.readouterr()
        printed = captured.err.splitlines() + captured.out.splitlines()
    else:
        # pytester runs in a folder of its own (and makes it the current one): link the page's files there.
        # It is only requested here, as at its teardown it drops the modules imported since it was set up.
        here = Path.cwd()
        pytester: pytest.Pytester = request.getfixturevalue("pytester")
        for item in here.iterdir():
            if not (pytester.path / item.name).exists():
                (pytester.path / item.name).symlink_to(item, target_is_directory=item.is_dir())
        try:
            result = pytester.runpytest_subprocess(*command.argv[1:])
        finally:
            os.chdir(here)
        code = int(result.ret)
        printed = result.errlines + result.outlines
    shown = "\n".join(printed)
    assert code == command.expected_exit_code, (
        f"{where} exited with {code}, the page says {command.expected_exit_code}; it printed:\n{shown}"
    )
    position = 0
    for expected in command.output:
        if expected.strip() in ("", "..."):
            continue
        pattern = _line_pattern(expected)
        for offset, actual in enumerate(printed[position:]):
            if pattern.fullmatch(actual.rstrip()):
                position += offset + 1
                break
        else:
            raise AssertionError(f"{where}: the page shows the line\n  {expected}\nwhich is not in the output "
                                 f"(or not in this order):\n{shown}")


def _line_pattern(expected: str) -> re.Pattern[str]:
    expected = expected.rstrip()
    parts, last = [], 0
    for volatile in VOLATILE.finditer(expected):
        parts.append(re.escape(expected[last:volatile.start()]))
        parts.append(re.sub(r"\d+", r"\\d+", re.escape(volatile.group())))
        last = volatile.end()
    parts.append(re.escape(expected[last:]))
    return re.compile("".join(parts))
