"""Files a reduction leaves behind: minimal world (YAML, SDF), run log, summary, pictures.

Every file is written atomically (write to a temporary name, then rename), so an interrupted reduction
never leaves a half-written file; the run log is appended and flushed line by line by the engine.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pytest_ddenv.reduce import Reduction
from pytest_ddenv.world import World

SUMMARY_FORMAT = 1
_UNSAFE = re.compile(r"[^A-Za-z0-9._-]+")


def artifact_dir_name(test_id: str) -> str:
    """A folder name for a test id: safe on every file system, no traversal, and unique per id."""
    readable = _UNSAFE.sub("_", test_id.replace("::", "__")).strip("._") or "test"
    digest = hashlib.sha1(test_id.encode("utf-8")).hexdigest()[:8]
    return f"{readable[:80]}-{digest}"


def write_text_atomic(path: Path, text: str) -> None:
    temporary = path.with_name(f".{path.name}.tmp{os.getpid()}")
    temporary.write_text(text, encoding="utf-8")
    os.replace(temporary, path)


def fingerprint(world: World, settings: dict[str, Any], test_source: str = "") -> str:
    """Identifies a reduction problem: a resumed log is only reused when this matches."""
    from importlib.metadata import version

    payload = json.dumps(
        {"world": world.to_yaml(), "settings": settings, "test": test_source,
         "pybullet": version("pybullet")},  # a run is bit-identical only with the same pybullet
        sort_keys=True,
        default=str,
    )
    return hashlib.sha256(payload.encode("utf-8")).hexdigest()


@dataclass(frozen=True)
class ArtifactPaths:
    directory: Path

    @property
    def minimal_yaml(self) -> Path:
        return self.directory / "minimal.yaml"

    @property
    def minimal_sdf(self) -> Path:
        return self.directory / "minimal.sdf"

    @property
    def log(self) -> Path:
        return self.directory / "runs.jsonl"

    @property
    def summary(self) -> Path:
        return self.directory / "summary.json"

    @property
    def reduction_png(self) -> Path:
        return self.directory / "reduction.png"

    @property
    def progress_png(self) -> Path:
        return self.directory / "progress.png"


def prepare(directory: Path, problem_fingerprint: str) -> ArtifactPaths:
    """Create the folder; keep an earlier log only if it belongs to the same problem (resume)."""
    directory.mkdir(parents=True, exist_ok=True)
    paths = ArtifactPaths(directory)
    previous = read_summary(paths.summary)
    if paths.log.exists() and (previous is None or previous.get("fingerprint") != problem_fingerprint):
        paths.log.unlink()
    return paths


def read_summary(path: Path) -> dict[str, Any] | None:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def write_reduction(
    paths: ArtifactPaths,
    world: World,
    reduction: Reduction,
    *,
    test_id: str,
    replay_command: str,
    problem_fingerprint: str,
    reference: dict[str, Any],
    extra: dict[str, Any] | None = None,
    model_paths: Sequence[str | Path] = (),
) -> dict[str, Any]:
    """Write the minimal world and the summary; returns the summary (plain JSON-able dict).

    `minimal.sdf` of a world read from an SDF file is that file with the removed models cut out (see
    `write_minimal_sdf`); `model_paths` are those the world was read with (to name its includes again).
    """
    minimal = world.select(reduction.minimal)
    write_text_atomic(paths.minimal_yaml, minimal.to_yaml(relative_to=paths.directory))
    files = {"minimal_yaml": str(paths.minimal_yaml), "log": str(paths.log), "summary": str(paths.summary)}
    how = write_minimal_sdf(paths.minimal_sdf, world, minimal, reduction.removed, model_paths)
    if how is not None:
        files["minimal_sdf"] = str(paths.minimal_sdf)
    summary = summary_of(world, reduction, test_id=test_id, replay_command=replay_command, reference=reference)
    summary["fingerprint"] = problem_fingerprint
    summary["files"] = files
    summary["minimal_sdf"] = how
    summary.update(extra or {})
    write_text_atomic(paths.summary, json.dumps(summary, indent=2) + "\n")
    return summary


def write_minimal_sdf(target: Path, world: World, minimal: World, removed: Sequence[str],
                      model_paths: Sequence[str | Path]) -> str | None:
    """Write `minimal.sdf` and say how: "cut from <file>" (the original SDF file with the removed models and
    their `<state>` entries deleted, nothing else changed: its relative paths are the original file's), or
    "regenerated[: why not cut]" (from the world model), or None when no SDF could be written."""
    from pytest_ddenv.sdf import SurgeryError, cut_models

    source = Path(world.source) if world.source else None
    reason = ""
    if source is not None and source.suffix.lower() in (".sdf", ".world") and source.is_file():
        try:
            text = cut_models(source, set(removed), model_paths=model_paths)
            _check_cut(text, source, minimal, model_paths)
        except SurgeryError as error:
            reason = f": {error.reason}"
        else:
            write_text_atomic(target, text)
            return f"cut from {source}"
    try:
        minimal.save(target)
    except Exception:  # noqa: BLE001 - SDF export is optional; the YAML is the reference artifact
        return None
    return "regenerated" + reason


def _check_cut(text: str, source: Path, minimal: World, model_paths: Sequence[str | Path]) -> None:
    """SurgeryError unless `text`, read as if it were `source`, gives exactly the minimal world's models (a kept
    model may be placed relative to a removed one, for instance)."""
    from pytest_ddenv.errors import WorldError
    from pytest_ddenv.sdf import SurgeryError, parse_sdf

    dropped = any(note.startswith("dropped ") for note in minimal.notes)
    try:
        reread = parse_sdf(text, source=source, model_paths=model_paths, skip_unsupported=dropped)
    except WorldError as error:
        raise SurgeryError(f"the cut file does not load: {error}", source=source) from None
    if reread.models != minimal.models:
        changed = sorted({m.name for m in reread.models} ^ {m.name for m in minimal.models}) or sorted(
            m.name for m, n in zip(reread.models, minimal.models, strict=False) if m != n)
        raise SurgeryError(f"the cut file does not give the minimal world ({', '.join(changed[:5])} differ)",
                           source=source)


def failure_rate_line(reduction: Reduction) -> str:
    """"minimal world fails 5/5 seeds (original world: 3/3)", with a warning when it rarely fails."""
    fails, runs = reduction.failure_rate
    line = f"minimal world fails {fails}/{runs} seeds"
    if reduction.calibration is not None:
        line += f" (original world: {reduction.calibration[0]}/{reduction.calibration[1]})"
    if runs and fails * 2 < runs:
        line += " (warning: it rarely reproduces the failure" + (
            "; consider deflake='auto')" if reduction.calibration is None else ")"
        )
    return line


def summary_of(
    world: World, reduction: Reduction, *, test_id: str, replay_command: str, reference: dict[str, Any]
) -> dict[str, Any]:
    removed = [name for name in reduction.original if name not in set(reduction.minimal)]
    fails, runs = reduction.failure_rate
    return {
        "format": SUMMARY_FORMAT,
        "test": test_id,
        "world": world.source or world.name,
        "complete": reduction.incomplete_reason is None,
        "incomplete_reason": reduction.incomplete_reason,
        "one_minimal": reduction.one_minimal,
        "original_size": reduction.original_size,
        "minimal_size": reduction.minimal_size,
        "reduction_percent": round(100.0 * (1 - reduction.minimal_size / max(reduction.original_size, 1)), 1),
        "minimal_models": list(reduction.minimal),
        "removed_models": removed,
        "kept_models": list(reduction.kept),
        "probes": reduction.probes,
        "cache_hits": reduction.cache_hits,
        "skipped": reduction.skipped,
        "errors": reduction.errors,
        "steps": [list(step) for step in reduction.steps],
        "failure_rate": {"fails": fails, "runs": runs},
        "original_failure_rate": (
            None if reduction.calibration is None
            else {"fails": reduction.calibration[0], "runs": reduction.calibration[1]}
        ),
        "wall_time": round(reduction.wall_time, 3),
        "schemas": {
            "partition": reduction.partition,
            "priority": reduction.priority,
            "granularity": reduction.granularity,
            "deflake": reduction.deflake,
        },
        "seed": reduction.seed,
        "reference_failure": reference,
        "replay": replay_command,
    }
