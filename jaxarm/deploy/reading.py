"""What a robot provides each control tick: its joints and gripper, and estimates of the task's objects. J is the
arm's joint count (its description's `arm_joints`)."""

from typing import NamedTuple

import numpy as np


class ArmReading(NamedTuple):
    """The arm's own sensors at one tick.

    Attributes:
      arm_q: [J] arm joint angles (rad).
      arm_qvel: [J] arm joint speeds (rad/s).
      finger_q: [F] each finger's opening (m; the gripper's width is their sum), F its description's
        `finger_joints`' count (the Panda's 2; none for an arm without a gripper).
    """

    arm_q: np.ndarray
    arm_qvel: np.ndarray
    finger_q: np.ndarray


class ObjectEstimate(NamedTuple):
    """What an object detector reports of the sorter's N objects.

    Attributes:
      pose: [N, 7] centre position (m) and orientation quaternion (w, x, y, z).
      velocity: [N, 6] linear velocity in the world frame and angular velocity in the object's frame.
      shape: [N] int, each object's shape (0 cube, 1 cylinder, 2 sphere: its bin).
      size: [N] half-size or radius (m).
    """

    pose: np.ndarray
    velocity: np.ndarray
    shape: np.ndarray
    size: np.ndarray


class HoleEstimate(NamedTuple):
    """Where the peg's hole is: its centre (x, y) [2] (m)."""

    centre: np.ndarray
