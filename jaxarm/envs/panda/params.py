"""`ArmParams`: the robot's params that every Panda task's params extend, declared once.

On top of the sim-to-real `RobotParams`, the arm's own control settings (its IK's and its start noise), whose
defaults are the robot description's (`jaxarm.robots`). A task's params subclass `ArmParams` and add only their own.
"""

import jax
from flax import struct

from jaxarm.envs.panda.sim_to_real import RobotParams
from jaxarm.ranges import NON_NEGATIVE, POSITIVE, UNIT_INTERVAL, ranged
from jaxarm.robots import PANDA


@struct.dataclass
class ArmParams(RobotParams):
    """The arm's params shared by every Panda task (scalars, float32), with `RobotParams`' (documented there).

    Attributes:
      ik_damping: damping λ of the damped-least-squares IK (metres-radians).
      ik_posture_gain: null-space pull of the arm towards its start posture per step (fraction of the error).
      home_noise: half-width of the uniform noise on the arm's initial joint angles (radians).
    """

    ik_damping: jax.Array = ranged(PANDA.ik_damping, POSITIVE)
    ik_posture_gain: jax.Array = ranged(PANDA.ik_posture_gain, UNIT_INTERVAL)
    home_noise: jax.Array = ranged(PANDA.home_noise, NON_NEGATIVE)
