"""The surgical export of a reduction's minimal world: cut, read back, and accepted only when it is that world."""

from __future__ import annotations

from collections.abc import Collection, Sequence
from pathlib import Path

from pytest_ddenv.errors import WorldError
from pytest_ddenv.sdf._reader import parse_sdf
from pytest_ddenv.sdf._surgical import cut_file
from pytest_ddenv.sdf._surgical_text import SurgeryError
from pytest_ddenv.world.model import World

COMPARED = ("scenario", "physics", "ground", "name")
"""What the reduction used besides the models, compared between the cut file and the minimal world."""


def minimal_cut(source: Path, minimal: World, removed: Collection[str],
                model_paths: Sequence[str | Path]) -> tuple[bytes, str]:
    """The SDF file `source` cut down to `minimal` (its removed models and their `<state>` entries deleted, its
    `ddenv:scenario` the minimal world's) and how it was made ("cut from FILE[; ...]"). SurgeryError when the
    file cannot be cut or the cut file, read back, is not exactly `minimal`."""
    cut = cut_file(source, set(removed), model_paths=model_paths, scenario=minimal.scenario)
    check_cut(cut.data, source, minimal, model_paths)
    how = f"cut from {source}"
    if cut.scenario_written:
        how += "; its ddenv:scenario written from the reduction's scenario (not the file's)"
    if cut.relative_paths:
        how += (f"; its relative paths ({', '.join(cut.relative_paths[:3])}) are relative to the original's folder "
                f"{source.resolve().parent}: copy minimal.sdf beside the original to open it")
    return cut.data, how


def check_cut(data: bytes, source: Path, minimal: World, model_paths: Sequence[str | Path]) -> None:
    """SurgeryError unless `data`, read as if it were `source`, gives exactly the minimal world: its models and
    everything else the reduction used (scenario, physics, ground, name)."""
    dropped = any(note.startswith("dropped ") for note in minimal.notes)
    try:
        reread = parse_sdf(data, source=source, model_paths=model_paths, skip_unsupported=dropped)
    except WorldError as error:
        raise SurgeryError(f"the cut file does not load: {error}", source=source) from None
    if reread == minimal:
        return
    if reread.models != minimal.models:
        changed = sorted({m.name for m in reread.models} ^ {m.name for m in minimal.models}) or sorted(
            m.name for m, n in zip(reread.models, minimal.models, strict=False) if m != n)
        raise SurgeryError(f"the cut file does not give the minimal world ({', '.join(changed[:5])} differ)",
                           source=source)
    differ = [part for part in COMPARED if getattr(reread, part) != getattr(minimal, part)]
    raise SurgeryError(f"the cut file does not give the minimal world (its {', '.join(differ)} differ)",
                       source=source)
