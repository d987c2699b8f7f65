"""A controller saved as files (deploy.json, robot.mjb) loads back without JAX and acts as the one saved."""

import numpy as np

from experiments.benchmarks.deploy import random_inputs
from jaxarm.deploy import files, from_env
from jaxarm.envs.panda_sort import PandaSort
from jaxarm.envs.peg_insert.env import PegInsert


def test_saved_controllers_observe_and_act_as_the_originals(tmp_path):
    rng = np.random.default_rng(0)
    envs = [PandaSort(objects_count=3, running_target=True, target_first=True), PegInsert()]
    for index, env in enumerate(envs):
        original = from_env.controller(env, env.default_params())
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
