"""The arm layer shared by the MJX arm envs (the Franka Panda's tasks first, hence the name; the robot itself is
`env_kwargs.robot`, `jaxarm.robots`): a robot's model and control (robot.py), drawing (render.py), and `ArmBase`
(base.py), the base class every arm task subclasses."""

from jaxarm._runtime import import_mjx_quietly

import_mjx_quietly()
