"""A jerk-limited servo stream: the policy's joint targets, one each control tick (25 Hz), turned into a setpoint
each servo tick (1 kHz) within the arm's speed, acceleration and jerk limits (its description's `JointLimits`; the
Panda's by default), by Ruckig's online trajectories. J is the arm's joint count, the length of the limits' arrays.
Imports numpy and ruckig alone.

Each target is reached no sooner than `arrival` seconds after it was given, moving at the rate the loop's targets
change over a tick: the stream follows the loop's piecewise-linear path that much behind, its corners rounded off
within the jerk limit. `hold` brakes to rest from wherever the stream is, within the same limits.
"""

from typing import NamedTuple

import numpy as np
import ruckig

from jaxarm.robots import PANDA
from jaxarm.robots.description import JointLimits


class StreamPoint(NamedTuple):
    """One servo tick's setpoint, each [J]: joint angle (rad), speed (rad/s) and acceleration (rad/s²)."""

    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray


class StreamError(RuntimeError):
    """Ruckig found no trajectory to the given target (an input beyond the limits or not finite)."""


class ServoStream:
    """Setpoints every `servo_period` seconds towards the latest target, within the arm's limits.

    Args:
      position: [J] where the arm is, at rest.
      servo_period: seconds between setpoints (0.001: Franka's 1 kHz).
      arrival: seconds after a target is given that the stream reaches it, at the earliest (`wire.Timing.arrival`).
      limits: the arm's joint limits, whose length is the stream's J.

    Attributes:
      holding: whether `hold` was called: the stream brakes to rest and takes no more targets.
    """

    def __init__(
        self, position: np.ndarray, servo_period: float, arrival: float, limits: JointLimits = PANDA.joint_limits
    ):
        joints = len(limits.speed)
        self._generator = ruckig.Ruckig(joints, servo_period)
        self._input = ruckig.InputParameter(joints)
        self._output = ruckig.OutputParameter(joints)
        self._speed_limits = limits.speed.astype(np.float64)
        self._input.max_velocity = self._speed_limits
        self._input.max_acceleration = limits.acceleration.astype(np.float64)
        self._input.max_jerk = limits.jerk.astype(np.float64)
        self._input.current_position = np.asarray(position, np.float64)
        self._input.target_position = np.asarray(position, np.float64)
        self._input.minimum_duration = arrival
        self._result = ruckig.Result.Finished
        self.holding = False

    def retarget(self, target: np.ndarray, velocity: np.ndarray) -> None:
        """Heads for `target` [J] (rad), to arrive there moving at `velocity` [J] (rad/s, clipped to the speed
        limits), `arrival` seconds from now or as soon after as the limits allow. Ignored once holding."""
        if self.holding:
            return
        self._input.target_position = np.asarray(target, np.float64)
        # Ruckig refuses a target speed at the limit's float rounding; 1e-9 below it changes nothing measurable.
        speed = self._speed_limits * (1 - 1e-9)
        self._input.target_velocity = np.clip(velocity, -speed, speed)

    def hold(self) -> None:
        """Brakes to rest where the arm gets to, within the limits: the safe reaction to a missing or late target."""
        self.holding = True
        self._input.control_interface = ruckig.ControlInterface.Velocity
        self._input.target_velocity = np.zeros_like(self._speed_limits)
        self._input.target_acceleration = np.zeros_like(self._speed_limits)
        self._input.minimum_duration = None

    @property
    def at_rest(self) -> bool:
        """Holding, and braked to rest."""
        return self.holding and self._result == ruckig.Result.Finished

    def next(self) -> StreamPoint:
        """The next servo tick's setpoint; `StreamError` where Ruckig finds no trajectory."""
        self._result = self._generator.update(self._input, self._output)
        if self._result not in (ruckig.Result.Working, ruckig.Result.Finished):
            raise StreamError(f"no jerk-limited trajectory to the target ({self._result})")
        self._output.pass_to_input(self._input)
        output = self._output
        return StreamPoint(
            np.array(output.new_position), np.array(output.new_velocity), np.array(output.new_acceleration)
        )


def limit_ratios(
    velocity: np.ndarray, acceleration: np.ndarray, servo_period: float, limits: JointLimits = PANDA.joint_limits
) -> dict[str, np.ndarray]:
    """[J] each joint's largest speed, acceleration and jerk over setpoints' `velocity` and `acceleration` [T, J]
    (the jerk from successive accelerations), as fractions of the arm's `limits`: 1 is at a limit."""
    jerk = np.diff(acceleration, axis=0) / servo_period
    return {
        "speed": np.abs(velocity).max(0) / limits.speed,
        "acceleration": np.abs(acceleration).max(0) / limits.acceleration,
        "jerk": np.abs(jerk).max(0, initial=0.0) / limits.jerk,
    }
