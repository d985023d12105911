"""The git plumbing of `ddenv bisect`: revisions, the first-parent line between two of them, and detached
worktrees of one commit. Every git command runs with a timeout. Apart from adding and removing the bisect's
own worktrees (a folder under the bisect's folder, and its entry under `.git/worktrees/`), they only read:
nothing here touches the user's checkout, index, other worktrees or `git bisect` state.
"""

from __future__ import annotations

import contextlib
import shutil
import subprocess
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from pytest_ddenv.errors import DdenvError, shown

GIT_TIMEOUT = 120.0
"""Seconds any one git command may take (a worktree of a large repository takes a few)."""


class GitError(DdenvError):
    """A git command failed, or the repository or a revision is not what `ddenv bisect` needs."""


@dataclass(frozen=True)
class Commit:
    sha: str
    subject: str

    @property
    def short(self) -> str:
        return self.sha[:7]

    def describe(self) -> str:
        return f"{self.short} {self.subject}"


def git(repository: Path, arguments: Sequence[str], *, timeout: float = GIT_TIMEOUT) -> str:
    """`git -C repository ARGUMENTS`'s stdout (stripped); `GitError` with git's own words if it fails."""
    command = ["git", "-C", str(repository), *arguments]
    try:
        done = subprocess.run(command, capture_output=True, text=True, timeout=timeout, check=False,
                              stdin=subprocess.DEVNULL)
    except FileNotFoundError:
        raise GitError("git is not installed (no 'git' on PATH); ddenv bisect needs it") from None
    except subprocess.TimeoutExpired:
        raise GitError(f"git {' '.join(arguments)} took more than {timeout:g} s in {repository}") from None
    if done.returncode != 0:
        words = done.stderr.strip().splitlines()
        raise GitError(f"git {' '.join(arguments)} failed in {repository}: {words[-1] if words else done.returncode}")
    return done.stdout.strip()


def repository_root(folder: Path) -> Path:
    """The top folder of the work tree `folder` is in (`GitError` naming `folder` when it is not in one)."""
    if not folder.is_dir():
        raise GitError(f"{folder}: no such folder (--repo)")
    try:
        return Path(git(folder, ["rev-parse", "--show-toplevel"]))
    except GitError:
        raise GitError(f"{folder}: not a git repository (give --repo, the folder of the project to bisect)") from None


def resolve(repository: Path, revision: str, role: str) -> Commit:
    """The commit `revision` names (`GitError` naming it and its `role`, "good" or "bad", when unknown)."""
    try:
        sha = git(repository, ["rev-parse", "--verify", "--quiet", "--end-of-options", f"{revision}^{{commit}}"])
    except GitError:
        raise GitError(f"unknown {role} revision {shown(revision)} in {repository} (git rev-parse found no "
                       "commit by that name)") from None
    return Commit(sha, subject(repository, sha))


def subject(repository: Path, sha: str) -> str:
    return git(repository, ["log", "-1", "--format=%s", sha])


def is_ancestor(repository: Path, older: str, newer: str) -> bool:
    command = ["git", "-C", str(repository), "merge-base", "--is-ancestor", older, newer]
    try:
        done = subprocess.run(command, capture_output=True, timeout=GIT_TIMEOUT, check=False,
                              stdin=subprocess.DEVNULL)
    except subprocess.TimeoutExpired:
        raise GitError(f"git merge-base --is-ancestor took more than {GIT_TIMEOUT:g} s in {repository}") from None
    if done.returncode not in (0, 1):
        raise GitError(f"git merge-base --is-ancestor {older} {newer} failed in {repository}")
    return done.returncode == 0


def first_parent_line(repository: Path, good: Commit, bad: Commit) -> list[Commit]:
    """The commits after `good` up to `bad` included, oldest first, along `bad`'s first parents: the line
    `git bisect --first-parent` searches. `GitError` when `good` is not an ancestor of `bad`, or is not on
    that line (it was merged in from a side branch)."""
    if good.sha == bad.sha:
        raise GitError(f"the good and bad revisions are the same commit ({good.short})")
    if not is_ancestor(repository, good.sha, bad.sha):
        raise GitError(f"the good revision {good.short} is not an ancestor of the bad revision {bad.short}: "
                       "give a good revision older than the bad one, on its history")
    lines = git(repository, ["log", "--first-parent", "--ancestry-path", "--reverse", "--format=%H %s",
                             f"{good.sha}..{bad.sha}"]).splitlines()
    line = [Commit(*text.split(" ", 1)) if " " in text else Commit(text, "") for text in lines if text]
    if not line or line[-1].sha != bad.sha:
        raise GitError(f"no first-parent line from {good.short} to {bad.short}")
    oldest_parent = git(repository, ["rev-parse", f"{line[0].sha}^1"])
    if oldest_parent != good.sha:
        raise GitError(f"the good revision {good.short} is not on the first-parent line of {bad.short} (it came "
                       "in through a merge): give a good revision on that line, e.g. the merge's first parent")
    return line


def add_worktree(repository: Path, commit: Commit, folder: Path) -> Path:
    """A detached worktree of `commit` in `folder` (which must not exist yet)."""
    folder.parent.mkdir(parents=True, exist_ok=True)
    git(repository, ["worktree", "add", "--detach", "--force", str(folder), commit.sha])
    return folder


def remove_worktree(repository: Path, folder: Path) -> None:
    """Remove a worktree `add_worktree` made (and its administrative files); quiet if it is already gone. A
    folder git does not know as a worktree (a half-made one) is deleted: it is inside the bisect's own folder.
    Other worktrees of the repository are left alone (no `git worktree prune`); one of ours whose folder went
    missing is reused by `add_worktree --force`."""
    if folder.exists():
        with contextlib.suppress(GitError):
            git(repository, ["worktree", "remove", "--force", "--force", str(folder)])
    if folder.exists():
        shutil.rmtree(folder)
