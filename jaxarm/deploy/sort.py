"""The sorter (`panda_sort`) next to a robot: its state observation (and its tool part, a camera policy's proprio)
and its controller in numpy, the same formulas as `jaxarm.envs.panda_sort.env` (tests/deploy/test_controller.py
holds them to 1e-5), and which objects are still in play. Imports numpy and mujoco alone.

The env parks an object once it is scored and observes it as zeros; here an object leaves play when its
estimated centre enters a bin or drops off the table (`scoring.next_outcome`), and is observed as zeros after.

J is the arm's joint count (`ArmKinematics.joints`); the servo targets `ctrl` [J + 2] are the arm joints' then the
two fingers' (`loop`).
"""

import dataclasses

import numpy as np

from jaxarm.deploy import ik, scoring
from jaxarm.deploy.kinematics import ArmKinematics, ArmPose
from jaxarm.deploy.reading import ArmReading, ObjectEstimate

MODE_EE = "ee"
MODE_JOINT = "joint"


@dataclasses.dataclass(frozen=True)
class SortTask:
    """What the sorter's observation and control need to know, as plain numbers
    (`jaxarm.deployable.panda_sort.sort_task` reads them from an env and its params; the env's docstrings say what
    each means).

    Attributes:
      objects_count, control_mode, running_target, target_first: the env's constructor arguments.
      ee_step, ee_yaw_step, joint_step, max_lead, max_yaw_lead, max_joint_lead: the env params of those names.
      ik_damping, ik_posture_gain, carry_height: the env params of those names.
      start_qpos: [J] the arm's start posture, towards which the IK's null space pulls.
      home_tcp_rotation: [3, 3] the tool's orientation at yaw 0, pointing down.
      bins: where the bins are (scoring.Bins).
      tcp_min_z: lowest tool-centre target (m).
      finger_open: each finger's travel when fully open (m).
    """

    objects_count: int
    control_mode: str
    running_target: bool
    target_first: bool
    ee_step: float
    ee_yaw_step: float
    joint_step: float
    max_lead: float
    max_yaw_lead: float
    max_joint_lead: float
    ik_damping: float
    ik_posture_gain: float
    carry_height: float
    start_qpos: np.ndarray
    home_tcp_rotation: np.ndarray
    bins: scoring.Bins
    tcp_min_z: float
    finger_open: float

    @property
    def action_size(self) -> int:
        """The tool's step and yaw turn in `ee` mode, or each arm joint's step in `joint` mode; then the gripper."""
        return 5 if self.control_mode == MODE_EE else len(self.start_qpos) + 1


def slot_order(task: SortTask, target: int) -> np.ndarray:
    """[N] the object slots in the order the observation lists them: from the target on with `target_first`."""
    slots = np.arange(task.objects_count)
    return (target + slots) % task.objects_count if task.target_first else slots


def observation(
    task: SortTask,
    pose: ArmPose,
    reading: ArmReading,
    objects: ObjectEstimate,
    outcome: np.ndarray,
    target: int,
    ctrl: np.ndarray,
) -> np.ndarray:
    """float32 [26 N + 14 + J] ([+J] with `running_target`): the env's state observation (`PandaSort._observe`) of
    the arm at `pose` (its posture `reading.arm_q`), `objects` with outcomes [N], the `target` slot, and the servos'
    targets `ctrl` [J + 2]."""
    in_play = (outcome == scoring.IN_PLAY)[:, None]
    position = objects.pose[:, :3]
    relative_yaw = ik.yaw_of_quaternion(objects.pose[:, 3:]) - ik.yaw_of_rotation(pose.tcp_rotation)
    shapes = len(task.bins.centres)
    rows = np.concatenate(
        [
            objects.pose,
            objects.velocity,
            np.eye(shapes)[objects.shape],
            objects.size[:, None],
            in_play,
            position - pose.tcp,
            scoring.carry_targets(task.bins, objects.shape, task.carry_height) - position,
            np.cos(4.0 * relative_yaw)[:, None],
            np.sin(4.0 * relative_yaw)[:, None],
        ],
        -1,
    )
    rows = rows * in_play
    tool = tool_observation(task, pose, reading, ctrl)
    return np.concatenate([rows[slot_order(task, target)].ravel(), tool]).astype(np.float32)


def tool_observation(task: SortTask, pose: ArmPose, reading: ArmReading, ctrl: np.ndarray) -> np.ndarray:
    """float32 [14 + J] ([14 + 2 J] with `running_target`): the tool's part of `observation`, which a camera policy
    reads as its proprio part: tool centre, hand orientation, tool velocity, gripper width, arm joints (and each
    joint's servo target `ctrl` [J + 2] minus its angle)."""
    tool = [pose.tcp, pose.hand_quat, pose.jacobian @ reading.arm_qvel, [np.sum(reading.finger_q)], reading.arm_q]
    if task.running_target:
        tool.append(ctrl[: len(reading.arm_q)] - reading.arm_q)
    return np.concatenate(tool).astype(np.float32)


def arm_targets(
    task: SortTask, kinematics: ArmKinematics, pose: ArmPose, ctrl: np.ndarray, action: np.ndarray
) -> np.ndarray:
    """[J] arm joint targets for `action` [A] from the arm measured at `pose` and the servos' targets `ctrl` [J + 2]:
    `PandaSort._arm_targets`."""
    limits, arm = kinematics.arm_limits, slice(kinematics.joints)
    if task.control_mode == MODE_JOINT:
        if task.running_target:
            joints = ik.advanced_target(ctrl[arm], action[arm] * task.joint_step, pose.arm_q, task.max_joint_lead)
        else:
            joints = pose.arm_q + action[arm] * task.joint_step
        return np.clip(joints, limits[:, 0], limits[:, 1])
    yaw = ik.yaw_of_rotation(pose.tcp_rotation)
    if task.running_target:
        # IK from where the servos are taking the tool, as the env's running target does.
        pose_from = kinematics.pose(ctrl[arm])
        target = ik.advanced_target(pose_from.tcp, action[:3] * task.ee_step, pose.tcp, task.max_lead)
        turn = ik.wrapped_angle(ik.yaw_of_rotation(pose_from.tcp_rotation) + action[3] * task.ee_yaw_step - yaw)
        target_yaw = yaw + np.clip(turn, -task.max_yaw_lead, task.max_yaw_lead)
    else:
        pose_from = pose
        target = pose.tcp + action[:3] * task.ee_step
        target_yaw = yaw + action[3] * task.ee_yaw_step
    target[2] = max(target[2], task.tcp_min_z)
    rotation = ik.rotation_about_z(target_yaw) @ task.home_tcp_rotation
    gains = (task.ik_damping, task.ik_posture_gain, task.start_qpos)
    if task.running_target:
        return ik.servo_ik_targets(kinematics, pose_from, target, rotation, *gains)
    return ik.ik_arm_targets(pose_from, target, rotation, *gains, limits)


def finger_targets(task: SortTask, action: np.ndarray) -> np.ndarray:
    """[2] each finger's target: the action's last entry maps [-1, 1] to closed..open."""
    return np.full(2, (action[-1] + 1.0) * (task.finger_open / 2))


class SortController:
    """The sorter's observation and control at a robot, with what it tracks over an episode: which objects are
    still in play and which one is the target.

    Attributes:
      task: the task's numbers.
      kinematics: the arm's kinematic model.
      outcome: [N] each object's `scoring` outcome, from the estimates.
      target: the slot being worked on (the observation lists it first with `target_first`).
    """

    def __init__(self, task: SortTask, kinematics: ArmKinematics):
        self.task = task
        self.kinematics = kinematics
        self.outcome = np.full(task.objects_count, scoring.IN_PLAY)
        self.target = -1
        self._pose: ArmPose | None = None

    @property
    def action_size(self) -> int:
        return self.task.action_size

    def begin(self) -> None:
        """A new episode: every object in play, the target chosen at the first observation."""
        self.outcome = np.full(self.task.objects_count, scoring.IN_PLAY)
        self.target = -1

    def observe(self, reading: ArmReading, objects: ObjectEstimate, ctrl: np.ndarray) -> np.ndarray:
        """The observation at this tick; scores the estimated objects first, as the env does after a step."""
        self._pose = self.kinematics.pose(reading.arm_q)
        position = objects.pose[:, :3]
        self.outcome = scoring.next_outcome(self.outcome, objects.shape, position, self.task.bins)
        self.target = scoring.next_target(self.outcome, self.target, position, self._pose.tcp)
        return observation(self.task, self._pose, reading, objects, self.outcome, self.target, ctrl)

    def proprio(self, reading: ArmReading, ctrl: np.ndarray) -> np.ndarray:
        """A camera policy's proprio part at this tick (`tool_observation`), in place of `observe`."""
        self._pose = self.kinematics.pose(reading.arm_q)
        return tool_observation(self.task, self._pose, reading, ctrl)

    def act(self, reading: ArmReading, ctrl: np.ndarray, action: np.ndarray) -> np.ndarray:
        """[J + 2] servo targets (arm, then fingers) for `action`, after `observe` (or `proprio`) of the same tick."""
        assert self._pose is not None, "observe before act"
        arm = arm_targets(self.task, self.kinematics, self._pose, ctrl, action)
        return np.concatenate([arm, finger_targets(self.task, action)])
