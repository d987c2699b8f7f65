"""A controller saved as files (deploy.json, robot.mjb) loads back without JAX and acts as the one saved."""

import json

import mujoco
import numpy as np
import pytest

from experiments.benchmarks.deploy import random_inputs
from jaxarm import deployable
from jaxarm.deploy import files
from jaxarm.envs.panda_sort import PandaSort
from jaxarm.envs.peg_insert.env import PegInsert


def test_saved_controllers_observe_and_act_as_the_originals(tmp_path):
    rng = np.random.default_rng(0)
    envs = [PandaSort(objects_count=3, running_target=True, target_first=True), PegInsert()]
    for index, env in enumerate(envs):
        original = deployable.controller(env, env.default_params())
        written = files.save(tmp_path / str(index), original)
        assert sorted(path.name for path in written) == ["deploy.json", "robot.mjb"]
        loaded = files.load(tmp_path / str(index))
        assert type(loaded) is type(original)
        # Saved again, the loaded task reads the same, number for number.
        again = files.save(tmp_path / f"{index}_again", loaded)
        assert again[0].read_text() == written[0].read_text()
        task = original.task  # type: ignore[attr-defined]
        ctrl = np.concatenate([task.start_qpos, np.full(2, 0.02)])
        for _ in range(3):
            reading, estimate = random_inputs(original, task.start_qpos, rng)
            action = rng.uniform(-1.0, 1.0, original.action_size)
            for controller in (original, loaded):
                controller.begin()
            np.testing.assert_array_equal(
                loaded.observe(reading, estimate, ctrl), original.observe(reading, estimate, ctrl)
            )
            np.testing.assert_array_equal(loaded.act(reading, ctrl, action), original.act(reading, ctrl, action))


def test_damaged_or_foreign_deploy_files_are_refused_in_one_line_naming_the_file(tmp_path):
    with pytest.raises(ValueError, match="no deploy files for a object; they are written for SortController"):
        files.save(tmp_path, object())  # type: ignore[arg-type]
    task_path, model_path = files.save(tmp_path, deployable.controller(PegInsert(), PegInsert().default_params()))
    saved = json.loads(task_path.read_text())
    for edited, error in [
        ("{", "JSONDecodeError"),
        ("[]", "TypeError"),
        (json.dumps({**saved, "task": "juggle"}), "KeyError: 'juggle'"),
        (json.dumps({**saved, "numbers": {**saved["numbers"], "spin": 1}}), "KeyError: 'spin'"),
        (json.dumps({**saved, "numbers": [1]}), "AttributeError"),
    ]:
        task_path.write_text(edited)
        with pytest.raises(ValueError) as raised:
            files.load(tmp_path)
        assert str(raised.value).startswith(f"{task_path} is damaged or from another version ({error}")
        assert "\n" not in str(raised.value)
    task_path.write_text(json.dumps(saved))
    for content, message in [(b"", "is not a panda scene (ValueError"), (None, "no ")]:
        model_path.unlink(missing_ok=True)
        if content is not None:
            model_path.write_bytes(content)
        with pytest.raises(ValueError) as raised:
            files.load(tmp_path)
        assert message in str(raised.value) and str(model_path) in str(raised.value)
    mujoco.mj_saveModel(mujoco.MjModel.from_xml_string("<mujoco/>"), str(model_path))
    with pytest.raises(ValueError, match=r"robot.mjb is not a panda scene \(KeyError: .*Invalid name 'joint1'"):
        files.load(tmp_path)
