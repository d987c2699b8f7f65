"""Drawing without a window, what a command must know before its heavy imports: the video formats it writes,
whether MuJoCo's OpenGL renderer can draw here (`gl_problem`) and what to do when it cannot (`GL_HINT`).

Must not import jax, and imports mujoco only when asked to probe: `experiments.eval --video` checks GL before it
imports the learners or compiles anything.
"""

import warnings

FORMATS = ("gif", "mp4")
"""The video files the commands write (`jaxarm.runner.video.write_video`)."""

GL_HINT = (
    "headless rendering needs an offscreen GL: MUJOCO_GL=egl with Mesa's libegl1 libegl-mesa0 libgl1-mesa-dri "
    "on a CPU machine (apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri), or a GPU driver's EGL"
)
"""What to do when MuJoCo cannot draw (the words of docs/install.md)."""


class GLImportError(ImportError):
    """mujoco could not load the GL platform MUJOCO_GL names (`jaxarm._runtime.import_mjx_quietly`); the message
    ends with `GL_HINT`."""


def probe_gl() -> None:
    """Draws one 8x8 frame of an empty scene with MuJoCo's renderer; raises whatever the GL platform raises."""
    import mujoco

    renderer = mujoco.Renderer(mujoco.MjModel.from_xml_string("<mujoco/>"), height=8, width=8)
    try:
        renderer.render()
    finally:
        renderer.close()


def no_gl_message(error: Exception) -> str:
    """One line: why MuJoCo could not draw (`error`), then `GL_HINT`."""
    reason = " ".join(f"{type(error).__name__}: {error}".split())
    return f"cannot draw here ({reason}); {GL_HINT}"


def gl_problem() -> str | None:
    """`no_gl_message` where MuJoCo's renderer cannot draw here (`probe_gl`), None where it can."""
    try:
        # GLFW warns of each step of its failure (no DISPLAY, library not initialised) before mujoco raises.
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            probe_gl()
    except Exception as error:  # mujoco.FatalError, GL loaders' errors: no shared base class
        return no_gl_message(error)
    return None
