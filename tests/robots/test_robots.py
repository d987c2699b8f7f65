"""The robot registry, and the Panda's description read against its own model files (MuJoCo C only, no JAX program):
every name it declares is in both models, and its gripper travel and home posture agree with them."""

import numpy as np
import pytest

from jaxarm.envs.peg_insert.model import build_model
from jaxarm.robots import PANDA, ROBOTS, robot


def test_the_registry_finds_each_robot_by_its_name():
    assert robot("panda") is PANDA
    assert all(robot(name).name == name for name in ROBOTS)
    with pytest.raises(ValueError, match="known: panda"):
        robot("ur5e")


def test_the_descriptions_arrays_are_read_only():
    for array in (PANDA.home_qpos, PANDA.joint_limits.speed, PANDA.joint_limits.acceleration, PANDA.joint_limits.jerk):
        assert array.dtype == np.float32 and not array.flags.writeable


@pytest.mark.parametrize("robot_xml", [PANDA.model_xml, PANDA.menagerie_xml], ids=["jaxarm", "menagerie"])
def test_the_panda_description_names_what_its_models_hold(robot_xml):
    model = build_model(robot_xml=robot_xml)
    arm_ranges = np.stack([model.joint(name).range for name in PANDA.arm_joints])
    assert np.all((arm_ranges[:, 0] <= PANDA.home_qpos) & (PANDA.home_qpos <= arm_ranges[:, 1]))
    assert [model.actuator(name).trnid[0] for name in PANDA.arm_actuators] == [
        model.joint(name).id for name in PANDA.arm_joints
    ]
    assert len(PANDA.joint_limits.speed) == len(PANDA.arm_joints) == len(PANDA.identified_links)
    for name in PANDA.finger_joints:
        assert model.joint(name).range[1] == pytest.approx(PANDA.finger_open)
    actuators = {model.actuator(k).name for k in range(model.nu)}
    assert sum(set(drive) <= actuators for drive in PANDA.finger_drives) == 1
    assert model.site(PANDA.tcp_site).id >= 0 and model.body(PANDA.hand_body).id >= 0  # KeyError if absent
