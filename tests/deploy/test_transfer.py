"""`python -m experiments.transfer`: policies run in stock MuJoCo through the deployment loop, on jaxarm's model of
the run's robot and on menagerie's.

The tests of episodes draw their starts with the env's reset (one MJX program: marked mjx); from there only
MuJoCo C and `jaxarm.deploy` run (and MuJoCo's OpenGL renderer, for a camera policy).
"""

import os

os.environ.setdefault("MUJOCO_GL", "egl")  # before mujoco loads a GL: the camera policy's images are drawn

import dataclasses
import json

import mujoco
import numpy as np
import pytest

from experiments import configs, transfer
from experiments.benchmarks.deploy import random_camera_policy, random_policy
from experiments.configs.td3 import td3_peg
from jaxarm import deployable, headless
from jaxarm.agents.common.config import apply_overrides
from jaxarm.deployable import panda_sort
from jaxarm.envs.panda.base import ArmOptions
from jaxarm.envs.panda.robot import resolve_robot_ids, tcp_pose_at
from jaxarm.envs.panda_sort import PandaSort
from jaxarm.envs.panda_sort import model as sort_model
from jaxarm.envs.peg_insert.env import PegInsert
from jaxarm.envs.peg_insert.params import RUNNING_TARGET_MAX_LEAD
from jaxarm.export import origin
from jaxarm.export.numpy_policy import EXPORT_AGAIN
from jaxarm.robots import PANDA, ROBOTS
from jaxarm.runner import rundir
from tests.deploy.exported import export_random_policy, sorter_run


@pytest.mark.parametrize("robot", sorted(ROBOTS))
def test_both_models_of_each_robot_have_the_same_kinematics_and_the_stock_solver(robot):
    env = PegInsert(options=ArmOptions(robot=robot))
    params = env.default_params()
    models = [transfer.plant_model(env, params, name) for name in transfer.MODELS]
    default = mujoco.MjModel.from_xml_string("<mujoco/>").opt
    assert all(model.opt.iterations == default.iterations for model in models)
    jaxarm, menagerie = models
    assert jaxarm.opt.timestep == env.mj_model.opt.timestep
    assert menagerie.opt.timestep == env.robot.menagerie_timestep
    # Menagerie's own dynamics: other link inertias (and the Panda's, another gripper drive).
    first_link = jaxarm.jnt_bodyid[jaxarm.joint(env.robot.arm_joints[1]).id]
    assert not np.allclose(menagerie.body_inertia[first_link], jaxarm.body_inertia[first_link])
    if robot == PANDA.name:
        assert menagerie.nu == jaxarm.nu - 1
    rng = np.random.default_rng(0)
    description = env.robot
    for _ in range(5):
        arm_q = env.start_qpos + rng.uniform(-0.5, 0.5, env.arm_dof)
        (tcp_a, rotation_a), (tcp_b, rotation_b) = (
            tcp_pose_at(m, resolve_robot_ids(m, description), arm_q) for m in models
        )
        np.testing.assert_allclose(tcp_a, tcp_b, atol=1e-9)
        np.testing.assert_allclose(rotation_a, rotation_b, atol=1e-6)


def test_an_env_transfer_does_not_run_is_named_with_those_it_runs(tmp_path, capsys):
    rundir.write_config(tmp_path, configs.get("ppo_arm2d"), "ppo_arm2d")
    assert transfer.main([str(tmp_path)]) == 2
    error = capsys.readouterr().err
    assert f"{tmp_path}'s env is arm2d; transfer runs panda_sort, panda_sort3," in error
    assert error.endswith("panda_sort_tosser, peg_insert, peg_insert_pixels, peg_insert_ur5e\n")


def wrist_step_response(model: mujoco.MjModel, start_qpos: np.ndarray, seconds: float) -> np.ndarray:
    """Joint 7's angle [T] after each physics step of `seconds`, its target stepped 0.1 rad from rest at
    `start_qpos` [7] (the other joints held)."""
    ids = resolve_robot_ids(model, PANDA)
    data = mujoco.MjData(model)
    data.qpos[ids.arm_qpos] = start_qpos
    data.ctrl[ids.arm_actuators] = start_qpos
    data.ctrl[ids.arm_actuators[6]] += 0.1
    angles = []
    for _ in range(round(seconds / model.opt.timestep)):
        mujoco.mj_step(model, data)
        angles.append(data.qpos[ids.arm_qpos[6]])
    return np.array(angles) - start_qpos[6]


def test_menageries_wrist_follows_a_target_step_at_the_plants_timestep():
    env = PandaSort()
    model = transfer.plant_model(env, env.default_params(), "menagerie")
    angle = wrist_step_response(model, env.start_qpos, 0.4)
    np.testing.assert_allclose(angle[-1], 0.1, rtol=0.05)
    # No chatter between its force limits: the joint turns one way, as jaxarm's wrist does at the scene's 0.01 s.
    assert np.all(np.diff(angle) > -1e-5)
    # The scene's timestep is what its servos can not take (the reason for `menagerie_timestep`).
    model.opt.timestep = env.mj_model.opt.timestep
    assert wrist_step_response(model, env.start_qpos, 0.4)[-1] < 0.08


def test_each_pandas_scene_gets_the_episodes_objects_on_its_own_bodies():
    env = PandaSort(objects_count=2)
    params = env.default_params()
    shape, size = np.array([0, 2]), np.array([0.02, 0.03])
    masses = {}
    for name in transfer.MODELS:
        model = transfer.plant_model(env, params, name)
        fingers = model.body("left_finger").mass.copy()
        ids = panda_sort.dress_scene(model, env, params, shape, size, np.zeros((2, 3)))
        assert [model.body(int(body)).name for body in ids.object_body] == ["object0", "object1"]
        masses[name] = model.body_mass[ids.object_body]
        np.testing.assert_array_equal(model.body("left_finger").mass, fingers)
        # The sphere's collision geom has its radius, the cube's box its half-size.
        np.testing.assert_allclose([model.geom("object0_box").size[0], model.geom("object1_sphere").size[0]], size)
    expected = float(params.density) * np.array([8 * 0.02**3, 4 / 3 * np.pi * 0.03**3])
    np.testing.assert_allclose(masses["jaxarm"], expected, rtol=1e-6)
    np.testing.assert_allclose(masses["menagerie"], expected, rtol=1e-6)


def test_the_tossers_scene_with_another_panda_keeps_its_firm_grip():
    for tosser in (False, True):
        env = PandaSort(tosser=tosser)
        scene = deployable.entry(env).scene(env, env.default_params(), PANDA.menagerie_xml)
        assert (scene.opt.timestep == sort_model.FIRM_GRIP_TIMESTEP) == tosser
        assert scene.opt.timestep == env.mj_model.opt.timestep


def scripted_insertion(obs: np.ndarray) -> np.ndarray:
    """Over the hole (the observation's first entries: hole bottom − tip, per 0.1 m) to within 2 mm, then down."""
    xy = np.clip(obs[:2] * 20.0, -1.0, 1.0)
    return np.array([*xy, -1.0 if np.abs(obs[:2]).max() * 0.1 < 0.002 else 0.0])


@pytest.mark.mjx
@pytest.mark.slow
@pytest.mark.parametrize(
    ("robot", "running_target"),
    [(PANDA.name, False), (PANDA.name, True), *((name, True) for name in ROBOTS if name != PANDA.name)],
)
def test_a_scripted_peg_inserts_in_stock_mujoco_with_both_models_of_each_robot(robot, running_target):
    env = PegInsert(running_target=running_target, options=ArmOptions(robot=robot))
    params = env.default_params()
    if running_target:
        params = params.replace(max_lead=RUNNING_TARGET_MAX_LEAD)
    for name in transfer.MODELS:
        result = transfer.run_episodes(env, params, scripted_insertion, name, 2, 0, clip=True, record=False)
        assert result["success_rate"] == 1.0, (name, result)
        assert result["ticks"] == 2 * result["steps_mean"] and result["return_mean"] > 1.0


@pytest.mark.mjx
@pytest.mark.slow
def test_a_pose_bias_moves_the_estimates_the_policy_sees_and_not_the_scoring():
    bias = np.array([0.01, -0.004, 0.002])
    peg = PegInsert()
    result = transfer.run_episodes(peg, peg.default_params(), scripted_insertion, "jaxarm", 2, 0, True, False, bias)
    assert result["success_rate"] == 0.0 and result["pose_bias"] == bias.tolist()  # inserts 2 of 2 without

    sorter = PandaSort()
    params = sorter.default_params().replace(max_episode_steps=1)
    seen: dict[str, np.ndarray] = {}
    for name, pose_bias in (("plain", transfer.NO_BIAS), ("biased", bias)):

        def still(obs: np.ndarray, name=name) -> np.ndarray:
            seen[name] = obs
            return np.zeros(sorter.spec.action_shape[0])

        transfer.run_episodes(sorter, params, still, "jaxarm", 1, 0, True, False, pose_bias)
    moved = seen["biased"] - seen["plain"]
    np.testing.assert_allclose(moved[:3], bias, atol=1e-6)  # the object's centre, its first entries
    assert np.count_nonzero(np.abs(moved) > 1e-6) == 9  # and its offsets from the tool and from its carry target


def test_an_export_older_than_its_run_is_named_with_the_update_the_run_reached(tmp_path):
    # An export made when a run first stopped (update 10) was driven for 200 episodes as if it were the run's
    # final policy (update 1,230): the figures were update 10's, and nothing said so.
    run_dir = tmp_path
    rows = [{"updates": updates, "env_steps": 32 * updates, "wall_time": 1.0} for updates in (10, 1230)]
    (run_dir / "metrics.jsonl").write_text("".join(json.dumps(row) + "\n" for row in rows))
    warning = transfer.stale_export(run_dir, "10")
    assert warning == (
        f"warning: {run_dir / 'export'} holds update 10's policy, and the run has trained to update 1230 since; "
        f"python -m experiments.export {run_dir} exports its latest"
    )
    assert transfer.stale_export(run_dir, "1230") is None and transfer.stale_export(run_dir, "best") is None


@pytest.mark.mjx
@pytest.mark.slow
def test_the_transfer_cli_runs_an_exported_sorter_policy_on_both_pandas(tmp_path, capsys):
    config = sorter_run(tmp_path, 20)
    assert transfer.main([str(tmp_path)]) == 2
    assert "export the run first" in capsys.readouterr().err
    export_random_policy(tmp_path, config, "24")
    for name in transfer.MODELS:
        assert transfer.main([str(tmp_path), "--model", name, "--episodes", "2"]) == 0
        result = json.loads((tmp_path / f"transfer-{name}-2-12345-24.json").read_text())
        assert result["model"] == name and result["ticks"] == 40 and result["steps_mean"] == 20
        assert 0.0 <= result["success_rate"] <= result["success_ci95"][1] <= 1.0
        assert len(result["acceleration_clips"]) == len(result["speed_clips"]) == 7
        assert f"({name}'s panda)" in capsys.readouterr().out


def test_transfer_refuses_a_damaged_policy_too_many_episodes_and_a_video_without_gl_in_one_line(
    tmp_path, capsys, monkeypatch
):
    rundir.write_config(tmp_path, apply_overrides(td3_peg(), ["num_envs=2"]), "td3_peg")
    (tmp_path / "export").mkdir()
    policy_path = tmp_path / "export" / "policy.npz"
    policy_path.write_bytes(b"PK\x03\x04 cut short")
    assert transfer.main([str(tmp_path), "--episodes", "2"]) == 2
    error = capsys.readouterr().err
    assert error == f"error: {policy_path} is not an .npz archive (empty, cut short or another format); " + (
        "export the run again (python -m experiments.export RUN)\n"
    )
    assert transfer.main([str(tmp_path), "--episodes", "100000000"]) == 2
    assert capsys.readouterr().err == "error: --episodes must be in [1, 1048576], got 100000000\n"
    assert transfer.main([str(tmp_path), "--seed", "99999999999999999999999"]) == 2  # JAX's OverflowError before
    assert capsys.readouterr().err.startswith("error: --seed must fit in int32")
    for bias in ("0.01,0", "0.2,0,0", "nan,0,0", "1cm,0,0"):
        assert transfer.main([str(tmp_path), "--pose-bias", bias]) == 2
        assert capsys.readouterr().err == f"error: --pose-bias is X,Y,Z in metres, each within ±0.1, got {bias!r}\n"

    # A policy without its record of the checkpoint it came from (an earlier version's export) is refused: its
    # results could not be told from another checkpoint's.
    config, _ = rundir.read_config(tmp_path)
    env, _ = config.make_eval_env()
    random_policy(config, env.spec.observation_shape[0], env.spec.action_shape[0], np.random.default_rng(0)).save(
        policy_path
    )
    origin_path = tmp_path / "export" / origin.FILE
    assert transfer.main([str(tmp_path), "--episodes", "2"]) == 2
    missing = f"error: no {origin_path} (which checkpoint the policy came from); {EXPORT_AGAIN}\n"
    assert capsys.readouterr().err == missing
    for content in ['{"checkpoint": "../24"}', '{"update": 24}', "[]", "\x00"]:
        origin_path.write_text(content)
        assert transfer.main([str(tmp_path), "--episodes", "2"]) == 2
        error = capsys.readouterr().err
        assert error.startswith(f"error: {origin_path} is damaged or edited (") and error.count("\n") == 1, error

    def no_gl():
        raise mujoco.FatalError("an OpenGL platform library has not been loaded into this process")

    monkeypatch.setattr(headless, "probe_gl", no_gl)
    monkeypatch.setattr(rundir, "read_config", lambda *args: pytest.fail("read the run before probing GL"))
    assert transfer.main([str(tmp_path), "--video"]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and error.startswith("error: cannot draw here (FatalError: an OpenGL platform")
    assert error.strip().endswith(headless.GL_HINT)


@pytest.mark.mjx
@pytest.mark.slow
def test_the_transfer_cli_runs_an_exported_camera_policy_on_both_pandas(tmp_path, capsys):
    config = apply_overrides(configs.get("ppo_peg_pixels"), ["env_kwargs.resolution=16", "num_envs=2"])
    config = dataclasses.replace(config, env_params=(*config.env_params, ("max_episode_steps", 5)))
    rundir.write_config(tmp_path, config, "ppo_peg_pixels")
    (tmp_path / "export").mkdir()
    rundir.write_json(tmp_path / "export" / origin.FILE, origin.record("7"))
    short = random_camera_policy((16, 16, 4), 8, 3, np.random.default_rng(0))  # one proprio value short
    short.save(tmp_path / "export" / "policy.npz")
    assert transfer.main([str(tmp_path), "--episodes", "1"]) == 2
    assert "does not fit the run's env" in capsys.readouterr().err
    random_camera_policy((16, 16, 4), 9, 3, np.random.default_rng(0)).save(tmp_path / "export" / "policy.npz")
    assert transfer.main([str(tmp_path), "--pose-bias", "0,0.01,0"]) == 2
    assert capsys.readouterr().err == "error: --pose-bias: a camera's policy is shown no position estimate to bias\n"
    for name in transfer.MODELS:
        assert transfer.main([str(tmp_path), "--model", name, "--episodes", "2"]) == 0, capsys.readouterr().err
        result = json.loads((tmp_path / f"transfer-{name}-2-12345-7.json").read_text())
        assert result["model"] == name and result["ticks"] == 2 * result["steps_mean"] and result["steps_mean"] >= 1
        assert f"({name}'s panda)" in capsys.readouterr().out
