"""Franka's datasheet limits on the arm's joint motion, and the clip that keeps a target path within them.

Imports numpy alone: the deployment loop clips with it, and jaxarm's envs clip their servos' targets with the same
function (`limit_targets` uses only array methods and operators, so it runs on numpy and JAX arrays alike).
"""

from typing import Any, NamedTuple

import numpy as np

ARM_SPEED_LIMITS = np.array([2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61], np.float32)
"""[7] the arm joints' speed limits (rad/s) in Franka's datasheet; panda.xml's servos do not enforce them."""
ARM_ACCELERATION_LIMITS = np.array([15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0], np.float32)
"""[7] the arm joints' acceleration limits (rad/s²) in Franka's datasheet."""
ARM_JERK_LIMITS = np.array([7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0], np.float32)
"""[7] the arm joints' jerk limits (rad/s³) in Franka's datasheet: what a 1 kHz servo stream must keep within
(`stream.ServoStream`); a 25 Hz tick's targets are not held to them."""


class LimitedTargets(NamedTuple):
    """A tick's joint targets within the limits (numpy or JAX arrays, as given).

    Attributes:
      targets: [7] the targets sent.
      velocity: [7] their rate of change over the tick (rad/s).
      acceleration_clipped: [7] bool, joints whose asked rate changed faster than the acceleration limit allows.
      speed_clipped: [7] bool, joints whose rate (after the acceleration limit) was beyond the speed limit.
    """

    targets: Any
    velocity: Any
    acceleration_clipped: Any
    speed_clipped: Any


def limit_targets(targets: Any, previous: Any, previous_velocity: Any, period: float) -> LimitedTargets:
    """[7] asked `targets` -> the nearest targets whose path from `previous` [7], moving at `previous_velocity` [7],
    keeps every joint within `ARM_SPEED_LIMITS` and `ARM_ACCELERATION_LIMITS` over one tick of `period` seconds.

    A path that a held action asks for and then stops asking for loses the distance the acceleration limit holds
    back while speeding up and regains it while slowing down, so it ends where the action's steps add up to."""
    asked = (targets - previous) / period
    change = ARM_ACCELERATION_LIMITS * period
    reachable = asked.clip(previous_velocity - change, previous_velocity + change)
    velocity = reachable.clip(-ARM_SPEED_LIMITS, ARM_SPEED_LIMITS)
    return LimitedTargets(
        targets=previous + velocity * period,
        velocity=velocity,
        acceleration_clipped=reachable != asked,
        speed_clipped=velocity != reachable,
    )
