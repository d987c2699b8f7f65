"""The clip that keeps an arm's target path within its joints' speed and acceleration limits (a robot
description's `JointLimits`; the Panda's are Franka's datasheet's). J is the arm's joint count, the length of the
limits' arrays.

Imports numpy alone: the deployment loop clips with it, and jaxarm's envs clip their servos' targets with the same
function (`limit_targets` uses only array methods and operators, so it runs on numpy and JAX arrays alike).
"""

from typing import Any, NamedTuple

from jaxarm.robots import PANDA
from jaxarm.robots.description import JointLimits


class LimitedTargets(NamedTuple):
    """A tick's joint targets within the limits (numpy or JAX arrays, as given).

    Attributes:
      targets: [J] the targets sent.
      velocity: [J] their rate of change over the tick (rad/s).
      acceleration_clipped: [J] bool, joints whose asked rate changed faster than the acceleration limit allows.
      speed_clipped: [J] bool, joints whose rate (after the acceleration limit) was beyond the speed limit.
    """

    targets: Any
    velocity: Any
    acceleration_clipped: Any
    speed_clipped: Any


def limit_targets(
    targets: Any, previous: Any, previous_velocity: Any, period: float, limits: JointLimits = PANDA.joint_limits
) -> LimitedTargets:
    """[J] asked `targets` -> the nearest targets whose path from `previous` [J], moving at `previous_velocity` [J],
    keeps every joint within the speed and acceleration `limits` over one tick of `period` seconds.

    A path that a held action asks for and then stops asking for loses the distance the acceleration limit holds
    back while speeding up and regains it while slowing down, so it ends where the action's steps add up to."""
    asked = (targets - previous) / period
    change = limits.acceleration * period
    reachable = asked.clip(previous_velocity - change, previous_velocity + change)
    velocity = reachable.clip(-limits.speed, limits.speed)
    return LimitedTargets(
        targets=previous + velocity * period,
        velocity=velocity,
        acceleration_clipped=reachable != asked,
        speed_clipped=velocity != reachable,
    )
