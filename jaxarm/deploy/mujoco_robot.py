"""Stock MuJoCo as the robot: a scene stepped by MuJoCo's C engine (`mujoco.mj_step`), read and commanded only as
a robot's controller would be (joints, gripper, servo targets). Imports numpy and mujoco alone.

J and F are the arm's joint and finger counts (its description's `arm_joints` and `finger_joints`).

The scene keeps its own timestep, integrator and contact settings; the constraint solver gets MuJoCo's defaults
(`stock_solver`), not the few iterations the MJX scenes are tuned to for speed.
"""

import mujoco
import numpy as np

from jaxarm.deploy.reading import ArmReading
from jaxarm.robots import PANDA, RobotDescription

SOLVER_OPTIONS = ("solver", "iterations", "ls_iterations", "tolerance", "ls_tolerance", "noslip_iterations")


def stock_solver(model: mujoco.MjModel) -> dict[str, float]:
    """Sets `model`'s constraint solver options to MuJoCo's defaults (in place); returns them by name."""
    default = mujoco.MjModel.from_xml_string("<mujoco/>").opt
    for name in SOLVER_OPTIONS:
        setattr(model.opt, name, getattr(default, name))
    return {name: float(getattr(default, name)) for name in SOLVER_OPTIONS}


class MujocoRobot:
    """A robot's scene in MuJoCo C, driven one control period at a time (a `loop.Robot`).

    Args:
      model: the scene (a robot with its description's joint and actuator names; its gripper one of the
        description's `finger_drives`).
      period: seconds per control tick; the scene steps `period / timestep` times per tick.
      robot: the description of the robot in the scene (the Panda by default).

    Attributes:
      model, data: the scene and its state.
      joints: J, the arm's joint count.
      substeps: physics steps per tick.
    """

    def __init__(self, model: mujoco.MjModel, period: float, robot: RobotDescription = PANDA):
        self.model = model
        self.data = mujoco.MjData(model)
        self.joints = len(robot.arm_joints)
        self.substeps = int(round(period / model.opt.timestep))
        joints = [model.joint(name) for name in (*robot.arm_joints, *robot.finger_joints)]
        self._qpos = np.array([joint.qposadr[0] for joint in joints])
        self._dof = np.array([joint.dofadr[0] for joint in joints])
        self._arm_actuators = np.array([model.actuator(name).id for name in robot.arm_actuators])
        names = {model.actuator(k).name for k in range(model.nu)}
        drive = next(drive for drive in robot.finger_drives if set(drive) <= names)
        self._finger_actuators = np.array([model.actuator(name).id for name in drive])
        # Command units per metre of finger opening: 1 for a finger's own servo, 255 / 0.04 for menagerie's.
        travel = model.joint(robot.finger_joints[0]).range[1]
        self._finger_scale = model.actuator_ctrlrange[self._finger_actuators, 1] / travel

    def now(self) -> float:
        """The scene's simulated time (s): the robot's clock, which `step` advances by one control period."""
        return float(self.data.time)

    def reading(self) -> ArmReading:
        """What the arm's sensors report now."""
        qpos, qvel = self.data.qpos[self._qpos], self.data.qvel[self._dof]
        joints = self.joints
        return ArmReading(arm_q=qpos[:joints].copy(), arm_qvel=qvel[:joints].copy(), finger_q=qpos[joints:].copy())

    def command(self, ctrl: np.ndarray) -> None:
        """Sends servo targets [J + F]: the arm's joints, then each finger's opening (m)."""
        self.data.ctrl[self._arm_actuators] = ctrl[: self.joints]
        # One drive per finger takes each finger's opening; a single drive for all (menagerie's) takes their mean.
        fingers = ctrl[self.joints :]
        if len(self._finger_actuators) != len(fingers):
            fingers = np.mean(fingers, keepdims=True)
        self.data.ctrl[self._finger_actuators] = fingers * self._finger_scale

    def step(self, after_substep=None) -> None:
        """One control period of physics; `after_substep(data)`, if given, runs after each physics step. The scene's
        poses (bodies, geoms, sites) are left where each step ends."""
        for substep in range(self.substeps):
            mujoco.mj_step(self.model, self.data)
            # mj_step leaves the poses it integrated from, a timestep behind qpos; whoever reads them (scoring, a
            # video) wants the scene as it stands. The next mj_step computes them again from qpos (physics
            # unchanged), so they are posed only where someone reads them: for `after_substep` and at the tick's end.
            if after_substep is not None or substep == self.substeps - 1:
                mujoco.mj_kinematics(self.model, self.data)
            if after_substep is not None:
                after_substep(self.data)
