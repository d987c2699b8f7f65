"""The Panda's `dynamics="identified"` option: the compiled arm carries Franka's table (`PANDA.identified_links`), its
joint-space inertia is the one that table implies, and nothing but the dynamics changed.

MuJoCo C models only (the builders cache them) and no MJX program: the whole file runs in seconds on a CPU.
"""

import copy
from collections.abc import Callable

import mujoco
import numpy as np
import pytest

from jaxarm import envs
from jaxarm.envs.panda.dynamics import IDENTIFIED, NOMINAL
from jaxarm.envs.panda_sort.layout import make_layout
from jaxarm.envs.panda_sort.model import build_model as build_sorter
from jaxarm.envs.peg_insert.model import build_model as build_peg
from jaxarm.robots import PANDA

SCENES: dict[str, Callable[[str], mujoco.MjModel]] = {
    "panda_sort": lambda dynamics: build_sorter(1, make_layout(), dynamics),
    "peg_insert": lambda dynamics: build_peg(dynamics=dynamics),
}
"""Each Panda task's scene builder, by registered env name, as a function of the robot's dynamics."""
UNCHANGED = (
    "body_pos",
    "body_quat",
    "jnt_type",
    "jnt_axis",
    "jnt_pos",
    "jnt_range",
    "dof_armature",
    "geom_type",
    "geom_size",
    "geom_pos",
    "geom_quat",
    "geom_contype",
    "geom_conaffinity",
    "geom_friction",
    "site_pos",
    "site_quat",
    "actuator_gainprm",
    "actuator_biasprm",
    "actuator_ctrlrange",
    "actuator_forcerange",
    "pair_geom1",
    "pair_geom2",
    "pair_friction",
)
"""MjModel fields of the kinematics, the collision set and the actuators, which the option must leave alone."""


@pytest.fixture(scope="module", params=sorted(SCENES))
def models(request) -> tuple[mujoco.MjModel, mujoco.MjModel]:
    """(nominal, identified: Franka's) compiled scene of one task."""
    build = SCENES[request.param]
    return build(NOMINAL), build(IDENTIFIED)


def link_bodies(model: mujoco.MjModel) -> list[int]:
    """Body ids of links 1..7, in `PANDA.identified_links` order: each is the body its arm joint moves."""
    return [int(model.jnt_bodyid[model.joint(name).id]) for name in PANDA.arm_joints]


def arm_dofs(model: mujoco.MjModel, joints=PANDA.arm_joints) -> np.ndarray:
    return np.array([model.joint(name).dofadr[0] for name in joints])


def inertia_tensor(inertia) -> np.ndarray:
    """[6] (Ixx, Iyy, Izz, Ixy, Ixz, Iyz) -> [3, 3] symmetric tensor."""
    xx, yy, zz, xy, xz, yz = inertia
    return np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])


def quat_to_matrix(quat: np.ndarray) -> np.ndarray:
    """[4] (w, x, y, z) -> [3, 3] rotation."""
    matrix = np.zeros(9)
    mujoco.mju_quat2Mat(matrix, quat)
    return matrix.reshape(3, 3)


def random_postures(model: mujoco.MjModel, count: int, seed: int = 0) -> np.ndarray:
    """[count, 7] arm postures drawn uniformly within the joint limits."""
    limits = model.jnt_range[[model.joint(name).id for name in PANDA.arm_joints]]
    return np.random.default_rng(seed).uniform(limits[:, 0], limits[:, 1], size=(count, len(PANDA.arm_joints)))


def posed(model: mujoco.MjModel, arm_q: np.ndarray, forward: bool = False) -> mujoco.MjData:
    """MjData with the arm at `arm_q` [7], after mj_kinematics (or mj_forward when `forward`)."""
    data = mujoco.MjData(model)
    data.qpos[[model.joint(name).qposadr[0] for name in PANDA.arm_joints]] = arm_q
    (mujoco.mj_forward if forward else mujoco.mj_kinematics)(model, data)
    return data


def without_hand(model: mujoco.MjModel) -> mujoco.MjModel:
    """A copy of `model` whose hand, fingers and whatever they hold weigh nothing: the arm of the table alone."""
    hand = model.body("hand").id
    lightened = copy.copy(model)
    for body in range(model.nbody):
        ancestor = body
        while ancestor not in (0, hand):
            ancestor = model.body_parentid[ancestor]
        if ancestor == hand:
            lightened.body_mass[body] = 0.0
            lightened.body_inertia[body] = 0.0
    return lightened


def arm_inertia(model: mujoco.MjModel, arm_q: np.ndarray) -> np.ndarray:
    """[7, 7] joint-space inertia of the arm's dofs from mj_fullM after mj_forward."""
    data = posed(model, arm_q, forward=True)
    full = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, full)
    dofs = arm_dofs(model)
    return full[np.ix_(dofs, dofs)]


def table_arm_inertia(model: mujoco.MjModel, arm_q: np.ndarray) -> np.ndarray:
    """[7, 7] joint-space inertia of the bare arm computed here from `PANDA.identified_links` and the joints' world
    axes and anchors alone: the sum over links of m Jvᵀ Jv + Jωᵀ (R I Rᵀ) Jω, plus each joint's armature."""
    data = posed(model, arm_q)
    joints = [model.joint(name).id for name in PANDA.arm_joints]
    axes, anchors = data.xaxis[joints], data.xanchor[joints]
    inertia = np.diag(model.dof_armature[arm_dofs(model)])
    for index, (link, body) in enumerate(zip(PANDA.identified_links, link_bodies(model), strict=True)):
        rotation = data.xmat[body].reshape(3, 3)
        com = data.xpos[body] + rotation @ np.array(link.com)
        # A serial chain: the link moves with joints 1..index+1 and no others.
        moving = slice(0, index + 1)
        linear, angular = np.zeros((3, 7)), np.zeros((3, 7))
        angular[:, moving] = axes[moving].T
        linear[:, moving] = np.cross(axes[moving], com - anchors[moving]).T
        tensor = rotation @ inertia_tensor(link.inertia) @ rotation.T
        inertia += link.mass * linear.T @ linear + angular.T @ tensor @ angular
    return inertia


def test_links_carry_the_published_mass_centre_of_mass_and_inertia(models):
    _, franka = models
    for link, body in zip(PANDA.identified_links, link_bodies(franka), strict=True):
        assert franka.body_mass[body] == pytest.approx(link.mass, rel=1e-12)
        np.testing.assert_allclose(franka.body_ipos[body], link.com, atol=1e-12)
        # MuJoCo keeps a full tensor as principal moments and the rotation to their axes.
        rotation = quat_to_matrix(franka.body_iquat[body])
        in_body_frame = rotation @ np.diag(franka.body_inertia[body]) @ rotation.T
        np.testing.assert_allclose(in_body_frame, inertia_tensor(link.inertia), atol=1e-9)


def test_arm_joints_carry_the_identified_damping_and_friction_loss(models):
    nominal, franka = models
    dofs = arm_dofs(franka)
    np.testing.assert_array_equal(franka.dof_damping[dofs], [link.damping for link in PANDA.identified_links])
    np.testing.assert_array_equal(franka.dof_frictionloss[dofs], [link.frictionloss for link in PANDA.identified_links])
    fingers = arm_dofs(franka, PANDA.finger_joints)
    np.testing.assert_array_equal(franka.dof_damping[fingers], nominal.dof_damping[fingers])
    np.testing.assert_array_equal(franka.dof_frictionloss[fingers], nominal.dof_frictionloss[fingers])


def test_kinematics_collisions_actuators_and_the_hand_are_unchanged(models):
    nominal, franka = models
    for field in UNCHANGED:
        np.testing.assert_array_equal(getattr(franka, field), getattr(nominal, field), err_msg=field)
    others = np.setdiff1d(np.arange(nominal.nbody), link_bodies(nominal))
    for field in ("body_mass", "body_ipos", "body_iquat", "body_inertia"):
        np.testing.assert_array_equal(getattr(franka, field)[others], getattr(nominal, field)[others], err_msg=field)


def test_postures_put_every_body_and_site_where_the_nominal_model_does(models):
    nominal, franka = models
    for arm_q in random_postures(nominal, 5):
        expected, actual = posed(nominal, arm_q), posed(franka, arm_q)
        np.testing.assert_allclose(actual.xpos, expected.xpos, atol=1e-9)
        np.testing.assert_allclose(actual.xmat, expected.xmat, atol=1e-9)
        np.testing.assert_allclose(actual.site_xpos, expected.site_xpos, atol=1e-9)


def test_joint_space_inertia_is_the_one_the_table_implies(models):
    nominal, franka = models
    bare_nominal, bare_franka = without_hand(nominal), without_hand(franka)
    armature = franka.dof_armature[arm_dofs(franka)]
    for arm_q in random_postures(franka, 3, seed=1):
        inertia = arm_inertia(bare_franka, arm_q)
        np.testing.assert_allclose(inertia, inertia.T, atol=1e-12)
        assert np.linalg.eigvalsh(inertia).min() > 0.0
        np.testing.assert_allclose(inertia, table_arm_inertia(franka, arm_q), atol=1e-9)
        # What the option is for: the capsules' wrist inertia is several times too small.
        wrist = np.diag(inertia)[-1] - armature[-1]
        assert np.diag(arm_inertia(bare_nominal, arm_q))[-1] - armature[-1] < wrist / 2


@pytest.mark.parametrize("name", sorted(SCENES))
def test_the_env_option_builds_its_scene_with_identified_dynamics_and_defaults_to_nominal(name):
    franka_env, default_env = envs.make(name, dynamics=IDENTIFIED), envs.make(name)
    dofs = arm_dofs(franka_env.mj_model)
    frictionloss = [link.frictionloss for link in PANDA.identified_links]
    np.testing.assert_array_equal(franka_env.mj_model.dof_frictionloss[dofs], frictionloss)
    np.testing.assert_array_equal(default_env.mj_model.body_mass, SCENES[name](NOMINAL).body_mass)
    np.testing.assert_array_equal(default_env.mj_model.dof_frictionloss, 0.0)


@pytest.mark.parametrize("name", sorted(SCENES))
def test_an_unknown_dynamics_is_refused_naming_the_choices(name):
    with pytest.raises(ValueError, match="dynamics must be one of nominal, identified, got 'identify'"):
        envs.make(name, dynamics="identify")
