"""MuJoCo's renderer in a helper process, one OpenGL backend after another until one starts.

MuJoCo picks its OpenGL backend from `MUJOCO_GL` when it is first imported, and a GL driver can crash the
process that starts it; so MuJoCo draws in a helper process (started as the probe workers are) whose
`MUJOCO_GL` is set before mujoco is imported there: the user's own `MUJOCO_GL` when it is set (and only
that), otherwise `egl` (a GPU or Mesa's EGL, headless) and then `osmesa` (Mesa's software renderer) on
Linux, MuJoCo's own choice elsewhere. A backend that does not start (`GLUnavailable`, or the helper died)
is noted and the next one tried in a new helper; when none starts, `AnimationUnavailable` says which were
tried and why each failed.
"""

from __future__ import annotations

import concurrent.futures
import concurrent.futures.process
import importlib.util
import os
import platform
from collections.abc import Callable
from typing import TypeVar

from pytest_ddenv.errors import DdenvError

GL_ENV = "MUJOCO_GL"
LINUX_BACKENDS = ("egl", "osmesa")

NEITHER = ("neither pybullet (TinyRenderer) nor mujoco (its OpenGL renderer) is installed: pip install "
           '"pytest-ddenv[mujoco]", or ask for the pictures alone (--ddenv-media pictures, ddenv reduce --media '
           "pictures)")

Result = TypeVar("Result")


class AnimationUnavailable(DdenvError):
    """No renderer can draw the animations here (neither pybullet nor an OpenGL backend for MuJoCo)."""


def gl_backends() -> tuple[str, ...]:
    """The `MUJOCO_GL` values to try, first to last ("" is MuJoCo's own choice)."""
    chosen = os.environ.get(GL_ENV)
    if chosen is not None:
        return (chosen,)
    return LINUX_BACKENDS if platform.system() == "Linux" else ("",)


def use_gl_backend(backend: str) -> None:
    """In the helper, before mujoco is imported there: select `backend` ("": MuJoCo's own choice)."""
    if backend:
        os.environ[GL_ENV] = backend


def in_gl_helper(task: Callable[..., Result], *arguments: object) -> Result:
    """`task(*arguments)` in a helper process with the first OpenGL backend that starts (the task raises
    `mujoco_scene.GLUnavailable` when its renderer cannot start); AnimationUnavailable when none does."""
    from pytest_ddenv.execution.local import main_module_hidden, probe_context
    from pytest_ddenv.media.mujoco_scene import GLUnavailable

    if importlib.util.find_spec("mujoco") is None:
        raise AnimationUnavailable(f"no renderer can draw the animations here: {NEITHER}")
    tried = []
    for backend in gl_backends():
        executor = concurrent.futures.ProcessPoolExecutor(1, mp_context=probe_context(), initializer=use_gl_backend,
                                                          initargs=(backend,))
        try:
            with main_module_hidden():  # the process starts here: it must not re-import a user's script
                future = executor.submit(task, *arguments)
            return future.result()
        except GLUnavailable as error:
            tried.append(f"{GL_ENV}={backend or '(unset)'}: {error}")
        except concurrent.futures.process.BrokenProcessPool:
            tried.append(f"{GL_ENV}={backend or '(unset)'}: the renderer's process died")
        finally:
            executor.shutdown(wait=True)
    yours = f"; {GL_ENV} is set in your environment, so only it was tried" if GL_ENV in os.environ else ""
    raise AnimationUnavailable(
        "no renderer can draw the animations here: pybullet is not installed and MuJoCo's renderer found no "
        f"OpenGL backend that starts (tried {'; '.join(tried)}){yours}; install EGL (libegl1) or OSMesa "
        "(libosmesa6), or ask for the pictures alone (--ddenv-media pictures, ddenv reduce --media pictures)")
