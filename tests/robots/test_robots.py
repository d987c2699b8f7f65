"""The robot registry, and each robot's description read against its own model files (MuJoCo C only, no JAX
program): every name it declares is in both models, and its gripper travel and home posture agree with them."""

import re
from pathlib import Path

import numpy as np
import pytest

from jaxarm.envs.peg_insert.model import build_model
from jaxarm.robots import PANDA, ROBOTS, UR5E, robot


def test_the_registry_finds_each_robot_by_its_name():
    assert robot("panda") is PANDA and robot("ur5e") is UR5E
    assert all(robot(name).name == name for name in ROBOTS)
    with pytest.raises(ValueError, match="known: panda, ur5e"):
        robot("ur10")


@pytest.mark.parametrize("name", sorted(ROBOTS))
def test_the_descriptions_arrays_are_read_only(name):
    limits = robot(name).joint_limits
    for array in (robot(name).home_qpos, limits.speed, limits.acceleration, limits.jerk):
        assert array.dtype == np.float32 and not array.flags.writeable


@pytest.mark.parametrize("model_file", ["model_xml", "menagerie_xml"])
@pytest.mark.parametrize("name", sorted(ROBOTS))
def test_each_description_names_what_its_models_hold(name, model_file):
    description = robot(name)
    model = build_model(robot=name, robot_xml=getattr(description, model_file))
    joints = len(description.arm_joints)
    # The arm first, then the fingers: a ctrl vector is the arm's targets, then the fingers'.
    assert [model.joint(name).qposadr[0] for name in description.arm_joints] == list(range(joints))
    assert [model.actuator(name).id for name in description.arm_actuators] == list(range(joints))
    arm_ranges = np.stack([model.joint(name).range for name in description.arm_joints])
    assert np.all((arm_ranges[:, 0] <= description.home_qpos) & (description.home_qpos <= arm_ranges[:, 1]))
    assert [model.actuator(name).trnid[0] for name in description.arm_actuators] == [
        model.joint(name).id for name in description.arm_joints
    ]
    limits = description.joint_limits
    assert len(limits.speed) == len(limits.acceleration) == len(limits.jerk) == joints
    assert len(description.identified_links) == len(description.home_qpos) == joints
    for name in description.finger_joints:
        assert model.joint(name).range[1] == pytest.approx(description.finger_open)
    actuators = {model.actuator(k).name for k in range(model.nu)}
    assert sum(set(drive) <= actuators for drive in description.finger_drives) == 1
    # KeyError if absent
    assert model.site(description.tcp_site).id >= 0 and model.body(description.hand_body).id >= 0


def test_the_readme_shows_the_registry_line_a_new_robot_extends():
    root = Path(__file__).resolve().parents[2]
    shown = re.search(r"```python\n\s*(ROBOTS = .*)\n", (root / "README.md").read_text())
    assert shown is not None
    assert shown.group(1).replace(", YOUR_ARM", "") in (root / "jaxarm" / "robots" / "__init__.py").read_text()
