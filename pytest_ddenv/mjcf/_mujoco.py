"""MuJoCo as the reader of MJCF: imported when a scene is first read, and its errors made one line of ours."""

from __future__ import annotations

import re
from pathlib import Path
from types import ModuleType

from pytest_ddenv.errors import WorldError
from pytest_ddenv.mjcf._files import SceneFiles

INSTALL = 'pip install "pytest-ddenv[mujoco]"'
_ELEMENT_LINE = re.compile(r"Element (?:name '(?P<name>[^']*)', id \d+, )?(?:'(?P<tag>[^']*)', )?line (?P<line>\d+)")
_XML_LINE = re.compile(r"Line number=(?P<line>\d+)")


def mujoco_module(source: Path) -> ModuleType:
    """The `mujoco` package; WorldError saying how to install it when it is not."""
    try:
        import mujoco
    except ImportError:
        raise WorldError(f"reading an MJCF scene needs MuJoCo: {INSTALL}", source=source) from None
    module: ModuleType = mujoco
    return module


def mujoco_error(error: Exception, scene: SceneFiles, what: str) -> WorldError:
    """MuJoCo's message (`what`: "cannot read the scene", ...) as one line naming the file and line it gives."""
    text = str(error).strip()
    found = _ELEMENT_LINE.search(text) or _XML_LINE.search(text)
    line = int(found["line"]) if found else None
    tag = found.groupdict().get("tag") if found else None
    name = found.groupdict().get("name") if found else None
    first = text.splitlines()[0] if text else type(error).__name__
    first = re.sub(r"^(XML Error|Error|XML parse error \d+):\s*", "", first)
    source = scene.where(tag, line) if tag else scene.main
    if not line and scene.included_as:  # MuJoCo numbers no line in an included file: read each one alone
        for file, data in list(scene.files.items())[1:]:
            try:
                mujoco_module(file).MjSpec.from_string(data.decode("utf-8", errors="replace"))
            except ValueError as alone:
                if str(alone).splitlines()[:1] == text.splitlines()[:1]:
                    return mujoco_error(alone, SceneFiles(file, {file: data}), what)
    return WorldError(f"{what}: MuJoCo says: {first}", source=source, line=line, field=tag,
                      model=name or None)
