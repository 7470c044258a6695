"""The process's OpenGL: who may draw (not a child forked after GL was initialised), and
one thread drawing at a time.

**Across fork.** A forked child cannot use the GL state it inherits, so it is refused.
Mesa's software rasteriser (llvmpipe, what EGL runs on without a GPU) starts worker
threads when its display is initialised and waits on them inside GL calls. ``fork``
copies the process without those threads: a child that creates a GL context on the
inherited display waits forever (a hung ``AsyncVectorEnv`` worker, in ``py-spy dump
--native``: ``pthread_cond_wait`` in ``swrast_dri.so`` under ``mjr_uploadTexture``, with
the parent blocked sending to it). The display is process-wide and stays initialised
until exit, even after every context is freed.

So the env creates its renderer lazily, in the process that renders (constructing an env,
as ``AsyncVectorEnv`` does in the parent to read the spaces, touches no GL), and
:func:`claim_gl` is called before each GL context is created: in a process forked after
GL was initialised it raises :class:`ForkedGLError` at once, naming the fix (the
``"spawn"`` start method), instead of hanging. The env's renderer may live on a render
thread (:mod:`wander_env.frames.stage`), which a forked child does not have: there the
stage raises the same error before handing the thread any work, and forgets the parent's
GL objects when closed, freeing nothing.

**One drawer at a time.** Every GL call of :class:`~wander_env.renderer.CameraRenderer`
(making a context, drawing and reading, freeing) runs under :func:`gl_lock`, one
re-entrant lock for the process. Each env draws on one thread (its render thread), so a
process with one env never waits on it; where one process holds several envs (a
``"sync"`` vector env, ``wander perf env``'s modes in turns) their render threads take
turns. Two threads each drawing in a context of its own is what OpenGL allows, but
processes of this project died in native code while two of their threads drew at once
(in CI: twice inside ``mjr_render``, once with no stack printed), and none has been seen
to die with one drawer; the cost of taking turns is in ``docs/benchmarks.md``.

Which process initialised GL, and its lock, are process-wide state by nature; they are
kept here, in one place: the pid that created a context through :func:`claim_gl`, or,
where something else (``mujoco.Renderer``, the user's own code) initialised MuJoCo's EGL
display, the parent's pid, noted by an ``os.register_at_fork`` hook in the child; and the
lock, made anew in a forked child (a thread that held the parent's is not there to
release it).

Examples:
    >>> claim_gl()  # this process may create GL contexts (it was not forked after GL)
    >>> gl_owner_pid() == os.getpid()
    True
"""

from __future__ import annotations

import os
import sys
import threading

# The pid of the process whose GL state this memory holds; None while no GL is known.
_GL_OWNER: dict[str, int | None] = {"pid": None}
# The lock every GL call of this process runs under.
_GL_LOCK: dict[str, threading.RLock] = {"lock": threading.RLock()}


class ForkedGLError(RuntimeError):
    """GL was initialised in a parent before this process was forked from it."""


def _egl_display_initialised() -> bool:
    """Whether MuJoCo's EGL backend has initialised its (process-wide) display."""
    egl = sys.modules.get("mujoco.egl")
    return getattr(egl, "EGL_DISPLAY", None) is not None


def _note_inherited_gl() -> None:
    """At fork, in the child: EGL initialised outside :func:`claim_gl` is the parent's."""
    if _GL_OWNER["pid"] is None and _egl_display_initialised():
        _GL_OWNER["pid"] = os.getppid()


def _new_lock_in_child() -> None:
    """At fork, in the child: a lock of its own (the parent's may be held by a thread the
    child does not have)."""
    _GL_LOCK["lock"] = threading.RLock()


os.register_at_fork(after_in_child=_note_inherited_gl)
os.register_at_fork(after_in_child=_new_lock_in_child)


def gl_lock() -> threading.RLock:
    """The lock this process's GL calls run under (re-entrant: a renderer collected inside
    a locked call, on the same thread, takes it again)."""
    return _GL_LOCK["lock"]


def gl_owner_pid() -> int | None:
    """The process whose OpenGL state this process holds (None: no GL initialised)."""
    return _GL_OWNER["pid"]


def fork_error_message(owner: int, pid: int) -> str:
    """What to do when process ``pid`` was forked from ``owner`` after GL was initialised."""
    return (
        f"OpenGL was initialised in process {owner} before this process ({pid}) was forked "
        "from it; a forked child inherits the GL driver's state without its threads, and its "
        "first render would wait forever. Start worker processes with the 'spawn' method: "
        "gymnasium.vector.AsyncVectorEnv(env_fns, context='spawn'), "
        "gymnasium.make_vec(..., vectorization_mode='async', "
        "vector_kwargs={'context': 'spawn'}) or multiprocessing.get_context('spawn'); or "
        "create the vector env before anything renders in the parent process"
    )


def claim_gl() -> None:
    """Call before creating a GL context: raises :class:`ForkedGLError` in a child forked
    after its parent initialised GL; otherwise records this process as the GL owner."""
    pid = os.getpid()
    owner = _GL_OWNER["pid"]
    if owner is not None and owner != pid:
        raise ForkedGLError(fork_error_message(owner, pid))
    _GL_OWNER["pid"] = pid


__all__ = ["ForkedGLError", "claim_gl", "fork_error_message", "gl_lock", "gl_owner_pid"]
