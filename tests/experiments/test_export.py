"""`python -m experiments.export`: every exported form of a PPO and a TD3 policy, of flat observations and of a
camera's (each conv stack the numpy policy runs, shared and own encoders), acts as `trainer.act` does. (A camera
without proprio leaves a normaliser of no values, which orbax does not checkpoint: no run of one exists to export.)

The learner states are built directly (random networks and a random observation normaliser) and
checkpointed into a run directory, as a run would leave them: exporting needs no training.
"""

import dataclasses
import importlib.util

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from experiments import export as export_cli
from jaxarm import envs
from jaxarm.agents.common import checkpoint
from jaxarm.agents.ppo import PPOConfig
from jaxarm.agents.td3 import TD3Config
from jaxarm.export import numpy_policy, origin, policy
from jaxarm.interop.gymnasium_env import GymnasiumEnv
from jaxarm.runner import learners, rundir

TOLERANCE = 1e-5
CONFIGS = {
    "ppo": PPOConfig(
        num_envs=8,
        rollout_length=4,
        num_minibatches=2,
        total_env_steps=32,
        policy_hidden_sizes=(32, 32),
        value_hidden_sizes=(16,),
        activation="swish",
    ),
    "td3": TD3Config(num_envs=4, total_env_steps=16, hidden_sizes=(32, 32), buffer_size=64, batch_size=8),
    "td3_normalized": TD3Config(
        num_envs=4, total_env_steps=16, hidden_sizes=(32, 32), buffer_size=64, batch_size=8, normalize_observations=True
    ),
    "ppo_pixels": PPOConfig(
        env="arm2d_pixels_proprio",
        env_kwargs=(("resolution", 16),),
        num_envs=8,
        rollout_length=4,
        num_minibatches=2,
        total_env_steps=32,
        policy_hidden_sizes=(32,),
        value_hidden_sizes=(16,),
        encoder="patches",
        encoder_features=16,
        shared_encoder=True,
    ),
    # 36 pixels: the Nature stack's smallest image of a whole-pixel output (8 by 4, 4 by 2, 3 by 1 -> 1x1).
    "td3_pixels": TD3Config(
        env="arm2d_pixels_proprio",
        env_kwargs=(("resolution", 36),),
        num_envs=4,
        total_env_steps=16,
        hidden_sizes=(32,),
        buffer_size=64,
        batch_size=8,
        encoder="nature",
        encoder_features=16,
        shared_encoder=True,
    ),
    "td3_pixels_proprio": TD3Config(
        env="arm2d_pixels_proprio",
        env_kwargs=(("resolution", 16),),
        num_envs=4,
        total_env_steps=16,
        hidden_sizes=(32,),
        buffer_size=64,
        batch_size=8,
        encoder="patches",
        encoder_features=16,
        normalize_observations=True,
    ),
}


def perturbed(tree, key, scale: float):
    """`tree` with Gaussian noise added to every float leaf (so the policy's outputs span its range)."""
    leaves, treedef = jax.tree.flatten(tree)
    keys = jax.random.split(key, len(leaves))
    return treedef.unflatten(
        [leaf + scale * jax.random.normal(k, leaf.shape) for leaf, k in zip(leaves, keys, strict=True)]
    )


def learner_state(name: str, trainer, config):
    """A fresh state with perturbed policy weights and a random observation normaliser (which a learner that
    does not normalise ignores)."""
    state = trainer.init(jax.random.PRNGKey(0), config.hparams())
    obs_size = state.normalizer.mean.shape[0]
    state = state.replace(
        normalizer=state.normalizer.replace(
            mean=jax.random.normal(jax.random.PRNGKey(2), (obs_size,)),
            std=jax.random.uniform(jax.random.PRNGKey(3), (obs_size,), minval=0.2, maxval=3.0),
        )
    )
    if name.startswith("td3"):
        return state.replace(actor_params=perturbed(state.actor_params, jax.random.PRNGKey(1), 0.3))
    params = dataclasses.replace(state.params, policy=perturbed(state.params.policy, jax.random.PRNGKey(1), 0.3))
    return state.replace(params=params)


@pytest.fixture(scope="module", params=list(CONFIGS))
def exported(request, tmp_path_factory):
    """(run dir, trainer, learner state, env spec) of a checkpointed tiny run and its export."""
    config = CONFIGS[request.param]
    run_dir = tmp_path_factory.mktemp(request.param)
    trainer = learners.make_trainer(config)
    state = learner_state(request.param, trainer, config)
    rundir.write_config(run_dir, config, f"tiny_{request.param}")
    checkpoint.save(run_dir / "checkpoints", 1, state)
    assert export_cli.main([str(run_dir)]) == 0
    return run_dir, trainer, state, config.make_env()[0].spec


def random_observations(spec, batch: int = 64) -> dict[str, np.ndarray]:
    """`batch` random observations of each part a policy reads: uniform uint8 images, Gaussian floats."""
    rng = np.random.default_rng(0)
    return {
        name: rng.integers(0, 256, (batch, *part.shape), np.uint8)
        if part.dtype == np.uint8
        else rng.normal(scale=2.0, size=(batch, *part.shape)).astype(np.float32)
        for name, part in policy.policy_inputs(spec).items()
    }


def test_every_exported_form_acts_as_the_learner(exported):
    run_dir, trainer, state, spec = exported
    parts = random_observations(spec)
    obs = parts[policy.FLAT_INPUT] if spec.flat_observation else parts
    expected = np.asarray(trainer.act(state, jax.tree.map(jnp.asarray, obs)))
    assert np.std(expected) > 0.1, "a policy this flat would hide errors in the export"
    files = sorted(path.name for path in (run_dir / "export").iterdir())
    with_onnx = importlib.util.find_spec("jax2onnx") is not None
    assert files == ["export.json", "policy.jax_export", "policy.npz", *(["policy.onnx"] if with_onnx else [])]
    assert origin.read(run_dir / "export") == str(int(state.updates))  # as experiments.eval names a checkpoint

    arrays = numpy_policy.load(run_dir / "export" / "policy.npz")
    np.testing.assert_allclose(arrays(obs), expected, atol=TOLERANCE)
    np.testing.assert_allclose(arrays(jax.tree.map(lambda part: part[3], obs)), expected[3], atol=TOLERANCE)

    serialized = jax.export.deserialize(bytearray((run_dir / "export" / "policy.jax_export").read_bytes()))
    for batch in (64, 1):
        actions = serialized.call(jax.tree.map(lambda part: part[:batch], obs))  # noqa: B023
        np.testing.assert_allclose(np.asarray(actions), expected[:batch], atol=TOLERANCE)

    if not with_onnx:
        pytest.skip("jax2onnx is not installed (the export extra)")
    import onnxruntime

    session = onnxruntime.InferenceSession(str(run_dir / "export" / "policy.onnx"))
    assert [node.name for node in session.get_inputs()] == list(parts)
    (output,) = session.run(None, parts)
    np.testing.assert_allclose(output, expected, atol=TOLERANCE)


def test_the_numpy_policy_drives_the_gymnasium_adapter(exported):
    # docs/tutorials/deploy.md's example: the policy file alone acts in the Gymnasium env.
    run_dir, _, _, spec = exported
    if not spec.flat_observation:
        pytest.skip("the Gymnasium adapter's example is the state policy's")
    actor = numpy_policy.load(run_dir / "export" / "policy.npz")
    env = GymnasiumEnv(envs.make("arm2d"))
    obs, _ = env.reset(seed=0)
    steps, done = 0, False
    while not done:
        obs, _, terminated, truncated, _ = env.step(actor(obs))
        steps, done = steps + 1, terminated or truncated
    assert 1 <= steps <= 200


def test_an_export_of_a_run_that_has_not_finished_says_so(tmp_path, capsys):
    # A run stopped early and exported was later driven in stock MuJoCo as if it were the finished run's policy.
    config = CONFIGS["ppo"]
    trainer = learners.make_trainer(config)
    rundir.write_config(tmp_path, config, "tiny_ppo")
    checkpoint.save(tmp_path / "checkpoints", 1, trainer.init(jax.random.PRNGKey(0), config.hparams()))
    assert export_cli.main([str(tmp_path), "--out", str(tmp_path / "early")]) == 0
    note = f"note: {tmp_path} has not finished training: this is the policy of update 0; export again when it has"
    assert note in capsys.readouterr().out
    rundir.write_json(tmp_path / "eval.json", {"success_rate": 1.0, "finished": True})
    assert export_cli.main([str(tmp_path), "--out", str(tmp_path / "final")]) == 0
    assert "note:" not in capsys.readouterr().out


def test_export_errors_are_one_line(tmp_path, capsys):
    assert export_cli.main([str(tmp_path)]) == 2
    assert "no config.json" in capsys.readouterr().err
    rundir.write_config(tmp_path, CONFIGS["ppo"], "tiny_ppo")
    assert export_cli.main([str(tmp_path)]) == 2
    assert "checkpoint" in capsys.readouterr().err
    assert not (tmp_path / "export").exists()
    for out in (tmp_path, tmp_path / "another_run"):  # a run's files and the export's mixed: it then resumed no more
        rundir.write_config(out, CONFIGS["ppo"], "tiny_ppo")
        before = sorted(path.name for path in out.iterdir())
        assert export_cli.main([str(tmp_path), "--out", str(out)]) == 2
        assert capsys.readouterr().err == f"error: --out {out} is a run directory; give a folder of the export's own\n"
        assert sorted(path.name for path in out.iterdir()) == before


def test_a_camera_policy_the_numpy_policy_cannot_run_is_refused_before_anything_is_written(tmp_path, capsys):
    config = dataclasses.replace(CONFIGS["ppo_pixels"], encoder="impala")
    trainer = learners.make_trainer(config)
    rundir.write_config(tmp_path, config, "tiny_impala")
    checkpoint.save(tmp_path / "checkpoints", 1, trainer.init(jax.random.PRNGKey(0), config.hparams()))
    assert export_cli.main([str(tmp_path)]) == 2
    assert capsys.readouterr().err == "error: the numpy policy runs the encoders nature and patches, not impala\n"
    assert not (tmp_path / "export").exists()
