"""The Panda envs' end-effector control maths in numpy: `jaxarm.envs.panda.robot`'s damped least-squares IK, its
orientation error, yaw helpers and running target, the same formulas (tests/deploy/test_controller.py holds the
two to 1e-5). J is the arm's joint count (`ArmKinematics.joints`). Imports numpy alone.
"""

import numpy as np

from jaxarm.deploy.kinematics import ArmKinematics, ArmPose


def damped_least_squares(jacobian: np.ndarray, error: np.ndarray, damping: float) -> tuple[np.ndarray, np.ndarray]:
    """[6, J] Jacobian, [6] task error -> ([J] joint step, [J, J] null-space projector), as `robot.py`'s."""
    gram = jacobian @ jacobian.T + damping**2 * np.eye(jacobian.shape[0])
    solved = np.linalg.solve(gram, np.concatenate([error[:, None], jacobian], axis=1))
    step = jacobian.T @ solved[:, 0]
    projector = np.eye(jacobian.shape[1]) - jacobian.T @ solved[:, 1:]
    return step, projector


def rotation_error(rotation: np.ndarray, target: np.ndarray) -> np.ndarray:
    """[3, 3] current and target rotations -> [3] world-frame axis·angle error (small-angle form)."""
    return 0.5 * np.sum(np.cross(rotation.T, target.T), axis=0)


def yaw_of_rotation(rotation: np.ndarray) -> np.ndarray:
    """[..., 3, 3] rotations -> [...] heading of their x axis in the horizontal plane (radians)."""
    return np.arctan2(rotation[..., 1, 0], rotation[..., 0, 0])


def yaw_of_quaternion(quat: np.ndarray) -> np.ndarray:
    """[..., 4] unit quaternions (w, x, y, z) -> [...] heading of the rotated x axis (radians)."""
    w, x, y, z = np.moveaxis(quat, -1, 0)
    return np.arctan2(2.0 * (x * y + w * z), 1.0 - 2.0 * (y * y + z * z))


def wrapped_angle(angle):
    """[...] angles (radians) -> the same directions in (-pi, pi]."""
    return np.arctan2(np.sin(angle), np.cos(angle))


def rotation_about_z(angle: float) -> np.ndarray:
    """[] angle -> [3, 3] rotation about the vertical."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def advanced_target(chased: np.ndarray, step: np.ndarray, measured: np.ndarray, lead) -> np.ndarray:
    """A running target's next value: `chased` moved by `step`, held within `lead` of `measured` per element."""
    return np.clip(chased + step, measured - lead, measured + lead)


def ik_arm_targets(
    pose: ArmPose,
    tcp_target: np.ndarray,
    tcp_rotation: np.ndarray,
    damping: float,
    posture_gain: float,
    posture: np.ndarray,
    arm_limits: np.ndarray,
) -> np.ndarray:
    """[J] arm joint targets moving the tool centre from `pose` towards `tcp_target` [3] with `tcp_rotation`
    [3, 3]: one damped least-squares step plus `posture_gain` of the way to `posture` [J] in the null space of the
    tool pose, clipped to `arm_limits` [J, 2]."""
    error = np.concatenate([tcp_target - pose.tcp, rotation_error(pose.tcp_rotation, tcp_rotation)])
    step, projector = damped_least_squares(pose.jacobian, error, damping)
    pull = projector @ (posture_gain * (posture - pose.arm_q))
    return np.clip(pose.arm_q + step + pull, arm_limits[:, 0], arm_limits[:, 1])


def servo_ik_targets(
    kinematics: ArmKinematics,
    servo_pose: ArmPose,
    tcp_target: np.ndarray,
    tcp_rotation: np.ndarray,
    damping: float,
    posture_gain: float,
    posture: np.ndarray,
) -> np.ndarray:
    """[J] arm joint targets from the arm posed at its servos' targets (`servo_pose`): `ik_arm_targets`, then a
    second damped step from the first's joints without the posture pull, as `ArmBase.servo_ik_targets`."""
    limits = kinematics.arm_limits
    joints = ik_arm_targets(servo_pose, tcp_target, tcp_rotation, damping, posture_gain, posture, limits)
    return ik_arm_targets(kinematics.pose(joints), tcp_target, tcp_rotation, damping, 0.0, posture, limits)
