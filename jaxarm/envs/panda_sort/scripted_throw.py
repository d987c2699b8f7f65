"""A hand-written overhead throw for the tosser in `joint` mode with `running_target`: a physics check of how far the
Panda can throw within Franka's joint speed limits.

It starts from an episode with the object held (`held_start_prob` = 1); the tosser's firm grip
(`model.FIRM_GRIP_TIMESTEP`) keeps it in the fingers through the swing (tests/envs/test_panda_sort_tosser.py). The
script moves the joint targets the servos chase along a timed path: a smooth move from the start posture to a
wind-up facing the aimed bin (upper arm leaning back, hand raised behind), then a swing in which the shoulder turns
forward while the elbow and the wrist whip the hand over, each joint's target speeding up to a constant fraction of
its speed limit (`PANDA.joint_limits`); at `release_step` the fingers open and the targets stop. The swing stays in the
vertical plane through the base and the bin, so the release time alone sets the range: the caller chooses it (a
landing moves 0.1-0.4 m per step of release, so a fractional `swing_start` times it finer). Pure JAX: `throw_action`
jits and scans; it reads only the observation and the step count.
"""

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from jaxarm.envs.panda.base import CONTROL_DT
from jaxarm.envs.panda_sort.curriculum import wound_up_posture
from jaxarm.envs.panda_sort.params import PandaSortParams
from jaxarm.robots import PANDA

OPEN, CLOSED = 1.0, -1.0
SWING_SPEEDS = np.array([0.0, 0.9, 0.0, -0.9, 0.0, -0.55, 0.0], np.float32)
"""Top speed of each joint's target in the swing, as a signed fraction of its limit: the shoulder turning forward,
the elbow and the wrist folding the hand over. Every joint at 0.9 scored 5 of 8 held throws while the wrist's servo
saturated (panda.xml before its gains were lowered; 0.8 threw short, 1.0 long). With the wrist following its target
as the shoulder does, 0.9 at the wrist threw all 8 long by 0.34-0.47 m (release at step 82), 0.5 short by
0.03-0.16 m; 0.55 scores 7 (0.6: 8, but only 2 of 8 wound-up throws against 0.55's 4)."""
SWING_RAMP_S = 0.3
"""Seconds over which the swing's target speeds rise from rest to the top: a step to full speed saturated
the shoulder's servo, which then overshot to 2.85 rad/s against the 1.74 asked."""
TURNING = np.array([0, 6])
"""The joints that turn first: the base towards the bin, and the hand so that the pads face along the swing."""
TURN_STEPS = 28
"""Steps of that turn."""
WIND_UP_STEPS = 68
"""Steps to the end of the wind-up: the peak joint speed of each smooth move (1.5 times its mean) stays under
the limits."""


@struct.dataclass
class Throw:
    """A planned throw, timed in env steps from the reset.

    Attributes:
      start: [7] arm posture at the reset (radians).
      wind_up: [7] arm posture to wind up to (radians).
      swing_velocity: [7] top speed of the joint targets in the swing (rad/s).
      swing_start: [] when the swing starts (steps; fractional to time the release finer than a step).
      release_step: [] int32, the step whose action opens the fingers and stops the targets.
    """

    start: jax.Array
    wind_up: jax.Array
    swing_velocity: jax.Array
    swing_start: jax.Array
    release_step: jax.Array


def aimed_throw(start: np.ndarray, bin_xy: np.ndarray, swing_start: float, release_step: int) -> Throw:
    """The throw from arm posture `start` [7] towards a bin at `bin_xy` [2]: the base turned to face it."""
    return Throw(
        start=jnp.asarray(start, jnp.float32),
        wind_up=wound_up_posture(jnp.asarray(bin_xy, jnp.float32)),
        swing_velocity=jnp.asarray(SWING_SPEEDS * PANDA.joint_limits.speed),
        swing_start=jnp.float32(swing_start),
        release_step=jnp.int32(release_step),
    )


def smoothstep(fraction: jax.Array) -> jax.Array:
    """[] fraction of a move's time -> fraction of its way, starting and ending at rest (0 before, 1 after)."""
    fraction = jnp.clip(fraction, 0.0, 1.0)
    return fraction**2 * (3.0 - 2.0 * fraction)


def planned_targets(throw: Throw, step: jax.Array) -> jax.Array:
    """[7] joint targets of the plan at `step` (steps from the reset, float []): wind-up, then swing."""
    # The base and the hand turn first, so the arm then pitches about an axis in the pads' plane.
    turned = throw.start.at[TURNING].set(throw.wind_up[TURNING])
    turn = (turned - throw.start) * smoothstep(step / TURN_STEPS)
    lean = (throw.wind_up - turned) * smoothstep((step - TURN_STEPS) / (WIND_UP_STEPS - TURN_STEPS))
    posture = throw.start + turn + lean
    # Seconds into the swing, frozen at the release; the target speed rises linearly over the ramp.
    swing_s = jnp.clip(step - throw.swing_start, 0.0, throw.release_step - throw.swing_start) * CONTROL_DT
    travel = jnp.where(swing_s < SWING_RAMP_S, swing_s**2 / (2 * SWING_RAMP_S), swing_s - SWING_RAMP_S / 2)
    return posture + throw.swing_velocity * travel


def servo_targets(obs: jax.Array) -> jax.Array:
    """[O] observation of a `running_target` env -> [7] the joint targets the servos chase: it ends with the arm's
    joint angles and then each servo's lead (`PandaSort._observe`)."""
    lead = len(PANDA.arm_joints)
    return obs[-2 * lead : -lead] + obs[-lead:]


def throw_action(obs: jax.Array, step: jax.Array, throw: Throw, params: PandaSortParams) -> jax.Array:
    """[8] action of env step `step` (int32 []): the servos' targets onto the plan's next ones, fingers closed
    until the release."""
    move = planned_targets(throw, step + 1.0) - servo_targets(obs)
    fingers = jnp.where(step < throw.release_step, CLOSED, OPEN)
    return jnp.append(jnp.clip(move / params.joint_step, -1.0, 1.0), fingers)
