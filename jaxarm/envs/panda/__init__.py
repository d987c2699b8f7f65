"""The Franka Panda shared by the MJX arm envs: its model and control (robot.py), drawing (render.py), and
`PandaBase` (base.py), the base class every Panda task subclasses."""

from jaxarm._runtime import import_mjx_quietly

import_mjx_quietly()
