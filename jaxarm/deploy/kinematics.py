"""A robot arm's forward kinematics and tool Jacobian with MuJoCo's C library: what the deployment loop's controller
and observation read of the arm's posture. J is the arm's joint count (its description's `arm_joints`). Imports numpy
and mujoco alone (no JAX)."""

from typing import NamedTuple

import mujoco
import numpy as np

from jaxarm.robots import PANDA, RobotDescription


class ArmPose(NamedTuple):
    """The arm at one posture.

    Attributes:
      arm_q: [J] joint angles.
      tcp: [3] tool-centre position.
      tcp_rotation: [3, 3] tool-centre orientation.
      hand_quat: [4] the hand body's orientation (w, x, y, z).
      jacobian: [6, J] the tool centre's linear, then angular, velocity per arm joint speed.
    """

    arm_q: np.ndarray
    tcp: np.ndarray
    tcp_rotation: np.ndarray
    hand_quat: np.ndarray
    jacobian: np.ndarray


class ArmKinematics:
    """Poses a robot's model (any MjModel with the names of its description) at arm postures.

    Only the arm's joints are set; the model's other joints stay at its qpos0 (nothing of the arm's kinematics
    depends on them). One MjData is reused, so an instance is not thread-safe.

    Args:
      model: the model posed.
      robot: the description of the robot in it.

    Attributes:
      model: the model posed.
      robot: the description of the robot in it.
      joints: J, the arm's joint count.
      arm_limits: [J, 2] the arm joints' ranges.
    """

    def __init__(self, model: mujoco.MjModel, robot: RobotDescription = PANDA):
        self.model = model
        self.robot = robot
        self.joints = len(robot.arm_joints)
        self._data = mujoco.MjData(model)
        joints = [model.joint(name) for name in robot.arm_joints]
        self._arm_qpos = np.array([joint.qposadr[0] for joint in joints])
        self._arm_dof = np.array([joint.dofadr[0] for joint in joints])
        self._tcp_site = model.site(robot.tcp_site).id
        self._hand_body = model.body(robot.hand_body).id
        self.arm_limits = np.stack([joint.range for joint in joints])
        self._jacp, self._jacr = np.zeros((3, model.nv)), np.zeros((3, model.nv))

    def pose(self, arm_q: np.ndarray) -> ArmPose:
        """The arm at `arm_q` [J]."""
        data = self._data
        data.qpos[self._arm_qpos] = arm_q
        mujoco.mj_kinematics(self.model, data)
        mujoco.mj_comPos(self.model, data)
        mujoco.mj_jacSite(self.model, data, self._jacp, self._jacr, self._tcp_site)
        return ArmPose(
            arm_q=np.array(arm_q, np.float64),
            tcp=data.site_xpos[self._tcp_site].copy(),
            tcp_rotation=data.site_xmat[self._tcp_site].reshape(3, 3).copy(),
            hand_quat=data.xquat[self._hand_body].copy(),
            jacobian=np.concatenate([self._jacp, self._jacr])[:, self._arm_dof],
        )

    def site_position_jacobian(self, site: str) -> tuple[np.ndarray, np.ndarray]:
        """(position [3], linear Jacobian [3, J] per arm joint speed) of `site` at the last `pose`'s posture."""
        site_id = self.model.site(site).id
        mujoco.mj_jacSite(self.model, self._data, self._jacp, None, site_id)
        return self._data.site_xpos[site_id].copy(), self._jacp[:, self._arm_dof].copy()
