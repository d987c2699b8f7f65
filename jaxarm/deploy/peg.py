"""The peg insertion (`peg_insert`) next to a robot: its state observation (and its arm part, a camera policy's
proprio) and controller in numpy, the same formulas as `jaxarm.envs.peg_insert.env` (tests/deploy/test_controller.py
holds them to 1e-5). Imports numpy and mujoco alone.

J is the arm's joint count (`ArmKinematics.joints`); the servo targets `ctrl` [J + F] are the arm joints' then the
fingers' (`loop`)."""

import dataclasses

import numpy as np

from jaxarm.deploy import ik
from jaxarm.deploy.kinematics import ArmKinematics, ArmPose
from jaxarm.deploy.reading import ArmReading, HoleEstimate

PEG_TIP_SITE = "peg_tip"


@dataclasses.dataclass(frozen=True)
class PegTask:
    """What the peg's observation and control need to know, as plain numbers
    (`jaxarm.deployable.peg_insert.peg_task` reads them).

    Attributes:
      running_target: the env's constructor argument.
      ee_step, max_lead, ik_damping, ik_posture_gain: the env params of those names.
      start_qpos: [J] the arm's start posture, towards which the IK's null space pulls.
      home_tcp_rotation: [3, 3] the tool's orientation, pointing down, held throughout.
      hole_nominal: [2] (x, y) of the hole before its per-episode shift.
      hole_floor: height of the hole's bottom above the table (m).
      position_scale: metres per observation unit.
    """

    running_target: bool
    ee_step: float
    max_lead: float
    ik_damping: float
    ik_posture_gain: float
    start_qpos: np.ndarray
    home_tcp_rotation: np.ndarray
    hole_nominal: np.ndarray
    hole_floor: float
    position_scale: float

    @property
    def action_size(self) -> int:
        return 3


def observation(
    task: PegTask, kinematics: ArmKinematics, pose: ArmPose, reading: ArmReading, hole: HoleEstimate, tcp_target
) -> np.ndarray:
    """float32 [12]: `PegInsert._observe` of the arm at `pose` (the last one `kinematics` posed), the hole's
    estimate and the tool-centre target [3]."""
    tip, _ = kinematics.site_position_jacobian(PEG_TIP_SITE)
    hole_bottom = np.concatenate([hole.centre, [task.hole_floor]])
    own = arm_observation(task, kinematics, pose, reading, tcp_target)
    return np.concatenate([(hole_bottom - tip) / task.position_scale, own]).astype(np.float32)


def arm_observation(
    task: PegTask, kinematics: ArmKinematics, pose: ArmPose, reading: ArmReading, tcp_target
) -> np.ndarray:
    """float32 [9]: the arm's own part of `observation`, which a camera policy reads as its proprio part: the tip's
    velocity, the tool's lead towards its target [3] and the tip's offset from the nominal hole."""
    tip, tip_jacobian = kinematics.site_position_jacobian(PEG_TIP_SITE)
    nominal = np.concatenate([task.hole_nominal, [task.hole_floor]])
    return np.concatenate(
        [
            tip_jacobian @ reading.arm_qvel / task.position_scale,
            (tcp_target - pose.tcp) / task.max_lead,
            (tip - nominal) / task.position_scale,
        ]
    ).astype(np.float32)


def arm_targets(
    task: PegTask,
    kinematics: ArmKinematics,
    pose: ArmPose,
    tcp_target: np.ndarray,
    ctrl: np.ndarray,
    action: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """`action` [3] -> (the next tool-centre target [3], the arm's joint targets [J]) from the arm measured at
    `pose`, the running target `tcp_target` [3] and the servos' targets `ctrl` [J + F], the tool pointing down:
    `PegInsert._arm_targets`."""
    step = action * task.ee_step
    gains = (task.ik_damping, task.ik_posture_gain, task.start_qpos)
    if task.running_target:
        servo_pose = kinematics.pose(ctrl[: kinematics.joints])
        target = ik.advanced_target(servo_pose.tcp, step, pose.tcp, task.max_lead)
        return target, ik.servo_ik_targets(kinematics, servo_pose, target, task.home_tcp_rotation, *gains)
    target = ik.advanced_target(tcp_target, step, pose.tcp, task.max_lead)
    return target, ik.ik_arm_targets(pose, target, task.home_tcp_rotation, *gains, kinematics.arm_limits)


class PegController:
    """The peg's observation and control at a robot, with the running tool-centre target it keeps.

    Attributes:
      task, kinematics: as given.
      tcp_target: [3] where the tool centre is being driven (the measured tool centre at the episode's start).
    """

    def __init__(self, task: PegTask, kinematics: ArmKinematics):
        self.task = task
        self.kinematics = kinematics
        self.tcp_target: np.ndarray | None = None
        self._pose: ArmPose | None = None

    @property
    def action_size(self) -> int:
        return self.task.action_size

    def begin(self) -> None:
        """A new episode: the target is set to the measured tool centre at the first observation."""
        self.tcp_target = None

    def _sense(self, reading: ArmReading) -> tuple[ArmPose, np.ndarray]:
        """The arm's pose at `reading` and the running target (the tool centre at an episode's first tick)."""
        self._pose = self.kinematics.pose(reading.arm_q)
        if self.tcp_target is None:
            self.tcp_target = self._pose.tcp
        return self._pose, self.tcp_target

    def observe(self, reading: ArmReading, hole: HoleEstimate, ctrl: np.ndarray) -> np.ndarray:
        pose, target = self._sense(reading)
        return observation(self.task, self.kinematics, pose, reading, hole, target)

    def proprio(self, reading: ArmReading, ctrl: np.ndarray) -> np.ndarray:
        """A camera policy's proprio part at this tick (`arm_observation`), in place of `observe`."""
        pose, target = self._sense(reading)
        return arm_observation(self.task, self.kinematics, pose, reading, target)

    def act(self, reading: ArmReading, ctrl: np.ndarray, action: np.ndarray) -> np.ndarray:
        """[J + F] servo targets: the arm's towards the moved target, the fingers' as they were."""
        assert self._pose is not None and self.tcp_target is not None, "observe before act"
        self.tcp_target, arm = arm_targets(self.task, self.kinematics, self._pose, self.tcp_target, ctrl, action)
        return np.concatenate([arm, ctrl[self.kinematics.joints :]])
